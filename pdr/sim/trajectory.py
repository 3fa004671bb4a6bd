"""The walker's path: where the person goes, how fast, facing where, and when each step falls.

The path is built from a :class:`~pdr.sim.scenario.Scenario` out of smooth levels
(:class:`~pdr.sim.smooth.StepProfile`): walking speed, step frequency and vertical speed per segment,
the walking heading (turns spread over their segment) and the motion of the ground under the feet
(escalator belt, elevator cabin). Two displacements add up to the path point (on the floor, under the
pelvis): the *walk* (what the legs do; stairs included) and the *ground* (what carries the person).
Velocities and accelerations are analytic; horizontal positions are their integral (Hermite-corrected
trapezoid on a 4 ms grid, error far below a micrometre).

Gait phase: ``g(t) = integral f dt`` counted from the start of each walking bout (a run of stepping
segments); a step (heel strike) happens at every ``g = k + 1/2``, of the right foot for even ``k``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.recording import Labels
from pdr.sim.scenario import Scenario
from pdr.sim.smooth import Jet, StepProfile

Array = NDArray[np.float64]

#: Time over which walking speed, step frequency and gait amplitudes change between segments, s.
GAIT_TRANSITION_S = 1.0
#: Time over which an escalator belt starts or stops under the feet, s.
RIDE_TRANSITION_S = 1.0
_GRID_DT_S = 0.004


@dataclass(frozen=True)
class Mover:
    """A displacement from horizontal speed along the heading plus vertical speed (both in m/s)."""

    speed: StepProfile
    climb: StepProfile
    heading: StepProfile
    grid_t: Array
    grid_pos: Array

    @staticmethod
    def build(speed: StepProfile, climb: StepProfile, heading: StepProfile, duration_s: float) -> Mover:
        t = np.arange(0.0, duration_s + 2 * _GRID_DT_S, _GRID_DT_S)
        vel, acc = _horizontal(speed, heading, t)
        h = np.diff(t)[:, None]
        inc = 0.5 * h * (vel[:-1] + vel[1:]) + h**2 / 12.0 * (acc[:-1] - acc[1:])
        pos = np.concatenate([np.zeros((1, 2)), np.cumsum(inc, axis=0)])
        return Mover(speed, climb, heading, t, pos)

    def evaluate(self, t_s: Array) -> Jet:
        """Displacement (N, 3) in m, ENU, with velocity and acceleration, at times ``t_s``."""
        t = np.asarray(t_s, dtype=np.float64)
        vel, acc = _horizontal(self.speed, self.heading, t)
        i = np.clip(np.searchsorted(self.grid_t, t, side="right") - 1, 0, self.grid_t.size - 2)
        h = (t - self.grid_t[i])[:, None]
        v0, a0 = _horizontal(self.speed, self.heading, self.grid_t[i])
        pos_h = self.grid_pos[i] + 0.5 * h * (v0 + vel) + h**2 / 12.0 * (a0 - acc)
        z = self.climb.integral(t)
        return Jet(np.column_stack([pos_h, z.value]), np.column_stack([vel, z.d1]), np.column_stack([acc, z.d2]))


def _horizontal(speed: StepProfile, heading: StepProfile, t: Array) -> tuple[Array, Array]:
    v = speed.value(t)
    psi = heading.value(t)
    c, s = np.cos(psi.value), np.sin(psi.value)
    vel = np.column_stack([v.value * c, v.value * s])
    acc = np.column_stack([v.d1 * c - v.value * psi.d1 * s, v.d1 * s + v.value * psi.d1 * c])
    return vel, acc


@dataclass(frozen=True)
class Steps:
    """Step events (heel strikes): times in s, foot (+1 right, -1 left), bout index, step period in s."""

    t_s: Array
    foot: NDArray[np.int64]
    bout: NDArray[np.int64]
    period_s: Array


@dataclass(frozen=True)
class Path:
    """The walker's path for one scenario; see the module docstring."""

    scenario: Scenario
    heading: StepProfile
    step_frequency: StepProfile
    walk: Mover
    ground: Mover
    bout_windows_s: Array
    bout_offsets: Array
    steps: Steps

    @property
    def duration_s(self) -> float:
        return self.scenario.duration_s

    def levels(self, values: list[float], max_transition_s: float = GAIT_TRANSITION_S) -> StepProfile:
        """A smooth level taking ``values[i]`` on segment ``i`` (e.g. a gait amplitude per mode)."""
        return StepProfile.from_levels(self.scenario.boundaries_s, values, max_transition_s)

    def position(self, t_s: Array) -> Jet:
        """Path point (on the floor under the pelvis), ENU m, with velocity and acceleration."""
        p = self.walk.evaluate(t_s) + self.ground.evaluate(t_s)
        return p + np.asarray(self.scenario.start_position_m)

    def phase(self, t_s: Array) -> Jet:
        """Gait phase in steps since the start of the current walking bout, with its derivatives."""
        t = np.asarray(t_s, dtype=np.float64)
        total = self.step_frequency.integral(t)
        bout = np.clip(np.searchsorted(self.bout_windows_s, t, side="right") - 1, 0, self.bout_offsets.size - 1)
        return total - self.bout_offsets[bout]

    def floor(self, z_m: Array) -> Array:
        """Floor number of heights ``z_m`` (ENU up, m): the start floor plus whole floor heights climbed."""
        rel = (np.asarray(z_m) - self.scenario.start_position_m[2]) / self.scenario.floor_height_m
        return self.scenario.start_floor + np.round(rel)

    def modes(self) -> Labels:
        """Motion-mode intervals (consecutive segments of the same mode merged)."""
        b = self.scenario.boundaries_s
        starts: list[float] = []
        ends: list[float] = []
        names: list[str] = []
        for i, seg in enumerate(self.scenario.segments):
            if names and names[-1] == seg.mode:
                ends[-1] = b[i + 1]
            else:
                starts.append(b[i])
                ends.append(b[i + 1])
                names.append(seg.mode)
        return Labels(np.array(starts), np.array(ends), tuple(names))

    def landmarks(self) -> Labels:
        """Landmark intervals: stairs, elevators, escalators and turns (one per segment)."""
        b = self.scenario.boundaries_s
        idx = [i for i, s in enumerate(self.scenario.segments) if s.landmark]
        return Labels(b[idx], b[np.array(idx, dtype=int) + 1],
                      tuple(self.scenario.segments[i].landmark for i in idx))

    def step_lengths_m(self) -> Array:
        """Horizontal distance walked since the previous step of the bout (or since the bout started), m."""
        st = self.steps
        if st.t_s.size == 0:
            return np.zeros(0)
        starts = self.bout_windows_s[st.bout]
        prev = np.where(np.r_[True, st.bout[1:] != st.bout[:-1]], starts, np.r_[0.0, st.t_s[:-1]])
        a = self.walk.evaluate(prev).value[:, :2]
        b = self.walk.evaluate(st.t_s).value[:, :2]
        return np.linalg.norm(b - a, axis=1)


