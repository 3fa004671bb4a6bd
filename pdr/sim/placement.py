"""Phone placements: the motion of a phone in a trouser pocket, on the torso or in the hand.

Each placement is a chain of rigid segments (:mod:`pdr.sim.kinematics`) driven by the path and the
gait phase (:mod:`pdr.sim.trajectory`, :mod:`pdr.sim.gait`). The person frame has x forward (walking
heading), y left, z up. Body dimensions scale with the person's height ``h``.

Every step also sends a heel-strike shock up the body (:func:`body_shock`); the pelvis surges forward and
back with each step. Amplitudes: :mod:`pdr.sim.gait`; statistics checked against real walks in
``tests/pdr/sim/test_realism.py`` (:mod:`pdr.sim.realism`).

* ``trouser_pocket``: pelvis (bounce, sway, surge, rotation, obliquity) -> hip joint -> thigh (normative
  flexion waveform, abduction, internal rotation) -> phone in the front pocket, at a fixed (possibly
  arbitrary) orientation on the thigh; the striking leg's heel-strike shock (:func:`leg_shock`) moves it,
  and the soft tissue lets it ring about its own centre after that heel strike (:func:`wobble`);
* ``torso``: pelvis -> trunk (yaw, pitch and roll wobble) -> phone on the chest, upright, screen forward;
* ``hand``: pelvis -> hand held in front (reading position, screen up and tilted 35 deg towards the face);
  the elbow takes up part of the body's bounce, the arm rings after each heel strike.

Every motion is a :class:`~pdr.sim.smooth.Jet`, so accelerations and angular rates stay the exact
derivatives of the truth positions and attitudes.

:data:`DEFAULT_MOUNTS` gives each placement's device orientation in its segment frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.sim.gait import THIGH_SHAPE, style
from pdr.sim.kinematics import Frame, Motion, euler_frame, point_on_frame, zero
from pdr.sim.smooth import SHOCK_PEAK_D2, Jet, ringing, shock
from pdr.sim.trajectory import Path

Array = NDArray[np.float64]
Shape = Callable[[Array], tuple[Array, Array, Array]]


def _mount(columns: list[list[float]], tilt_x_rad: float = 0.0) -> Array:
    """Segment -> device quaternion from the device axes written in segment coordinates."""
    c = np.array(columns, dtype=np.float64).T
    q = quat.from_rotmat(c)
    return quat.multiply(q, quat.from_euler(tilt_x_rad, 0.0, 0.0))


#: Device orientation on its body segment (segment frame: x forward, y left, z up) per placement.
DEFAULT_MOUNTS: MappingProxyType[str, Array] = MappingProxyType({
    # upright in the front pocket, screen towards the thigh: x right, y up the thigh, z backwards
    "trouser_pocket": _mount([[0, -1, 0], [0, 0, 1], [-1, 0, 0]]),
    # upright on the chest, screen facing forward: x left, y up, z forward
    "torso": _mount([[0, 1, 0], [0, 0, 1], [1, 0, 0]]),
    # reading position: x right, y forward, z up, then the top raised by 35 degrees
    "hand": _mount([[0, -1, 0], [1, 0, 0], [0, 0, 1]], math.radians(35.0)),
    "foot": quat.IDENTITY.copy(),
})


def gait_level(path: Path, name: str, t: Array) -> Jet:
    """A gait amplitude (a field of :class:`~pdr.sim.gait.GaitStyle`) as a smooth function of time."""
    values = [float(getattr(style(s.mode), name)) for s in path.scenario.segments]
    return path.levels(values).value(t)


BODY_SHOCK_S = 0.25
LEG_SHOCK_S = 0.25
WOBBLE_S = 0.35
HAND_WOBBLE_HZ = 5.0
HAND_BOUNCE_KEPT = 0.7


def step_amplitudes(path: Path, name: str) -> Array:
    """A gait amplitude (a field of :class:`~pdr.sim.gait.GaitStyle`) of each step's segment, (M,)."""
    st = path.steps.t_s
    segs = path.scenario.segments
    seg = np.clip(np.searchsorted(path.scenario.boundaries_s, st, side="right") - 1, 0, len(segs) - 1)
    return np.array([float(getattr(style(segs[i].mode), name)) for i in seg])


