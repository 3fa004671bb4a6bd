"""Gait styles: how the body moves within a step, per motion mode.

Amplitudes of the periodic body motions the placements use, as functions of the gait phase ``g``
(:mod:`pdr.sim.trajectory`; heel strikes at ``g = k + 1/2``, the right foot's at even ``k``) or of a leg's
stride phase ``phi`` (0 at that leg's heel strike, 1 at its next one; ``phi = (g - 1/2) / 2`` for the right
leg, ``(g - 3/2) / 2`` for the left):

* thigh forward angle (sagittal hip flexion) ``mean + amp s(phi)`` with ``s`` the normalised shape of the
  normative thigh angle of level walking (:data:`THIGH_SHAPE`: flexed at heel strike, extending slowly
  through the 60 % stance, flexing fast in swing; peak angular rate about 9.7 ``amp`` rad/s per Hz of
  stride frequency). Following seed 003 eqs. 1-3, going upstairs opens the legs wider and lifts the thigh
  higher than walking; going downstairs opens them less, with a higher minimum (``thigh_amp_rad``,
  ``thigh_mean_rad`` below);
* thigh abduction ``thigh_abduction sin(2 pi phi)`` and internal rotation ``thigh_rotation cos(2 pi phi)``
  (mirrored for the left leg);
* pelvis vertical bounce ``bounce cos(2 pi g)`` (lowest at heel strike), lateral sway ``sway cos(pi g)``
  (towards the stance leg) and forward surge ``surge sin(2 pi (g - 1/2))`` (walking speed fastest at heel
  strike, braking just after it: about +/- ``2 pi f surge`` m/s), pelvis rotation ``pelvis_yaw sin(pi g)``
  (the hip of the leading leg forward) and obliquity ``-pelvis_roll sin(pi (g - 0.3))`` (the swing side
  drops);
* trunk yaw (``trunk_yaw sin(pi g)``, against the pelvis), pitch (``trunk_pitch cos(2 pi g)``) and roll
  (``-trunk_roll cos(pi g)``);
* the hand's pitch wobble ``hand_pitch sin(2 pi g)``;
* shoe: stance share of the stride, swing clearance, toe-off and heel-strike pitch, peak heel-strike
  impact acceleration;
* heel-strike transients: the shock felt at the pelvis after every step (``body_shock_mps2``, peak
  vertical acceleration of an 80 ms wavelet), damped by the body compared with the shoe's; the sharper
  shock felt on the thigh of the striking leg (``leg_shock_mps2``, 60 ms, along the thigh and braking
  forward); the ringing of a pocket phone on the soft tissue of the thigh after that leg's heel strike
  (``wobble_rad``, peak angle of a damped oscillation at ``wobble_hz``) and of a hand-held phone after every
  step (``hand_wobble_rad``).

Modes without stepping (standing, elevator, escalator) have every amplitude zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

_D = math.pi / 180.0


@dataclass(frozen=True)
class GaitStyle:
    """Gait amplitudes of one motion mode (angles in rad, lengths in m, acceleration in m/s^2)."""

    thigh_mean_rad: float = 0.0
    thigh_amp_rad: float = 0.0
    bounce_m: float = 0.0
    sway_m: float = 0.0
    trunk_yaw_rad: float = 0.0
    trunk_pitch_rad: float = 0.0
    trunk_roll_rad: float = 0.0
    hand_pitch_rad: float = 0.0
    stance_fraction: float = 0.6
    clearance_m: float = 0.0
    toe_off_pitch_rad: float = 0.0
    heel_strike_pitch_rad: float = 0.0
    impact_mps2: float = 0.0
    body_shock_mps2: float = 0.0
    surge_m: float = 0.0
    pelvis_yaw_rad: float = 0.0
    pelvis_roll_rad: float = 0.0
    thigh_abduction_rad: float = 0.0
    thigh_rotation_rad: float = 0.0
    leg_shock_mps2: float = 0.0
    wobble_rad: float = 0.0
    wobble_hz: float = 6.0
    hand_wobble_rad: float = 0.0
    hand_ring_m: float = 0.0


STILL = GaitStyle()

#: Normalised thigh-angle shape ``s(phi)`` (range [-1, 1]) of level walking: the mean and the cos/sin
#: coefficients of harmonics 1-3 of a least-squares fit to the normative sagittal thigh angle over the stride
#: (heel strike at 0; about +20 deg at heel strike, -13 deg at 55 %, +23 deg at 90 % of the stride, after
#: D. A. Winter, *The Biomechanics and Motor Control of Human Gait*, 1991), minus the mid-range and divided
#: by the half range.
THIGH_SHAPE = (0.1230, ((0.9590, -0.0861), (-0.1458, -0.1474), (-0.0307, 0.0570)))

#: Gait style per motion mode.
STYLES: MappingProxyType[str, GaitStyle] = MappingProxyType({
    "walking": GaitStyle(5 * _D, 20 * _D, 0.025, 0.02, 4 * _D, 2 * _D, 2.5 * _D, 1.2 * _D, 0.60, 0.06,
                         30 * _D, 15 * _D, 25.0, 3.0, surge_m=0.015, pelvis_yaw_rad=4 * _D,
                         pelvis_roll_rad=4 * _D, thigh_abduction_rad=5 * _D, thigh_rotation_rad=6 * _D,
                         leg_shock_mps2=8.0, wobble_rad=3 * _D, wobble_hz=6.0, hand_wobble_rad=1.5 * _D,
                         hand_ring_m=0.0008),
    "running": GaitStyle(15 * _D, 35 * _D, 0.05, 0.015, 8 * _D, 3 * _D, 3 * _D, 4 * _D, 0.35, 0.15,
                         40 * _D, 20 * _D, 60.0, 10.0, surge_m=0.01, pelvis_yaw_rad=6 * _D,
                         pelvis_roll_rad=5 * _D, thigh_abduction_rad=6 * _D, thigh_rotation_rad=8 * _D,
                         leg_shock_mps2=25.0, wobble_rad=5 * _D, wobble_hz=6.0, hand_wobble_rad=2 * _D,
                         hand_ring_m=0.006),
    "stairs_up": GaitStyle(25 * _D, 27 * _D, 0.02, 0.02, 3 * _D, 4 * _D, 2 * _D, 2 * _D, 0.62, 0.06,
                           20 * _D, 5 * _D, 15.0, 2.0, surge_m=0.005, pelvis_yaw_rad=3 * _D,
                           pelvis_roll_rad=3 * _D, thigh_abduction_rad=4 * _D, thigh_rotation_rad=5 * _D,
                           leg_shock_mps2=4.0, wobble_rad=2 * _D, wobble_hz=6.0, hand_wobble_rad=1 * _D,
                           hand_ring_m=0.002),
    "stairs_down": GaitStyle(12 * _D, 14 * _D, 0.03, 0.02, 3 * _D, 3 * _D, 2 * _D, 3 * _D, 0.62, 0.05,
                             15 * _D, 0.0, 30.0, 4.0, surge_m=0.005, pelvis_yaw_rad=3 * _D,
                             pelvis_roll_rad=4 * _D, thigh_abduction_rad=4 * _D, thigh_rotation_rad=5 * _D,
                             leg_shock_mps2=10.0, wobble_rad=3 * _D, wobble_hz=6.0, hand_wobble_rad=1.5 * _D,
                             hand_ring_m=0.003),
})


def style(mode: str) -> GaitStyle:
    """The gait style of a motion mode (no motion for non-stepping modes)."""
    return STYLES.get(mode, STILL)
