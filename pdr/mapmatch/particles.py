"""Particle filter over step events: walls kill the hypotheses of heading and step length they contradict.

Each particle holds a position (m, site frame), a heading offset (rad, added to the step's magnetometer-based
heading: that heading is a prior, not a truth) and a step-length scale. All particles share the floor of the
step events (the pipeline's floor estimate), whose plan they walk on. Per step ``k`` with length ``L_k`` and yaw
``psi_k`` (rad, counter-clockwise from the frame's x axis)::

    offset_i += wrap(dg_k - dpsi_k)            (a) what the gyro turned and the step heading did not
    offset_i *= exp(-L_k / mag_distance)       (b) optional: the magnetometer as a weak prior
    offset_i += N(0, offset_walk^2)            scale_i += N(0, scale_walk^2)
    psi_i = psi_k + offset_i + N(0, heading_step^2)
    l_i = L_k * scale_i + N(0, length_sigma^2)
    p_i += l_i (cos psi_i, sin psi_i)

Step (a) (``follow_gyro``, when the steps carry the gyro's heading ``g_k``; ``dg_k``, ``dpsi_k`` the changes of
``g`` and ``psi`` since the previous step) keeps each particle on the gyro's turns: where the magnetometer-based step
heading is pulled off by a disturbed field and later comes back, a particle's heading ``psi_k + offset_i`` does not
follow it, so the offset that the walls selected before the disturbance stays right after it. The random walk
``offset_walk`` then covers the gyro's drift and the phone turning in the hand against the walking direction (2 deg
per step stayed best: 1 and 3 did worse or no better on MS F3 and F4). Measured on the MS site2
traces (step heading against the truth's direction between waypoints): the gyro's heading has a lower standard
deviation about its own mean than the step heading on the traces with a disturbed start (5dd38ffd: 11 against
21 deg; 5dd3a34c: 15 against 25 deg), the same elsewhere. Step (b) draws the offsets back to 0, the magnetometer's
answer, over ``mag_distance_m`` of walking: the gyro's drift (and a wrong turn carried through a suspension) would
otherwise move the offsets without bound on a long walk through open space, while the magnetometer's indoor errors
are local. 40 m by default (3 seeds on cached MS site2 tracks, p75 online / smoothed: F3 3.37 / 3.46 m against
3.48 / 3.46 without relaxation and 3.35 / 3.43 with 10 m; F4 5.61 / 5.38 against 5.76 / 5.15 and 6.00 / 6.10; 10 m
cut F3's worst trace from 13 to 5 m; without relaxation, with each trace's true step scale, one F4 trace went 31 m
off after a suspension). Without a gyro heading (a) is skipped and the step heading carries the offset as before.

A particle whose step crosses a wall dies (its likelihood is zero, the others' equal), and each dead particle is
replaced by a copy of a survivor drawn uniformly: every survivor is kept and gets ``N / survivors`` copies on
average, as in multinomial resampling, but the lineages of the survivors are not resampled away (the smoother's
ancestry stays diverse). The dead particle takes the survivor's position but corrects only what its death gave
evidence about, told by the angle at which its step met the first wall on its way:

- grazing (less than ``graze_deg``, 45, to the wall): the heading was wrong (the particle drifted sideways into
  a corridor's side wall); it takes the survivor's heading offset and keeps its own step-length scale;
- head-on: the along-track position was wrong (past a corridor's end, a turn taken too early or too late); it
  takes the survivor's scale and keeps its own heading offset.

Were every death to copy the survivor whole, the survivors of a wandering heading would be the short striders
(sideways drift per step is the step length times the heading error) and the filter would learn too short a
stride: on MS site2 F3 / F4 the mean scale at the end of the walks was 0.97 / 0.96 where the truth needs
1.10 / 1.07 (a straight corridor walked with the true stride and a wandering heading: 0.98, now 1.00); and the
head-on deaths at the start, while the heading is unknown, narrowed the offsets to whichever survived first.
8 seeds on cached MS site2 tracks, p75 online / smoothed (m), copying whole -> split: F3 3.36 / 3.43 -> 3.21 /
3.22, F4 5.71 / 5.52 -> 5.47 / 5.04; with ``--calibrate cross`` F3 3.02 / 3.05 -> 2.64 / 2.59, F4 4.99 / 4.56 ->
4.68 / 4.26. The angle is no threshold tuned to a file: 30 and 60 deg give the same within the seeds' spread
(3 seeds, calibrated online F3 2.64 / 2.68, F4 4.71 / 4.67). Splitting only the scale (grazing deaths keep
their scale, head-on ones copy the survivor whole) did about half as well (F3 calibrated 2.87 / 2.91).

When every particle dies, the step is retried once with three times the heading and length noise; if they die
again, map matching is suspended with a notice and the track goes on as PDR (the last estimate walked with the
mean offset and scale) until it is back in the walkable area, where the particles are drawn again about it.

What limits it: the step-length scale. The walls give one-sided evidence about it: a particle that strides too far
dies head-on at a corridor's end, one that strides too short and turns early into a wide corridor or hall kills
nobody. So deaths only ever pull the scale down, and the prior (``scale_sigma`` 0.06 about 1) keeps it near 1 on
nearly every MS site2 trace, where the hindsight scales (PDR against the truth) run from 0.57 to 1.46. With each
trace's hindsight scale given, online p75 would be F3 2.35 / F4 3.03 m (no F3 and 4 F4 traces over 5 m); with its
hindsight rotation instead, 3.13 / 4.77 (8 seeds, cached tracks, in a session's study, not a shipped command). A
wider prior lets the ratchet act: with ``scale_sigma`` 0.15 the scale of trace 5dd398d3 fell from 1.00 to 0.90 at the
first corridor wall and its error grew from 1.7 to 6.4 m down the corridor. Also tried and not adopted (means over 8
seeds, online / smoothed p75, F3 and F4): ``length_sigma_m`` 0.10 (3.11 / 3.16, 5.05 / 4.68 against 3.09 / 3.11,
5.47 / 5.05: nearly all of F4's gain is one trace, 5dd3ac5f, whose particles no longer all die, while two F3
traces lose 0.7 m), reseeding about the last cloud instead of suspending (the same one-trace gain), no gyro
term, ``scale_walk`` 0.01, ``graze_deg`` 0 and 90, ``heading_offset_walk_deg`` 1. What does help is an outside
scale: the phone's K from its walks elsewhere (``pdr eval ms --map --calibrate cross``: online p75 F3 2.93 -> 2.60,
F4 5.49 -> 4.83 m). Two-sided evidence (a turn made where the walls
allow it says the walker got there) is not built. Traces with a step heading 47-68 deg off in open halls
(5dd52053, 5dd3a34c) lie outside the offset prior (20 deg) with no wall within reach: no map corrects those.
A wider prior does not reach them either: ``heading_offset_sigma_deg`` 30 and 45 (seed 0) took F3 from 2.93 to 3.16
and 3.66 m online; a tenth or a quarter of the particles drawn uniformly over the circle (3 seeds; 3.17 / 5.39 m
online F3 / F4 without) gave 3.67 / 5.88 and 4.39 / 6.92 m, the cloud's mean being pulled between the modes that
survive in halls. Where the walker brushes a wall (5dd3bbc0, the truth passing about 0.5 m from a corner), the
particles that die are those on the wall's side of the true path, and their survivors' heading offsets move away from
it (+25 deg there, with the step heading right and even with the hindsight scale): the deaths select position and
offset together.

A session's study of the F4 traces that the map makes worse or leaves over 5 m (3 seeds, 0-2, on cached MS site2
tracks, not a shipped command; baseline mean p75 online / smoothed F3 3.08 / 3.12, F4 5.41 / 5.02 m) found the scale
behind most of them: with each trace's hindsight scale (truth path over step lengths) F4 would be 3.59 / 2.65 m, and
online 5dd3bbc0 9.8 -> 3.1, 5dd3bbd3 5.9 -> 2.5, 5dd522ff 7.0 -> 2.3, 5dd3ac5f 6.7 -> 1.8, 5dd3bbcb 10.2 -> 4.0 m.
5dd3bbcb (scale 1.24) and 5dd3bbd3 (1.09) walk straight corridors of 90 and 50 m, where no wall tells the stride;
5dd3bbd3's scale also fell to 0.97 in its first 2 s, 895 of 1000 particles dying head-on in one step in the nook it
starts in while its first waypoint leg needs 0.5 (steps from rest). On 5dd3bbc0 (scale 0.77) the cloud overshoots up
a corridor and its deaths are grazing, so the evidence goes to the offset (+13 deg by step 9, +25 at the next wall)
and the scale stays 1.00. On 5dd3bb57 (1.25) the narrow corridor it turns into needs the scale and a +16 deg offset
together, which the priors hardly hold; the cloud stays 7 to 9 m behind, pressed against the wide corridor's wall.
The dead are longer striders than the cloud on every group of traces, those whose truth needs more than 1.05
included (by 0.002 to 0.010, about the cloud's variance over its mean; 0.01 to 0.04 with ``scale_sigma`` 0.13): a
longer step meets a wall sooner whatever its error, so deaths lower the scale even where they carry no stride
evidence, and with ``scale_sigma`` 0.13 or 0.15 the final mean scale passed 1.05 on at most 2 traces of 59 (the
hindsight scale is above 1.05 on 33). Tried and not adopted (online / smoothed, F3 then F4): soft walls, a crossing
step surviving with probability exp(-d^2/2s^2) of its depth ``d`` past the wall and stopped before it, s 0.1 / 0.2 /
0.3 m: 3.38 / 3.40, 5.39 / 4.71; 3.98 / 3.96, 5.95 / 5.19; 4.53 / 4.41, 6.66 / 5.69 (only 5dd3ac5f gains; the
waypoints lie 0.37 m or more inside the plan); a dead particle's offset and scale moved by the cloud's regression of
them on position times its jump to the survivor: 3.17 / 3.27, 5.69 / 5.46; that for the scale of head-on deaths
only: 3.02 / 3.02, 5.48 / 5.09 (``scale_sigma`` 0.13: 3.18 / 3.27, 4.95 / 4.95); the graze angle taken against the
walk from the start instead of the step: 3.38 / 3.35, 5.59 / 5.39; the scale copied when the jump to the survivor
lies along that walk: 3.03 / 2.97, 5.73 / 5.15; survivors drawn in proportion to their scale (against the length
bias above): 3.12 / 3.14, 5.49 / 4.94 (``scale_sigma`` 0.13: 3.21 / 3.36, 4.89 / 4.86); no death copying the scale:
3.04 / 3.09, 5.56 / 5.10. What helps F4 costs F3. A step-length factor of 1.07 (the path ratio over all traces of
either floor: F3 1.084, F4 1.066) gives 2.56 / 2.62, 4.96 / 4.21: the calibration, not the map.

Online: :meth:`MapMatcher.update` takes a batch of steps and returns one :class:`MatchedStep` each; its
:meth:`~MapMatcher.state` (particle arrays, the random generator's state and a few scalars: size independent of
the walk's length) resumes bit-identically with :meth:`~MapMatcher.from_state`. Offline: :func:`smooth_walk` runs
the same filter with its ancestry and returns each step's position averaged over the lineages of the final
particles (the genealogy of a particle filter as a fixed-interval smoother, Kitagawa 1996).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.frames import heading_deg_to_yaw
from pdr.mapmatch.kernel import advance_particles, cloud_summary, resample_summary
from pdr.site.plan import SitePlan
from pdr.site.wall_index import WallIndex

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

STATE_VERSION = 1

#: No resampling draws (every particle survived the step).
_NO_DRAWS = np.zeros(0, dtype=np.int64)


@dataclass(frozen=True)
class StepInput:
    """One step of the pipeline: end time (s, log clock), length (m), compass heading (deg), floor, and the gyro's
    heading (deg, arbitrary origin: only its changes count; None without a gyroscope).
    """

    t_s: float
    length_m: float
    heading_deg: float
    floor: int
    gyro_heading_deg: float | None = None


@dataclass(frozen=True)
class MatchedStep:
    """One map-matched step: position (m, site frame), floor, whether the map constrained it, and the spread.

    ``spread_m``: root mean square distance of the particles from their mean (m; 0 while suspended);
    ``heading_offset_deg``, ``scale``: the particles' mean heading offset (deg, counter-clockwise) and
    step-length scale.
    """

    t_s: float
    east_m: float
    north_m: float
    floor: int
    matched: bool
    spread_m: float
    heading_offset_deg: float
    scale: float


@dataclass(frozen=True)
class MapMatchConfig:
    """Noise of the particle filter (module doc). Angles in degrees, lengths in metres.

    ``follow_gyro``: carry the offsets through the gyro's turns (eq. (a)); ``mag_distance_m``: the walking distance
    (m) over which the offsets relax to the magnetometer-based heading (eq. (b); ``inf``: never); ``graze_deg``: a
    particle that dies meeting a wall at less than this angle takes a survivor's heading offset and keeps its own
    step-length scale, at more the reverse (module doc; 0: every death counts as head-on).
    """

    particles: int = 1000
    start_sigma_m: float = 0.3
    heading_offset_sigma_deg: float = 20.0
    heading_offset_walk_deg: float = 2.0
    heading_step_sigma_deg: float = 3.0
    scale_sigma: float = 0.06
    scale_walk: float = 0.001
    scale_bounds: tuple[float, float] = (0.6, 1.6)
    length_sigma_m: float = 0.05
    reseed_sigma_m: float = 1.0
    follow_gyro: bool = True
    mag_distance_m: float = 40.0
    graze_deg: float = 45.0
    seed: int = 0


def steps_from_rows(rows: Sequence[dict[str, Any]]) -> list[StepInput]:
    """The pipeline's step events (or track rows) as :class:`StepInput`."""
    return [step_input(r["t_s"], r["step_length_m"], r["heading_deg"], r["floor"], r.get("gyro_heading_deg"))
            for r in rows]


def step_input(t_s: Any, length_m: Any, heading_deg: Any, floor: Any, gyro_heading_deg: Any,
               floor_shift: int = 0) -> StepInput:
    """A :class:`StepInput` from a step's fields (floor rounded to an integer, plus ``floor_shift``)."""
    return StepInput(float(t_s), float(length_m), float(heading_deg), int(round(float(floor))) + floor_shift,
                     None if gyro_heading_deg is None else float(gyro_heading_deg))


@dataclass
class _History:
    """Per step of a walk: particle positions after resampling and each one's parent index (-1: reseeded)."""

    pos: list[NDArray[np.float32]] = field(default_factory=list)
    parent: list[NDArray[np.int32]] = field(default_factory=list)


class MapMatcher:
    """Online particle filter on a site's floor plans (module doc)."""

    def __init__(self, site: SitePlan, start_en: tuple[float, float], floor: int,
                 config: MapMatchConfig | None = None, source: str = "start") -> None:
        self.site = site
        self.config = c = config or MapMatchConfig()
        site.check_walkable(start_en, floor, source)
        start = np.array([start_en], dtype=np.float64)
        self.rng = np.random.Generator(np.random.PCG64(c.seed))
        self.floor = int(floor)
        self.pos = self._draw_about(start[0], c.start_sigma_m)
        self.offset = self.rng.normal(0.0, math.radians(c.heading_offset_sigma_deg), c.particles)
        self.scale = np.clip(self.rng.normal(1.0, c.scale_sigma, c.particles), *c.scale_bounds)
        self.suspended = False
        self.dr = start[0].copy()               # the estimate while suspended (m)
        self.history: _History | None = None
        self._grid_rad = math.radians(site.frame_bearing_deg or 0.0)
        self.prev_turn = (math.nan, math.nan)   # the previous step's yaw and gyro yaw (rad)

    # -- state ------------------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Everything :meth:`from_state` needs to go on bit-identically (size independent of the walk)."""
        return {"version": STATE_VERSION, "floor": self.floor, "pos": self.pos.copy(), "offset": self.offset.copy(),
                "scale": self.scale.copy(), "suspended": self.suspended, "dr": self.dr.copy(),
                "rng": self.rng.bit_generator.state, "prev_turn": list(self.prev_turn)}

    @classmethod
    def from_state(cls, site: SitePlan, state: dict[str, Any], config: MapMatchConfig | None = None) -> MapMatcher:
        if not isinstance(state, dict) or state.get("version") != STATE_VERSION:
            raise InputError(f"map matcher state of another version (expected {STATE_VERSION})",
                             source="map matcher state", field="version")
        self = cls.__new__(cls)
        self.site, self.config, self.history = site, config or MapMatchConfig(), None
        self.floor = int(state["floor"])
        self.pos = np.array(state["pos"], dtype=np.float64).reshape(-1, 2)
        self.offset = np.array(state["offset"], dtype=np.float64)
        self.scale = np.array(state["scale"], dtype=np.float64)
        self.suspended = bool(state["suspended"])
        self.dr = np.array(state["dr"], dtype=np.float64)
        self.rng = np.random.Generator(np.random.PCG64())
        self.rng.bit_generator.state = state["rng"]
        self._grid_rad = math.radians(site.frame_bearing_deg or 0.0)
        prev = state.get("prev_turn") or (math.nan, math.nan)      # absent from states saved before it
        self.prev_turn = (float(prev[0]), float(prev[1]))
        return self

    # -- filter -----------------------------------------------------------------------------------
    def update(self, steps: Sequence[StepInput]) -> tuple[list[MatchedStep], list[str]]:
        """Match a batch of steps; returns one :class:`MatchedStep` per step and the notices raised."""
        out: list[MatchedStep] = []
        notices: list[str] = []
        for s in steps:
            out.append(self._step(s, notices))
        return out, notices

    def _walls(self, floor: int) -> WallIndex | None:
        plan = self.site.floors.get(floor)
        return None if plan is None else plan.wall_index

    def _step(self, s: StepInput, notices: list[str]) -> MatchedStep:
        c = self.config
        yaw = float(heading_deg_to_yaw(s.heading_deg)) + self._grid_rad
        if s.floor != self.floor:
            self.floor = s.floor
            if not self.suspended and self.site.floors.get(s.floor) is None:
                self._suspend(notices, f"floor {s.floor} has no floor plan")
        walls = self._walls(self.floor)
        if self.suspended:
            self.dr = self._dead_reckon(self.dr, yaw, s.length_m)
            plan = self.site.floors.get(self.floor)
            if plan is not None and plan.contains(self.dr[None, :])[0]:
                self._reseed(notices, s.t_s)
                return self._estimate(s.t_s)
            return self._unmatched(s.t_s)
        assert walls is not None
        n = c.particles
        noise = self.rng.standard_normal((4, n))
        turn, relax = self._carry_terms(yaw, s)
        new, alive, across, n_alive = advance_particles(
            self.pos, self.offset, self.scale, noise, turn, relax, math.radians(c.heading_offset_walk_deg),
            c.scale_walk, c.scale_bounds, yaw, s.length_m, math.radians(c.heading_step_sigma_deg), c.length_sigma_m,
            walls, 3.0)
        if n_alive == 0:
            self.dr = self._dead_reckon(np.mean(self.pos, axis=0), yaw, s.length_m)
            self._suspend(notices, f"every particle crossed a wall at t = {s.t_s:.2f} s")
            return self._unmatched(s.t_s)
        draws = self.rng.integers(0, n_alive, n - n_alive) if n_alive < n else _NO_DRAWS
        self.pos, self.offset, self.scale, pick, mx, my, spread, off, scale = resample_summary(
            new, self.offset, self.scale, alive, draws, across, math.sin(math.radians(c.graze_deg)))
        self._record(pick)
        return MatchedStep(s.t_s, mx, my, self.floor, True, spread, math.degrees(off), scale)

    def _carry_terms(self, yaw: float, s: StepInput) -> tuple[float, float]:
        """What carries the heading offsets to this step: the turn (rad) the gyro made and the step heading did
        not (eq. (a) of the module doc; 0 without it) and the factor relaxing them towards 0 over
        ``mag_distance_m`` of walking (eq. (b); 1 without it).
        """
        c = self.config
        gyro = math.nan if s.gyro_heading_deg is None else float(heading_deg_to_yaw(s.gyro_heading_deg))
        y0, g0 = self.prev_turn
        self.prev_turn = (yaw, gyro)
        turn = 0.0
        if c.follow_gyro and not (math.isnan(g0) or math.isnan(gyro)):
            turn = _wrap((gyro - g0) - (yaw - y0))
        relax = math.exp(-s.length_m / c.mag_distance_m) if math.isfinite(c.mag_distance_m) else 1.0
        return turn, relax

    def _dead_reckon(self, pos: FloatArray, yaw: float, length_m: float) -> FloatArray:
        """``pos`` (m) walked one step with the particles' mean heading offset and step-length scale."""
        psi = yaw + _circ_mean(self.offset)
        return np.asarray(pos + length_m * float(np.mean(self.scale)) * np.array([math.cos(psi), math.sin(psi)]))

    def _unmatched(self, t_s: float) -> MatchedStep:
        """The dead-reckoned estimate of a step the map does not constrain (recorded for the smoother)."""
        self._record(None)
        return MatchedStep(t_s, float(self.dr[0]), float(self.dr[1]), self.floor, False, 0.0,
                           math.degrees(_circ_mean(self.offset)), float(np.mean(self.scale)))

    def _estimate(self, t_s: float) -> MatchedStep:
        mx, my, spread, off, scale = cloud_summary(self.pos, self.offset, self.scale)
        return MatchedStep(t_s, mx, my, self.floor, True, spread, math.degrees(off), scale)

    def _suspend(self, notices: list[str], why: str) -> None:
        self.suspended = True
        notices.append(f"map matching suspended ({why}); the track goes on as PDR")

    def _reseed(self, notices: list[str], t_s: float) -> None:
        self.suspended = False
        self.pos = self._draw_about(self.dr, self.config.reseed_sigma_m)
        notices.append(f"map matching resumed at t = {t_s:.2f} s (back in floor {self.floor}'s walkable area)")
        self._record(None)

    def _draw_about(self, centre: FloatArray, sigma_m: float) -> FloatArray:
        """``particles`` positions about ``centre`` (m, walkable): a draw behind a wall seen from the centre is
        replaced by the centre (one wall-index query instead of a point-in-polygon test per particle).
        """
        n = self.config.particles
        pts = centre[None, :] + self.rng.normal(0.0, sigma_m, (n, 2))
        c = np.broadcast_to(centre, pts.shape)
        behind = self.site.floor(self.floor).wall_index.crosses(c[:, 0], c[:, 1], pts[:, 0], pts[:, 1])
        pts[behind] = centre
        return pts

    def _record(self, parent: IntArray | None) -> None:
        if self.history is None:
            return
        self.history.pos.append(self.pos.astype(np.float32) if not self.suspended else
                                np.repeat(self.dr[None, :], 1, axis=0).astype(np.float32))
        self.history.parent.append(np.full(1, -1, np.int32) if parent is None else parent.astype(np.int32))


