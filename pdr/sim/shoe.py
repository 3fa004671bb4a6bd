"""Shoe-mounted IMU: stance with zero velocity, swing between footprints, heel-strike impact.

Each foot alternates between *plants* (footprints, where it stays still) and *swings* to the next
footprint. The footprint of a step lies where the body is at mid-stance (the path point at
``t_strike + stance_fraction * step_period``), offset sideways by half the stance width, facing the
walking heading there. A swing ends at the heel strike and lasts ``(1 - stance_fraction)`` of the stride;
along it the foot moves with a quintic smoothstep (zero velocity and acceleration at both ends), rises by
a clearance bump, pitches heel-up after toe-off and toe-up before the strike, and turns to the new heading.
At heel strike a short (50 ms) vertical shock wavelet of the style's peak acceleration follows; it has no
net displacement or velocity change. Without stepping (standing, riding) the feet stay on their last
footprints, carried by the ground (escalator belt, elevator floor).

The foot frame is x forward, y left, z up; the IMU sits at the tracked point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.sim.gait import style
from pdr.sim.kinematics import Motion, euler_frame
from pdr.sim.smooth import SHOCK_PEAK_D2, Jet, bump, shock, smoothstep
from pdr.sim.trajectory import Path

Array = NDArray[np.float64]

IMPACT_S = 0.05
_MIN_STANCE_S = 0.12


@dataclass(frozen=True)
class FootPlan:
    """Footprints and swings of one foot.

    ``plant_pos`` (M + 1, 3) footprint positions in the walk displacement's coordinates (m), ``plant_yaw``
    (M + 1,) rad; plant 0 is the starting stance. Swing ``k`` (``swing_start_s[k]`` to ``swing_end_s[k]``,
    the heel strike) goes from plant ``k`` to plant ``k + 1`` with clearance ``clearance_m[k]``,
    toe-off and heel-strike pitch ``toe_off_rad[k]``, ``heel_rad[k]`` and impact ``impact_mps2[k]``.
    """

    plant_pos: Array
    plant_yaw: Array
    swing_start_s: Array
    swing_end_s: Array
    clearance_m: Array
    toe_off_rad: Array
    heel_rad: Array
    impact_mps2: Array


def plan_foot(path: Path, side: str, height_m: float) -> FootPlan:
    """Footprints and swing times of the ``side`` ("left"/"right") foot along ``path``."""
    sign = 1 if side == "right" else -1
    lateral = -sign * 0.06 * height_m
    steps = path.steps
    segs = path.scenario.segments
    b = path.scenario.boundaries_s
    mine = np.flatnonzero(steps.foot == sign)
    strike = steps.t_s[mine]
    period = steps.period_s[mine]
    seg_idx = np.clip(np.searchsorted(b, strike, side="right") - 1, 0, len(segs) - 1)
    styles = [style(segs[i].mode) for i in seg_idx]
    stance = np.array([s.stance_fraction for s in styles])
    window_end = path.bout_windows_s[steps.bout[mine] + 1]
    t_print = np.minimum(strike + stance * period, window_end)
    t_all = np.concatenate([[0.0], t_print])
    w = path.walk.evaluate(t_all).value
    yaw = path.heading.value(t_all).value
    normal = np.column_stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)])
    plants = w + lateral * normal
    prev_land = np.concatenate([[-np.inf], strike[:-1]])
    start = np.maximum(strike - (1.0 - stance) * 2.0 * period, prev_land + _MIN_STANCE_S + IMPACT_S)
    start = np.maximum(start, 0.0)
    return FootPlan(plants, yaw, start, strike, np.array([s.clearance_m for s in styles]),
                    np.array([s.toe_off_pitch_rad for s in styles]),
                    np.array([s.heel_strike_pitch_rad for s in styles]),
                    np.array([s.impact_mps2 for s in styles]))


def foot_motion(path: Path, t_s: Array, side: str, q_mount: Array, height_m: float) -> tuple[Motion, Array]:
    """Kinematics of the shoe IMU at times ``t_s`` and a (N,) flag: foot at rest (zero velocity)."""
    t = np.asarray(t_s, dtype=np.float64)
    plan = plan_foot(path, side, height_m)
    n = t.size
    done = np.searchsorted(plan.swing_end_s, t, side="right")           # swings completed by t
    pos = plan.plant_pos[done].copy()
    vel = np.zeros((n, 3))
    acc = np.zeros((n, 3))
    yaw = Jet(plan.plant_yaw[done].copy(), np.zeros(n), np.zeros(n))
    pitch = Jet(np.zeros(n), np.zeros(n), np.zeros(n))
    k = np.clip(np.searchsorted(plan.swing_start_s, t, side="right") - 1, 0, None)
    in_swing = (plan.swing_start_s.size > 0) & (k < plan.swing_start_s.size)
    if plan.swing_start_s.size:
        in_swing &= (t >= plan.swing_start_s[np.minimum(k, plan.swing_start_s.size - 1)]) & (done == k)
    if in_swing.any():
        ks = k[in_swing]
        dur = plan.swing_end_s[ks] - plan.swing_start_s[ks]
        u = (t[in_swing] - plan.swing_start_s[ks]) / dur
        a, b = plan.plant_pos[ks], plan.plant_pos[ks + 1]
        s0, s1, s2 = smoothstep(u)
        dz = b[:, 2] - a[:, 2]
        up = dz > 0
        xz = np.where(up, u / 0.7, (u - 0.3) / 0.7)                    # climb early, descend late
        z0, z1, z2 = smoothstep(xz)
        h0, h1, h2 = bump(u)
        d = (b - a)
        pos[in_swing] = a + d * s0[:, None]
        vel[in_swing] = d * (s1 / dur)[:, None]
        acc[in_swing] = d * (s2 / dur**2)[:, None]
        c = plan.clearance_m[ks]
        pos[in_swing, 2] = a[:, 2] + dz * z0 + c * h0
        vel[in_swing, 2] = (dz * z1 / 0.7 + c * h1) / dur
        acc[in_swing, 2] = (dz * z2 / 0.49 + c * h2) / dur**2
        dyaw = plan.plant_yaw[ks + 1] - plan.plant_yaw[ks]
        yaw.value[in_swing] = plan.plant_yaw[ks] + dyaw * s0
        yaw.d1[in_swing] = dyaw * s1 / dur
        yaw.d2[in_swing] = dyaw * s2 / dur**2
        # Pitch is positive nose-down (ZYX): heel up after toe-off, toe up before the strike.
        p_to = bump(u / 0.6)
        p_hs = bump((u - 0.4) / 0.6)
        to, hs = plan.toe_off_rad[ks], plan.heel_rad[ks]
        pitch.value[in_swing] = to * p_to[0] - hs * p_hs[0]
        pitch.d1[in_swing] = (to * p_to[1] - hs * p_hs[1]) / (0.6 * dur)
        pitch.d2[in_swing] = (to * p_to[2] - hs * p_hs[2]) / (0.36 * dur**2)
    # Heel-strike shock after each landing.
    last = done - 1
    since = t - plan.swing_end_s[np.maximum(last, 0)] if plan.swing_end_s.size else np.full(n, np.inf)
    hit = (last >= 0) & (since >= 0.0) & (since < IMPACT_S)
    if hit.any():
        amp = plan.impact_mps2[last[hit]] * IMPACT_S**2 / SHOCK_PEAK_D2
        f0, f1, f2 = shock(since[hit] / IMPACT_S)
        pos[hit, 2] += amp * f0
        vel[hit, 2] += amp * f1 / IMPACT_S
        acc[hit, 2] += amp * f2 / IMPACT_S**2
    ground = path.ground.evaluate(t)
    start = np.asarray(path.scenario.start_position_m)
    frame = euler_frame(Jet(np.zeros(n), np.zeros(n), np.zeros(n)), pitch, yaw).then(q_mount)
    at_rest = ~in_swing & ~hit & (np.linalg.norm(ground.d1, axis=1) < 1e-9)
    motion = Motion(pos + ground.value + start, vel + ground.d1, acc + ground.d2, frame)
    return motion, at_rest