def _bouts(scenario: Scenario) -> list[tuple[int, int]]:
    """(first, last) segment indices of each run of stepping segments."""
    out: list[tuple[int, int]] = []
    for i, seg in enumerate(scenario.segments):
        if seg.stepping:
            if out and out[-1][1] == i - 1:
                out[-1] = (out[-1][0], i)
            else:
                out.append((i, i))
    return out


def _elevator_transitions(scenario: Scenario) -> list[tuple[float, float, float]]:
    b = scenario.boundaries_s
    out = []
    for i, seg in enumerate(scenario.segments):
        if seg.kind != "elevator":
            continue
        v = math.copysign(seg.ride_speed_mps, seg.climb_m)
        go = b[i] + seg.wait_s
        stop = go + abs(seg.climb_m) / seg.ride_speed_mps
        out += [(go, go + seg.ramp_s, v), (stop, stop + seg.ramp_s, -v)]
    return out


def _find_steps(path_phase: Path, windows: Array, duration: float) -> Steps:
    times, feet, bouts, periods = [], [], [], []
    for k in range(windows.size - 1):
        a, b = windows[k], min(windows[k + 1], duration)
        grid = np.arange(a, b + _GRID_DT_S, _GRID_DT_S)
        grid = grid[(grid <= b) & (grid < windows[k + 1])]   # the next window restarts the count
        g = path_phase.phase(grid).value
        targets = np.arange(0.5, g[-1], 1.0) if g[-1] > 0.5 else np.zeros(0)
        for j, target in enumerate(targets):
            i = int(np.searchsorted(g, target))
            i = min(max(i, 1), g.size - 1)
            t = grid[i - 1] + (target - g[i - 1]) / (g[i] - g[i - 1]) * (grid[i] - grid[i - 1])
            for _ in range(3):  # Newton on g(t) = target, g' = f > 0 at a crossing
                jet = path_phase.phase(np.array([t]))
                if jet.d1[0] <= 0:
                    break
                t = float(np.clip(t - (jet.value[0] - target) / jet.d1[0], grid[i - 1], grid[i]))
            times.append(t)
            feet.append(1 if j % 2 == 0 else -1)
            bouts.append(k)
        if targets.size:
            f = path_phase.step_frequency.value(np.array(times[-targets.size:])).value
            periods += list(1.0 / np.maximum(f, 1e-3))
    return Steps(np.array(times, dtype=np.float64), np.array(feet, dtype=np.int64),
                 np.array(bouts, dtype=np.int64), np.array(periods, dtype=np.float64))


