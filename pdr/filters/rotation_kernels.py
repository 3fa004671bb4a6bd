"""Compiled (numba) rotation helpers for the per-sample filter loops: quaternion product, exponential, rotation
matrix, a turn about the vertical, yaw and angle wrap on scalars and small arrays.

The conventions of :mod:`pdr.frames`: Hamilton quaternions, scalar first, ``q_nb`` rotates body vectors into the
ENU navigation frame; yaw counter-clockwise from east. :mod:`pdr.quaternion` is the vectorised counterpart for
whole arrays; these are for the ``@njit`` loops (:mod:`pdr.foot.zupt`, :mod:`pdr.foot.filterbank`,
:mod:`pdr.foot.bc`, :mod:`pdr.foot.drift`, :mod:`pdr.phone.gyro_yaw`, :mod:`pdr.phone.heading_smoother`,
:mod:`pdr.phone.attitude.kernel`) and tested against it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel

Array = NDArray[np.float64]


@kernel
def quat_mul(a: Array, b: Array) -> Array:  # pragma: no cover - compiled
    """Hamilton product ``a b`` of two (4,) quaternions."""
    return np.array([
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


@kernel
def quat_exp(phi: Array) -> Array:  # pragma: no cover - compiled
    """Unit quaternion of the rotation vector ``phi`` (3,), rad (series near zero)."""
    return np.array(quat_exp_of(phi[0], phi[1], phi[2]))


@kernel
def quat_exp_of(phi0: float, phi1: float, phi2: float) -> tuple[float, float, float, float]:  # pragma: no cover
    """:func:`quat_exp` of the rotation vector ``(phi0, phi1, phi2)`` (rad) given as scalars, as scalars (a per-sample
    loop then allocates no array).
    """
    angle = math.sqrt(phi0 ** 2 + phi1 ** 2 + phi2 ** 2)
    k = 0.5 - angle * angle / 48.0 if angle < 1e-8 else math.sin(0.5 * angle) / angle
    return math.cos(0.5 * angle), k * phi0, k * phi1, k * phi2


@kernel
def rotate_yaw(q: Array, angle: float) -> None:  # pragma: no cover - compiled
    """``q := Rz(angle) q`` in place: turn the attitude about the navigation-frame vertical by ``angle`` (rad,
    counter-clockwise); the tilt is kept.
    """
    c, s = math.cos(0.5 * angle), math.sin(0.5 * angle)
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    q[0] = c * q0 - s * q3
    q[1] = c * q1 - s * q2
    q[2] = c * q2 + s * q1
    q[3] = c * q3 + s * q0


@kernel
def rotmat(q: Array) -> Array:  # pragma: no cover - compiled
    """(3, 3) rotation matrix ``C_nb`` of a unit quaternion ``q_nb`` (4,)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@kernel
def yaw_of(q: Array) -> float:  # pragma: no cover - compiled
    """Yaw (rad, counter-clockwise from east) of the ZYX Euler angles of ``q_nb`` (4,)."""
    return math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] * q[2] + q[3] * q[3]))


@kernel
def wrap_pi(a: float) -> float:  # pragma: no cover - compiled
    """Angle ``a`` (rad) wrapped to [-pi, pi), as :func:`pdr.frames.wrap_angle`."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi
