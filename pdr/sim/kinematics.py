"""Rigid-body kinematics of the simulator: attitude, angular rate and acceleration of body segments.

A body segment (thigh, trunk, hand, shoe) is oriented by ZYX Euler angles ``yaw``, ``pitch``, ``roll``
(:func:`pdr.quaternion.from_euler`: yaw about ENU up, then pitch about the new y axis, then roll about the
new x axis), each given as a :class:`~pdr.sim.smooth.Jet`. The angular velocity in the navigation frame
follows from the Euler rates,

    omega_n = yaw' e_z + pitch' u_y + roll' u_x,   u_y = Rz(yaw) e_y,   u_x = Rz(yaw) Ry(pitch) e_x,

and its derivative (angular acceleration) from differentiating the rotating axes,
``du_y/dt = (yaw' e_z) x u_y`` and ``du_x/dt = (yaw' e_z + pitch' u_y) x u_x``. A point at a lever arm
``r`` on the segment then has ``v = v_0 + omega x r + C dr_b/dt`` and
``a = a_0 + alpha x r + omega x (omega x r) + 2 omega x C dr_b/dt + C d2r_b/dt2`` (``r = C r_b``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.frames import GRAVITY_MPS2
from pdr.sim.smooth import Jet

Array = NDArray[np.float64]

#: Gravity in ENU, m/s^2.
GRAVITY_N = np.array([0.0, 0.0, -GRAVITY_MPS2])


@dataclass(frozen=True)
class Frame:
    """Orientation of a body segment: ``q_nb`` (N, 4), angular velocity and acceleration in ENU (N, 3)."""

    q_nb: Array
    omega_n: Array
    alpha_n: Array

    def then(self, q_mount: Array) -> Frame:
        """The frame of a device fixed on this segment with orientation ``q_mount`` (segment -> device)."""
        return Frame(quat.multiply(self.q_nb, q_mount), self.omega_n, self.alpha_n)

    def compose(self, relative: Frame) -> Frame:
        """Frame of a moving rotation ``relative`` (given in this frame's coordinates) applied after this one.

        ``q = q_self q_rel``, ``omega = omega_self + C omega_rel`` and
        ``alpha = alpha_self + C alpha_rel + omega_self x (C omega_rel)`` with ``C`` the rotation of ``q_self``.
        """
        w_rel = quat.rotate(self.q_nb, relative.omega_n)
        a_rel = quat.rotate(self.q_nb, relative.alpha_n)
        return Frame(quat.multiply(self.q_nb, relative.q_nb), self.omega_n + w_rel,
                     self.alpha_n + a_rel + np.cross(self.omega_n, w_rel))


@dataclass(frozen=True)
class Motion:
    """Kinematics of one device: position, velocity, acceleration (N, 3) in ENU and its frame."""

    pos_n: Array
    vel_n: Array
    acc_n: Array
    frame: Frame

    def specific_force_b(self) -> Array:
        """Ideal accelerometer: ``f_b = C_bn (a_n - g_n)`` in m/s^2 (seed 004 eq. 10)."""
        return quat.rotate(quat.conjugate(self.frame.q_nb), self.acc_n - GRAVITY_N)

    def angular_rate_b(self) -> Array:
        """Ideal gyroscope: body angular rate ``omega_b = C_bn omega_n`` in rad/s (Earth rate neglected)."""
        return quat.rotate(quat.conjugate(self.frame.q_nb), self.frame.omega_n)


def euler_frame(roll: Jet, pitch: Jet, yaw: Jet) -> Frame:
    """Attitude, angular velocity and angular acceleration of ZYX Euler angle jets (rad, rad/s, rad/s^2)."""
    n = yaw.value.shape[0]
    q = quat.from_euler(roll.value, pitch.value, yaw.value)
    cy, sy = np.cos(yaw.value), np.sin(yaw.value)
    cp, sp = np.cos(pitch.value), np.sin(pitch.value)
    ez = np.tile([0.0, 0.0, 1.0], (n, 1))
    u_y = np.column_stack([-sy, cy, np.zeros(n)])
    u_x = np.column_stack([cy * cp, sy * cp, -sp])
    w_yaw = yaw.d1[:, None] * ez
    w_2 = w_yaw + pitch.d1[:, None] * u_y
    omega = w_2 + roll.d1[:, None] * u_x
    alpha = (yaw.d2[:, None] * ez + pitch.d2[:, None] * u_y + pitch.d1[:, None] * np.cross(w_yaw, u_y)
             + roll.d2[:, None] * u_x + roll.d1[:, None] * np.cross(w_2, u_x))
    return Frame(q, omega, alpha)


def point_on_frame(origin: Jet, frame: Frame, lever_b: Jet) -> Jet:
    """Position, velocity, acceleration (ENU) of a point at lever ``lever_b`` (segment frame) from ``origin``."""
    r = quat.rotate(frame.q_nb, lever_b.value)
    dr = quat.rotate(frame.q_nb, lever_b.d1)
    ddr = quat.rotate(frame.q_nb, lever_b.d2)
    w, a = frame.omega_n, frame.alpha_n
    w_r = np.cross(w, r)
    pos = origin.value + r
    vel = origin.d1 + w_r + dr
    acc = origin.d2 + np.cross(a, r) + np.cross(w, w_r) + 2.0 * np.cross(w, dr) + ddr
    return Jet(pos, vel, acc)


def zero(n: int) -> Jet:
    """A zero scalar jet of N samples."""
    return Jet.constant(0.0, n)
