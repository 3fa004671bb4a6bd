"""Strapdown mechanisation and the first-order error model of the ZUPT-aided INS (seed 001 eqs. 1-2): the
error-state indices, the two-sample strapdown step, the error transition and the covariance propagation
(compiled).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import quat_exp, quat_mul, rotmat
from pdr.filters.small_linalg import cross3

Array = NDArray[np.float64]


# Indices of the error state (seed 001 eq. 2).
POS = slice(0, 3)
VEL = slice(3, 6)
ATT = slice(6, 9)
YAW = 8


@cached_njit()
def mechanize(p: Array, v: Array, q: Array, f0_b: Array, w0_b: Array, f_b: Array, w_b: Array, dt: float,
              g_n: Array) -> Array:  # pragma: no cover - compiled
    """Second-order strapdown step (eq. 1 as :mod:`pdr.strapdown`) in place; returns the mean specific force f_n.

    ``f0_b, w0_b`` are the samples at the start of the interval, ``f_b, w_b`` at its end: two-sample rotation
    vector (trapezoid + coning term), acceleration integrated as varying linearly between the two ends.
    """
    coning = cross3(w0_b, w_b)
    theta = np.empty(3)
    for i in range(3):
        theta[i] = 0.5 * (w0_b[i] + w_b[i]) * dt + coning[i] * dt * dt / 12.0
    c0 = rotmat(q)
    q1 = quat_mul(q, quat_exp(theta))
    c1 = rotmat(q1)
    f_n = np.empty(3)
    for i in range(3):
        f0 = c0[i, 0] * f0_b[0] + c0[i, 1] * f0_b[1] + c0[i, 2] * f0_b[2]
        f1 = c1[i, 0] * f_b[0] + c1[i, 1] * f_b[1] + c1[i, 2] * f_b[2]
        a0 = f0 + g_n[i]
        a1 = f1 + g_n[i]
        p[i] += v[i] * dt + (a0 / 3.0 + a1 / 6.0) * dt * dt
        v[i] += 0.5 * (a0 + a1) * dt
        f_n[i] = 0.5 * (f0 + f1)
    q[:] = q1
    return f_n


@cached_njit()
def error_transition(f_n: Array, dt: float) -> Array:  # pragma: no cover - compiled
    """Transition matrix of the 9 error states (eq. 2) over ``dt`` with specific force ``f_n``."""
    F = np.eye(9)
    for i in range(3):
        F[i, 3 + i] = dt
    # -[f_n]x dt: attitude error (true = exp(dtheta) est) to velocity error.
    F[3, 7] = f_n[2] * dt
    F[3, 8] = -f_n[1] * dt
    F[4, 6] = -f_n[2] * dt
    F[4, 8] = f_n[0] * dt
    F[5, 6] = f_n[1] * dt
    F[5, 7] = -f_n[0] * dt
    return F


@cached_njit()
def zupt_predict(p: Array, v: Array, q: Array, P: Array, f0_b: Array, w0_b: Array, f_b: Array, w_b: Array,
                 dt: float, g_n: Array, qa: float, qg: float) -> Array:  # pragma: no cover - compiled
    """Mechanization (eq. 1) and covariance propagation (eq. 2) in place; returns the specific force f_n."""
    f_n = mechanize(p, v, q, f0_b, w0_b, f_b, w_b, dt, g_n)
    propagate_covariance(P, error_transition(f_n, dt), dt, qa, qg)
    return f_n


@cached_njit()
def propagate_covariance(P: Array, F: Array, dt: float, qa: float, qg: float) -> None:  # pragma: no cover
    """``P := F P F^T + Q`` in place (eq. 2), white velocity noise ``qa dt^2`` and attitude noise ``qg dt^2``.

    Plain loops that skip the zeros of ``F`` (18 of its 81 entries are non-zero): cheaper than two BLAS calls.
    """
    FP = np.zeros((9, 9))
    for i in range(9):
        for k in range(9):
            f = F[i, k]
            if f != 0.0:
                for j in range(9):
                    FP[i, j] += f * P[k, j]
    for i in range(9):
        for j in range(9):
            acc = 0.0
            for k in range(9):
                f = F[j, k]
                if f != 0.0:
                    acc += FP[i, k] * f
            P[i, j] = acc
    for i in range(3):
        P[3 + i, 3 + i] += qa * dt * dt
        P[6 + i, 6 + i] += qg * dt * dt