def build_path(scenario: Scenario) -> Path:
    """The path of a scenario (deterministic: no randomness is involved)."""
    segs = scenario.segments
    b = scenario.boundaries_s
    duration = scenario.duration_s
    heading = StepProfile.build(scenario.start_yaw_rad,
                                [(b[i], b[i + 1], s.turn_rad) for i, s in enumerate(segs) if s.turn_rad])
    speed = StepProfile.from_levels(b, [s.speed_mps for s in segs], GAIT_TRANSITION_S)
    freq = StepProfile.from_levels(b, [s.step_frequency_hz for s in segs], GAIT_TRANSITION_S)
    walk_climb = StepProfile.from_levels(
        b, [s.climb_m / s.duration_s if s.kind == "stairs" else 0.0 for s in segs], GAIT_TRANSITION_S)
    ride_h = StepProfile.from_levels(
        b, [s.ride_speed_mps * math.cos(s.incline_rad) if s.kind == "escalator" else 0.0 for s in segs],
        RIDE_TRANSITION_S)
    escalator_v = StepProfile.from_levels(
        b, [s.climb_m / s.duration_s if s.kind == "escalator" else 0.0 for s in segs], RIDE_TRANSITION_S)
    ride_v = StepProfile.build(0.0, [*zip(escalator_v.starts, escalator_v.ends, escalator_v.deltas, strict=True),
                                     *_elevator_transitions(scenario)])
    walk = Mover.build(speed, walk_climb, heading, duration)
    ground = Mover.build(ride_h, ride_v, heading, duration)

    # Bout windows run from the middle of one non-stepping stretch to the middle of the next; the step
    # frequency is exactly zero there, so restarting the phase count there keeps it smooth.
    bouts = _bouts(scenario)
    windows = [0.0]
    for (_, last), (first, _) in zip(bouts[:-1], bouts[1:], strict=True):
        windows.append(0.5 * (b[last + 1] + b[first]))
    windows.append(duration + 1.0)
    win = np.array(windows)
    offsets = freq.integral(win[:-1]).value
    offsets[0] = 0.0
    path = Path(scenario, heading, freq, walk, ground, win, offsets, Steps(np.zeros(0), np.zeros(0, np.int64),
                                                                         np.zeros(0, np.int64), np.zeros(0)))
    steps = _find_steps(path, win, duration)
    return Path(scenario, heading, freq, walk, ground, win, offsets, steps)
