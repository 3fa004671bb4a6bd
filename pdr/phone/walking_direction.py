"""Walking direction of a swinging phone (trouser pocket, swinging hand): the swing plane's axis and the
forward/backward decision from the centripetal acceleration in turns.

All angles are internal yaw (rad, counter-clockwise from east, ENU).

Swing-plane axis (:func:`swing_plane_axis`)
    A phone in a swinging hand turns with the arm, and one in a trouser pocket with the thigh, about the
    shoulder's or hip's lateral axis ``r = f x u`` (``f`` walking direction, ``u`` up). Over a stride the
    horizontal part of the navigation-frame angular rate therefore lies along ``+/-r``: the principal axis of
    its 2x2 scatter is ``r``, and the walking line is perpendicular to it. The device's own yaw plays no part,
    so it holds whatever way the phone sits in the hand.

Forward or backward (:func:`turn_evidence`; which rule decides and why)
    The walking line has two directions. Walking at speed ``V`` along ``f`` while turning at the yaw rate
    ``Omega``, the body's mean horizontal acceleration over a stride is the centripetal ``V Omega (u x f)``,
    whatever the gait or the carriage: it is the only horizontal acceleration that does not average out over a
    stride (the gait's fore-aft and lateral oscillations and the limb's swing all do). For a candidate
    direction ``p`` the evidence is ``Omega * (a_mean . (u x p))``: ``V Omega^2 > 0`` for ``p = f`` and the
    opposite for ``p = -f``. It is scaled by ``v_ref * omega_ref^2`` and clipped to [-1, 1], so a straight
    stride (``Omega`` near 0) carries no evidence and a clear turn one full vote. It needs no assumption on the
    arm's or thigh's swing, which is why it decides for the swinging hand, whose swing is nearly symmetric
    (the thigh-swing skewness of :func:`pdr.phone.heading.thigh_swing_evidence` picks the right direction in only
    53-65 % of its strides on the motion-capture benchmark). In a trouser pocket the skewness decides
    (76-97 % right per stride there) and the turn cue is not used (below). The decision is carried between
    strides by the gyro's rotation about the vertical and accumulated by :class:`pdr.phone.heading.DirectionVote`.

    What limits it: a tilt error ``d`` of the attitude adds ``g d`` (0.17 m/s^2 per degree) to the mean
    horizontal acceleration, against a centripetal term of about 0.5 m/s^2 (1.2 m/s turning 23 deg/s). With the
    motion-capture attitude the cue is right in 86-98 % of the benchmark's strides in every carriage; with the
    attitude filter's, whose accelerometer rows take a pendulum's specific force (along the arm) for gravity,
    in 57-75 % of the swinging hand's turning strides, and added to the skewness in a pocket it raised the flips
    of the MobiFall pocket walks from 5 to 124 in 2510 steps.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.phone.heading import pca_axis

FloatArray = NDArray[np.float64]

#: Reference walking speed (m/s) and turn rate (rad/s) of a full vote: 1 m/s turning 17 deg/s.
V_REF_MPS = 1.0
OMEGA_REF_RPS = 0.3


def nav_angular_rate(q_nb: FloatArray, rate_hz: float) -> FloatArray:
    """Navigation-frame angular rate (rad/s, ENU) between consecutive attitudes, (N - 1, 3).

    ``q_{k+1} = dq q_k`` with ``dq = exp(omega_n / rate_hz)``.
    """
    q = np.asarray(q_nb, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 3:
        raise InputError("need (N >= 3, 4) attitude quaternions", source="walking direction")
    return np.asarray(quat.to_rotvec(quat.multiply(q[1:], quat.conjugate(q[:-1]))) * rate_hz)


def swing_plane_axis(q_nb: FloatArray, rate_hz: float) -> tuple[float, float]:
    """Walking line of one stride from the swing plane: (yaw in (-pi/2, pi/2], eigenvalue ratio).

    The line is perpendicular to the principal axis (:func:`pdr.phone.heading.pca_axis`) of the horizontal
    navigation-frame angular rate (module doc); the ratio of the two eigenvalues (>= 1) says how planar the
    swing was.
    """
    axis, ratio = pca_axis(nav_angular_rate(q_nb, rate_hz)[:, :2])
    line = axis + math.pi / 2
    return float(line - math.pi if line > math.pi / 2 else line), ratio


def turn_evidence(f_n: FloatArray, yaw_rate_rps: float, yaw: float, v_ref_mps: float = V_REF_MPS,
                  omega_ref_rps: float = OMEGA_REF_RPS) -> float:
    """Evidence in [-1, 1] that ``yaw`` (rad) is the walking direction, from the centripetal acceleration.

    Parameters
    ----------
    f_n
        (N, 3) specific force over one stride (m/s^2, ENU).
    yaw_rate_rps
        Mean rotation rate about the vertical over the stride (rad/s, counter-clockwise positive).
    yaw
        Candidate walking direction (rad).
    """
    f = np.asarray(f_n, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 1:
        raise InputError("need (N >= 1, 3) specific forces", source="walking direction")
    mean_h = f[:, :2].sum(axis=0) / f.shape[0]
    lateral = float(-mean_h[0] * math.sin(yaw) + mean_h[1] * math.cos(yaw))   # a . (u x p)
    return float(np.clip(yaw_rate_rps * lateral / (v_ref_mps * omega_ref_rps ** 2), -1.0, 1.0))