def _wrap(a: float) -> float:
    """``a`` (rad) wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _circ_mean(a: FloatArray) -> float:
    return math.atan2(float(np.mean(np.sin(a))), float(np.mean(np.cos(a))))


def smooth_walk(site: SitePlan, steps: Sequence[StepInput], start_en: tuple[float, float], floor: int,
                config: MapMatchConfig | None = None, source: str = "start") -> tuple[list[MatchedStep], list[str]]:
    """Offline: the filter over the whole walk, each step's position averaged over the final lineages."""
    mm = MapMatcher(site, start_en, floor, config, source)
    mm.history = _History()
    online, notices = mm.update(steps)
    hist = mm.history
    out = list(online)
    lineage: IntArray | None = None
    for k in range(len(online) - 1, -1, -1):
        if not online[k].matched:
            lineage = None
            continue
        pos = hist.pos[k]
        if lineage is None:
            lineage = np.arange(len(pos))
        m = pos[lineage].astype(np.float64).mean(axis=0)
        out[k] = MatchedStep(online[k].t_s, float(m[0]), float(m[1]), online[k].floor, True, online[k].spread_m,
                             online[k].heading_offset_deg, online[k].scale)
        parent = hist.parent[k]
        lineage = None if parent[0] < 0 else parent[lineage].astype(np.int64)
    return out, notices