def step_transient(path: Path, t: Array, duration_s: float, shape: Shape, amplitude: Array,
                   foot: int = 0) -> Jet:
    """Sum of ``amplitude[k] shape((t - t_k) / duration)`` over the steps ``k`` (of one foot: +1 / -1).

    ``shape`` maps ``x`` in [0, 1] to (f, df/dx, d2f/dx2) and vanishes with its derivatives at both ends;
    a transient must be shorter than the time between two steps of the chosen feet.
    """
    keep = np.ones(path.steps.t_s.size, dtype=bool) if foot == 0 else path.steps.foot == foot
    st = path.steps.t_s[keep]
    amp_k = np.asarray(amplitude, dtype=np.float64)[keep]
    n = t.size
    out = Jet(np.zeros(n), np.zeros(n), np.zeros(n))
    if st.size == 0:
        return out
    last = np.searchsorted(st, t, side="right") - 1
    since = t - st[np.maximum(last, 0)]
    hit = (last >= 0) & (since < duration_s)
    amp = amp_k[last[hit]]
    f0, f1, f2 = shape(since[hit] / duration_s)
    out.value[hit] = amp * f0
    out.d1[hit] = amp * f1 / duration_s
    out.d2[hit] = amp * f2 / duration_s**2
    return out


def body_shock(path: Path, t: Array) -> Jet:
    """Vertical pelvis displacement (m) of the heel-strike shocks: a wavelet after every step."""
    amp = step_amplitudes(path, "body_shock_mps2") * BODY_SHOCK_S**2 / SHOCK_PEAK_D2
    return step_transient(path, t, BODY_SHOCK_S, shock, amp)


def leg_shock(path: Path, t: Array, foot: int) -> Jet:
    """Displacement (m) of the heel-strike shock of one leg (+1 right, -1 left) at the thigh."""
    amp = step_amplitudes(path, "leg_shock_mps2") * LEG_SHOCK_S**2 / SHOCK_PEAK_D2
    return step_transient(path, t, LEG_SHOCK_S, shock, amp, foot)


def wobble(path: Path, t: Array, name: str, duration_s: float, hz: float | None, foot: int = 0) -> Jet:
    """Ringing after heel strikes (of one foot: +1 / -1): peak ``style.<name>`` (rad or m) at ``hz`` Hz.

    ``hz`` None: each step's ``style.wobble_hz``.
    """
    amp = step_amplitudes(path, name)
    freq = step_amplitudes(path, "wobble_hz") if hz is None else np.full(amp.size, hz)
    if amp.size == 0:
        return zero(t.size)
    # one ringing shape per distinct frequency (the style table has few)
    out = zero(t.size)
    for f in np.unique(freq):
        a = np.where(freq == f, amp, 0.0)
        out = out + step_transient(path, t, duration_s, _ringing_shape(float(f) * duration_s), a, foot)
    return out


def _ringing_shape(cycles: float) -> Shape:
    def f(x: Array) -> tuple[Array, Array, Array]:
        return ringing(x, cycles)
    return f


def thigh_shape(phi: Jet) -> Jet:
    """Normalised thigh-angle shape ``s(phi)`` (:data:`~pdr.sim.gait.THIGH_SHAPE`) of stride phase jets."""
    mean, harmonics = THIGH_SHAPE
    out = Jet.constant(mean, phi.value.shape[0])
    for k, (a, b) in enumerate(harmonics, start=1):
        arg = (2.0 * math.pi * k) * phi
        out = out + a * arg.cos() + b * arg.sin()
    return out


def _vec(x: Jet, y: Jet, z: Jet) -> Jet:
    return x.stack(y, z)


