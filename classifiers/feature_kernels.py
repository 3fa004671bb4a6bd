"""Compiled (numba) kernels of the window features where one vectorised numpy pass per statistic is too slow.

The feature extractor must run at well over 10 000 windows per second on one core; numpy spends most of
that budget streaming (W, n) temporaries through memory, one pass per statistic. These kernels do the
per-row work of :func:`classifiers.features.signal_features` and the recursive attitude integration of the
coning feature (seed 004 eqs. 26-27) in one pass per window, with the window in cache. They compute
exactly the quantities documented in :mod:`classifiers.features`; tests compare them with plain numpy.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit

FloatArray = NDArray[np.float64]


@cached_njit()
def row_moments(x: FloatArray, taper: FloatArray, n_sub: int, sub_taper: FloatArray) -> tuple[
        FloatArray, FloatArray, FloatArray]:
    """Moments, zero crossings and tapered copies of each row of ``x`` (W, n).

    Returns
    -------
    stats
        (W, 5): mean, variance, skewness (0 for a constant row), mean absolute deviation and the number of
        sign changes of the mean-removed row.
    tapered
        (W, n): ``(x - mean) * taper``.
    sub_tapered
        (W * n_sub, m): each of the ``n_sub`` sub-frames of ``m = len(sub_taper)`` samples of the
        mean-removed row, minus its own mean, times ``sub_taper``.
    """
    w, n = x.shape
    m = sub_taper.size
    stats = np.empty((w, 5))
    tapered = np.empty((w, n))
    sub_tapered = np.empty((w * n_sub, m))
    for i in range(w):
        s = 0.0
        for k in range(n):
            s += x[i, k]
        mean = s / n
        s2 = 0.0
        s3 = 0.0
        sa = 0.0
        crossings = 0
        prev_neg = x[i, 0] - mean < 0.0
        for k in range(n):
            d = x[i, k] - mean
            d2 = d * d
            s2 += d2
            s3 += d2 * d
            sa += abs(d)
            neg = d < 0.0
            if neg != prev_neg:
                crossings += 1
            prev_neg = neg
            tapered[i, k] = d * taper[k]
        var = s2 / n
        std = math.sqrt(var)
        stats[i, 0] = mean
        stats[i, 1] = var
        stats[i, 2] = s3 / n / (std * std * std) if std > 1e-12 else 0.0
        stats[i, 3] = sa / n
        stats[i, 4] = crossings
        for b in range(n_sub):
            sb = 0.0
            for k in range(m):
                sb += x[i, b * m + k]
            mb = sb / m
            for k in range(m):
                sub_tapered[i * n_sub + b, k] = (x[i, b * m + k] - mb) * sub_taper[k]
    return stats, tapered, sub_tapered


@cached_njit(inline="always")
def _exp(px: float, py: float, pz: float) -> tuple[float, float, float, float]:
    """Unit quaternion of a rotation vector (rad), exact exponential map with a Taylor branch near zero."""
    angle = math.sqrt(px * px + py * py + pz * pz)
    half = 0.5 * angle
    k = 0.5 - angle * angle / 48.0 if angle < 1e-8 else math.sin(half) / angle
    return math.cos(half), k * px, k * py, k * pz


@cached_njit(inline="always")
def _mul(aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float,
         bz: float) -> tuple[float, float, float, float]:
    """Hamilton product ``a * b`` (same convention as :func:`pdr.quaternion.multiply`)."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@cached_njit(inline="always")
def _angle(aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float, bz: float) -> float:
    """Rotation angle (rad) between two attitudes, sign-invariant (as :func:`pdr.quaternion.angle_between`)."""
    na = math.sqrt(aw * aw + ax * ax + ay * ay + az * az)
    nb = math.sqrt(bw * bw + bx * bx + by * by + bz * bz)
    d = abs(aw * bw + ax * bx + ay * by + az * bz) / (na * nb)
    return 2.0 * math.acos(min(max(d, 0.0), 1.0))


@cached_njit()
def coning(gyro: FloatArray, dt: float, n_blocks: int) -> FloatArray:
    """Coning feature (seed 004 eqs. 26-27) and total rotation of each window; (W, n, 3) rad/s -> (W, 2) rad.

    The attitude integrated at the full rate (eq. 9 with eq. 7, ``p = omega dt`` per sample) is compared,
    at the end of each of ``n_blocks`` blocks, with the attitude from one rotation vector per block
    (eq. 27, ``p = T_block * mean(omega)``); column 0 is the largest angle between them, column 1 the
    total rotation angle of the full-rate attitude. NaN samples must be replaced by the caller.
    """
    w, n, _ = gyro.shape
    m = n // n_blocks
    out = np.empty((w, 2))
    for i in range(w):
        qw, qx, qy, qz = 1.0, 0.0, 0.0, 0.0
        aw, ax, ay, az = 1.0, 0.0, 0.0, 0.0
        worst = 0.0
        for b in range(n_blocks):
            sx, sy, sz = 0.0, 0.0, 0.0
            for k in range(b * m, (b + 1) * m):
                gx, gy, gz = gyro[i, k, 0], gyro[i, k, 1], gyro[i, k, 2]
                sx += gx
                sy += gy
                sz += gz
                rw, rx, ry, rz = _exp(gx * dt, gy * dt, gz * dt)
                qw, qx, qy, qz = _mul(qw, qx, qy, qz, rw, rx, ry, rz)
            rw, rx, ry, rz = _exp(sx * dt, sy * dt, sz * dt)
            aw, ax, ay, az = _mul(aw, ax, ay, az, rw, rx, ry, rz)
            worst = max(worst, _angle(qw, qx, qy, qz, aw, ax, ay, az))
        out[i, 0] = worst
        out[i, 1] = _angle(qw, qx, qy, qz, 1.0, 0.0, 0.0, 0.0)
    return out


@cached_njit()
def rotate_to_first(f: FloatArray, gyro: FloatArray, dt: float) -> FloatArray:
    """Specific force of each window in the body frame of its first sample; (W, n, 3) -> (W, n, 3).

    The attitude relative to the first sample is integrated from the gyro at the full rate (eq. 9 of seed
    004 with eq. 7, ``p = omega dt`` per sample, as :func:`coning`) and each sample's specific force is
    rotated by it, so a thigh's swing no longer tilts the vertical the features project on. NaN samples
    must be replaced by the caller.
    """
    w, n, _ = f.shape
    out = np.empty((w, n, 3))
    for i in range(w):
        qw, qx, qy, qz = 1.0, 0.0, 0.0, 0.0
        for k in range(n):
            vx, vy, vz = f[i, k, 0], f[i, k, 1], f[i, k, 2]
            # v' = q v q*, written out: t = 2 (q_v x v); v' = v + qw t + q_v x t.
            tx = 2.0 * (qy * vz - qz * vy)
            ty = 2.0 * (qz * vx - qx * vz)
            tz = 2.0 * (qx * vy - qy * vx)
            out[i, k, 0] = vx + qw * tx + (qy * tz - qz * ty)
            out[i, k, 1] = vy + qw * ty + (qz * tx - qx * tz)
            out[i, k, 2] = vz + qw * tz + (qx * ty - qy * tx)
            rw, rx, ry, rz = _exp(gyro[i, k, 0] * dt, gyro[i, k, 1] * dt, gyro[i, k, 2] * dt)
            qw, qx, qy, qz = _mul(qw, qx, qy, qz, rw, rx, ry, rz)
    return out
