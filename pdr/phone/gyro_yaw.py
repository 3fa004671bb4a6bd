"""Gyro yaw of a phone: its rotation about the vertical from the gyroscope alone, free of the geometric phase.

The offline heading smoother (:mod:`pdr.phone.heading_smoother`) needs, per step, the heading change the gyroscope saw,
with neither the magnetometer's deflections nor a landmark's correction in it. Integrating the body rate's vertical
component, ``int omega . u dt`` (``u`` the up direction in the device frame), is exact for a phone that only turns
about the vertical, but not for one that also swings: a closed loop of attitudes (one gait cycle of a thigh, whose
swing and roll trace a cone) adds a geometric phase, the solid angle of the cone. A phone in a trouser pocket gains
so 1-2 deg per stride (simulated pocket walks, ``pdr.sim``, with the true attitude and rates: 47-80 deg over
45-70 s), which the smoother would have to take for a gyro bias of 1-2 deg/s.

What is integrated instead is the change of a *state function*: the yaw ``psi_a(q) = atan2(n_north, n_east)`` of a
device axis ``a`` (``n = C_nb(q) a``), which returns to its value whenever the attitude does, minus the part of that
change the attitude filter put in by its measurement updates about the vertical. Per sample ``k`` (``q_k`` the
filter's attitude, ``omega_k`` the raw gyro, ``ts`` the interval):

* the gyro-only prediction ``q^-_k = q_{k-1} exp(omega_k ts)`` (the filter's time update, eq. 7 of seed 003, without
  its bias);
* the filter's correction ``delta_k = q_k (q^-_k)^*`` (navigation frame; magnetometer, gravity, landmark updates,
  its gyro bias), whose rotation vector's vertical component ``c_k`` is a rotation about the vertical;
* ``yaw_k = yaw_{k-1} + wrap(psi_a(q_k) - psi_a(q_{k-1})) - c_k``.

A rotation about the vertical moves ``psi_a`` of every axis by its angle, so ``c_k`` removes exactly the filter's
heading corrections, while its tilt corrections (gravity-referenced) stay, bounded, in ``psi_a``. The raw gyro
enters, bias included: a constant bias ``b`` adds ``u . b`` per second, and ``up_time = int u dt`` (s) lets the
smoother remove the walk's stationary bias estimate afterwards (``yaw - up_time . b``), as before.

The axis is the device axis nearest the horizontal at the start; it is changed (to the axis then nearest the
horizontal) when it comes within ``acos(AXIS_SWITCH)`` of the vertical, where its yaw becomes ill-defined. The
recursion runs sample by sample from the stored previous attitude, so the result does not depend on how a session
is split into batches.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel
from pdr.filters.rotation_kernels import quat_exp_of, wrap_pi

FloatArray = NDArray[np.float64]

#: |vertical component| of the unit axis beyond which another axis is taken (the axis within 26 deg of vertical).
AXIS_SWITCH = 0.9


@kernel
def _vertical_angle(w: float, vx: float, vy: float, vz: float) -> float:  # pragma: no cover - compiled
    """Vertical component of the rotation vector of the unit quaternion ``(w, vx, vy, vz)`` (rad)."""
    if w < 0.0:                                   # the shorter of the two rotations
        w, vx, vy, vz = -w, -vx, -vy, -vz
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    if vn < 1e-12:
        return 2.0 * vz
    return 2.0 * math.atan2(vn, w) * vz / vn


# The two functions below give single rows/columns of C_nb as scalars. pdr.filters.rotation_kernels.rotmat gives the
# whole matrix, but as a new array per call, which doubles this kernel's cost (0.17 against 0.085 s per hour at 100 Hz).
@kernel
def _axis_column(q: FloatArray, axis: int) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Column ``axis`` of ``C_nb(q)``: the device axis in ENU."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    if axis == 0:
        return 1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)
    if axis == 1:
        return 2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)
    return 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)


@kernel
def _up_row(q: FloatArray) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Last row of ``C_nb(q)``: the up direction in the device frame."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)


@kernel
def _nearest_horizontal(u: tuple[float, float, float]) -> int:  # pragma: no cover - compiled
    """Device axis whose vertical component ``u[i]`` is smallest."""
    axis = 0
    for i in range(1, 3):
        if abs(u[i]) < abs(u[axis]):
            axis = i
    return axis


@kernel
def _gyro_yaw_kernel(q: FloatArray, gyro: FloatArray, ts: float, q_prev: FloatArray, has_prev: bool, axis: int,
                     yaw0: float, up0: FloatArray, switch: float, yaw: FloatArray, up_time: FloatArray
                     ) -> int:  # pragma: no cover - compiled
    n = q.shape[0]
    y = yaw0
    u0, u1, u2 = up0[0], up0[1], up0[2]
    prev = q_prev
    if not has_prev and n:
        axis = _nearest_horizontal(_up_row(q[0]))
    for k in range(n):
        qk = q[k]
        up = _up_row(qk)
        if has_prev or k > 0:
            # Gyro-only prediction q_{k-1} exp(w ts), then the filter's correction q_k (q^-)^*, about the vertical.
            e0, e1, e2, e3 = quat_exp_of(gyro[k, 0] * ts, gyro[k, 1] * ts, gyro[k, 2] * ts)
            p0 = prev[0] * e0 - prev[1] * e1 - prev[2] * e2 - prev[3] * e3
            p1 = prev[0] * e1 + prev[1] * e0 + prev[2] * e3 - prev[3] * e2
            p2 = prev[0] * e2 - prev[1] * e3 + prev[2] * e0 + prev[3] * e1
            p3 = prev[0] * e3 + prev[1] * e2 - prev[2] * e1 + prev[3] * e0
            d0 = qk[0] * p0 + qk[1] * p1 + qk[2] * p2 + qk[3] * p3
            d1 = -qk[0] * p1 + qk[1] * p0 - qk[2] * p3 + qk[3] * p2
            d2 = -qk[0] * p2 + qk[1] * p3 + qk[2] * p0 - qk[3] * p1
            d3 = -qk[0] * p3 - qk[1] * p2 + qk[2] * p1 + qk[3] * p0
            a1 = _axis_column(qk, axis)
            a0 = _axis_column(prev, axis)
            d_psi = wrap_pi(math.atan2(a1[1], a1[0]) - math.atan2(a0[1], a0[0]))
            y += d_psi - _vertical_angle(d0, d1, d2, d3)
            u0, u1, u2 = u0 + up[0] * ts, u1 + up[1] * ts, u2 + up[2] * ts
        yaw[k] = y
        up_time[k, 0], up_time[k, 1], up_time[k, 2] = u0, u1, u2
        if abs(up[axis]) > switch:
            axis = _nearest_horizontal(up)
        prev = qk
    return axis


class GyroYaw:
    """Running gyro yaw (rad, counter-clockwise, arbitrary origin) and up time (s, device frame) of a session.

    :meth:`update` takes the attitude filter's attitudes and the raw gyro of the next samples on the uniform grid.
    State: the last yaw and up time, the axis in use and the last attitude (:meth:`state`).
    """

    def __init__(self, rate_hz: float) -> None:
        self.ts = 1.0 / rate_hz
        self.yaw = 0.0
        self.up_time = np.zeros(3)
        self.axis = 0
        self.q_prev: FloatArray | None = None

    def update(self, q_nb: FloatArray, gyro_b: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(N,) gyro yaw (rad) and (N, 3) up time (s) after each of the N samples.

        ``q_nb`` (N, 4) are the attitude filter's attitudes, ``gyro_b`` (N, 3) the raw angular rates (rad/s,
        device frame) of the same samples.
        """
        q = np.ascontiguousarray(q_nb, dtype=np.float64)
        w = np.ascontiguousarray(gyro_b, dtype=np.float64)
        n = q.shape[0]
        yaw, up_time = np.empty(n), np.empty((n, 3))
        has_prev = self.q_prev is not None
        prev = self.q_prev if self.q_prev is not None else np.array([1.0, 0.0, 0.0, 0.0])
        self.axis = int(_gyro_yaw_kernel(q, w, self.ts, prev, has_prev, self.axis, self.yaw, self.up_time,
                                         AXIS_SWITCH, yaw, up_time))
        if n:
            self.yaw, self.up_time, self.q_prev = float(yaw[-1]), up_time[-1].copy(), q[-1].copy()
        return yaw, up_time

    def state(self) -> dict[str, Any]:
        return {"yaw": self.yaw, "up_time": self.up_time.tolist(), "axis": self.axis,
                "q_prev": None if self.q_prev is None else self.q_prev.tolist()}

    @classmethod
    def from_state(cls, d: dict[str, Any], rate_hz: float) -> GyroYaw:
        g = cls(rate_hz)
        g.yaw = float(d["yaw"])
        g.up_time = np.array(d["up_time"], dtype=np.float64).reshape(3)
        g.axis = int(d["axis"])
        if not 0 <= g.axis <= 2:
            raise ValueError(f"gyro yaw axis must be 0, 1 or 2, got {g.axis}")
        g.q_prev = None if d["q_prev"] is None else np.array(d["q_prev"], dtype=np.float64).reshape(4)
        return g