def phone_motion(path: Path, t_s: Array, placement: str, side: str, q_mount: Array, height_m: float) -> Motion:
    """Kinematics of a phone at ``placement`` sampled at ``t_s`` (N,); ``q_mount``: segment -> device."""
    t = np.asarray(t_s, dtype=np.float64)
    n = t.size
    s = 1.0 if side == "right" else -1.0
    base = path.position(t)
    psi = path.heading.value(t)
    g = path.phase(t)
    pi_g = math.pi * g
    two_pi_g = 2.0 * math.pi * g
    nil = zero(n)

    def level(name: str) -> Jet:
        return gait_level(path, name, t)

    bounce = level("bounce_m") * two_pi_g.cos()
    sway = level("sway_m") * pi_g.cos()
    surge = level("surge_m") * (two_pi_g - math.pi).sin()
    hip_h = 0.53 * height_m
    pelvis_origin = base + _vec(nil, nil, bounce + body_shock(path, t) + hip_h)
    heading_frame = euler_frame(nil, nil, psi)
    pelvis = point_on_frame(pelvis_origin, heading_frame, _vec(surge, sway, nil))

    if placement == "trouser_pocket":
        foot = 1 if s > 0 else -1
        phi = 0.5 * (g - (0.5 if s > 0 else 1.5))          # this leg's stride phase
        two_pi_phi = 2.0 * math.pi * phi
        pelvis_yaw = level("pelvis_yaw_rad") * pi_g.sin()
        pelvis_roll = -1.0 * level("pelvis_roll_rad") * (pi_g - 0.3 * math.pi).sin()
        pelvis_frame = euler_frame(pelvis_roll, nil, psi + pelvis_yaw)
        hip = point_on_frame(pelvis, pelvis_frame, Jet.constant([0.0, -s * 0.05 * height_m, 0.0], n))
        thigh = level("thigh_mean_rad") + level("thigh_amp_rad") * thigh_shape(phi)
        abduction = s * level("thigh_abduction_rad") * two_pi_phi.sin()
        rotation = s * level("thigh_rotation_rad") * (two_pi_phi.cos() + 0.5 * (2.0 * two_pi_phi).sin())
        w_roll = wobble(path, t, "wobble_rad", WOBBLE_S, None, foot)
        w_pitch = wobble(path, t, "wobble_rad", 0.8 * WOBBLE_S, None, foot)
        w_yaw = wobble(path, t, "wobble_rad", 1.2 * WOBBLE_S, None, foot)
        # ZYX pitch is positive nose-down: swinging the thigh forward is a negative pitch.
        leg = euler_frame(pelvis_roll + abduction, -1.0 * thigh, psi + pelvis_yaw + rotation)
        kick = leg_shock(path, t, foot)
        lever = Jet.constant([0.07, -s * 0.02, -0.115 * height_m], n)
        phone = point_on_frame(hip, leg, lever)
        phone = point_on_frame(phone, heading_frame, _vec(-1.2 * kick, nil, 0.7 * kick))
        # the phone rings on the soft tissue about its own centre
        ringing_frame = euler_frame(0.7 * w_roll, w_pitch, 0.5 * w_yaw)
        return _motion(phone, leg.compose(ringing_frame), q_mount)
    if placement == "torso":
        roll = -1.0 * level("trunk_roll_rad") * pi_g.cos()
        pitch = level("trunk_pitch_rad") * two_pi_g.cos()
        yaw = psi - level("trunk_yaw_rad") * pi_g.sin()
        trunk = euler_frame(roll, pitch, yaw)
        lever = Jet.constant([0.12, 0.0, (0.72 - 0.53) * height_m], n)
        return _motion(point_on_frame(pelvis, trunk, lever), trunk, q_mount)
    if placement == "hand":
        w_pitch = wobble(path, t, "hand_wobble_rad", WOBBLE_S, HAND_WOBBLE_HZ)
        w_roll = wobble(path, t, "hand_wobble_rad", 0.8 * WOBBLE_S, HAND_WOBBLE_HZ)
        pitch = -1.0 * level("hand_pitch_rad") * two_pi_g.sin()
        roll = 0.5 * level("trunk_roll_rad") * pi_g.cos()
        yaw = psi + 0.8 * level("trunk_yaw_rad") * pi_g.sin()
        hand = euler_frame(roll, pitch, yaw)
        lever = Jet.constant([0.30, -s * 0.05, (0.66 - 0.53) * height_m], n)
        # the arm rings after each heel strike: the hand bounces, the wrist lets the phone turn about its centre
        # and the elbow takes up part of the body's bounce (HAND_BOUNCE_KEPT of it reaches the hand)
        ring = wobble(path, t, "hand_ring_m", WOBBLE_S, HAND_WOBBLE_HZ) - (1.0 - HAND_BOUNCE_KEPT) * bounce
        phone = point_on_frame(point_on_frame(pelvis, hand, lever), heading_frame, _vec(0.5 * ring, nil, ring))
        ringing_frame = euler_frame(0.7 * w_roll, w_pitch, nil)
        return _motion(phone, hand.compose(ringing_frame), q_mount)
    raise ValueError(f"not a phone placement: {placement}")


def _motion(point: Jet, segment: Frame, q_mount: Array) -> Motion:
    return Motion(point.value, point.d1, point.d2, segment.then(q_mount))
