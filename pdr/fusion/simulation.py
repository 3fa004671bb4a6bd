"""The simulations of seed 001 Sec. 5.1: step-wise dead reckoning of dual feet plus round-robin ranging.

"The agents move with 1 m steps at 1 Hz. Gaussian errors with standard deviation 0.01 m and 0.2 deg were
added to the step displacements and the heading changes, respectively, and heavy-tailed Cauchy distributed
errors of scale 1 m were added to the range measurements. The ranging is done time-multiplexed in a
round-robin fashion at a total rate of 1 Hz." Two scenarios: the straight-line march of N agents 10 m apart
(Sec. 5.1.1) and three static agents with a fourth walking a circle around them (Sec. 5.1.2).

Each foot resets once per step: the left foot at ``t = k / f_step`` and the right foot half a period later,
each moving one step length along the agent's path (so the two feet alternate, half a step apart). The
radio is at the agent's body, on the path at ``s = v t``. Static agents' foot units are locked (Sec. 3.1) and
report zero displacement with zero covariance at the step rate.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.frames import wrap_angle
from pdr.fusion.centre import FusionCentre, FusionConfig
from pdr.fusion.dead_reckoning import rotation_z
from pdr.fusion.state import FOOT_DIM, FootKey
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SimulationConfig:
    """Sensor and gait parameters of Sec. 5.1.

    Attributes
    ----------
    step_length_m
        Length of each step (each foot moves this far per reset), m.
    step_rate_hz
        Resets per second of each foot, Hz.
    step_sigma_m
        Standard deviation of the displacement error, per axis, m.
    heading_sigma_deg
        Standard deviation of the heading-change error, deg.
    range_scale_m
        Scale of the Cauchy range error, m.
    ranging_rate_hz
        Total ranging rate of the group (round robin over the pairs), Hz.
    foot_spacing_m
        Lateral distance between the two feet, m.
    """

    step_length_m: float = 1.0
    step_rate_hz: float = 1.0
    step_sigma_m: float = 0.01
    heading_sigma_deg: float = 0.2
    range_scale_m: float = 1.0
    ranging_rate_hz: float = 1.0
    foot_spacing_m: float = 0.2

    def __post_init__(self) -> None:
        for name in ("step_length_m", "step_rate_hz", "ranging_rate_hz"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InputError("must be positive", field=name)
        for name in ("step_sigma_m", "heading_sigma_deg", "range_scale_m", "foot_spacing_m"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InputError("must be non-negative", field=name)

    @property
    def speed_mps(self) -> float:
        """Walking speed, m/s."""
        return self.step_length_m * self.step_rate_hz

    def step_cov(self) -> Array:
        """(4, 4) covariance of ``(dp, dpsi)`` reported with every step."""
        return np.diag([self.step_sigma_m**2] * 3 + [math.radians(self.heading_sigma_deg) ** 2])


#: A path: arc length s (m) -> ((..., 3) position m ENU, (...,) heading rad).
Path = Callable[[Array], tuple[Array, Array]]


def straight_path(start_n: Array, heading: float) -> Path:
    """Straight line from ``start_n`` (m) with constant heading (rad, CCW from east)."""
    direction = np.array([math.cos(heading), math.sin(heading), 0.0])

    def path(s: Array) -> tuple[Array, Array]:
        s = np.asarray(s, dtype=np.float64)
        return start_n + s[..., None] * direction, np.full(s.shape, heading)

    return path


def circle_path(centre_n: Array, radius_m: float, start_angle: float) -> Path:
    """Counter-clockwise circle of ``radius_m`` around ``centre_n``, starting at polar angle ``start_angle``."""

    def path(s: Array) -> tuple[Array, Array]:
        a = start_angle + np.asarray(s, dtype=np.float64) / radius_m
        pos = centre_n + radius_m * np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=-1)
        return pos, a + math.pi / 2.0

    return path


@dataclass(frozen=True)
class AgentPlan:
    """One simulated agent: ``path`` or ``None`` for a static agent at ``static_n`` with ``static_heading``."""

    name: str
    path: Path | None
    static_n: Array = field(default_factory=lambda: np.zeros(3))
    static_heading: float = 0.0


@dataclass(frozen=True)
class FootTruth:
    """True reset positions of one foot: (L+1,) times s, (L+1, 3) positions m ENU, (L+1,) headings rad."""

    t_s: Array
    pos_n: Array
    heading: Array


class StepEvent(NamedTuple):
    """A foot's step summary arriving at the fusion centre."""

    t_s: float
    agent: str
    foot: str
    increment: StepIncrement


class RangeEvent(NamedTuple):
    """A range between two agents' radios: measured (with error) and true, m."""

    t_s: float
    agent_a: str
    agent_b: str
    measured_m: float
    true_m: float


@dataclass(frozen=True)
class Scenario:
    """A simulated group: truth, the step summaries and ranges, in time order.

    Attributes
    ----------
    agents
        Agent names.
    truth
        True reset poses per foot (row 0 is the initial pose at t = 0).
    body
        Agent name -> (T,) -> (T, 3) true radio position at given times, m.
    steps
        (t_s, agent, foot, increment) in time order.
    ranges
        (t_s, agent_a, agent_b, measured_m, true_m) in time order.
    duration_s
        Length of the scenario, s.
    """

    agents: tuple[str, ...]
    truth: dict[FootKey, FootTruth]
    body: dict[str, Callable[[Array], Array]]
    steps: list[StepEvent]
    ranges: list[RangeEvent]
    duration_s: float

    def events(self, ranging: bool = True) -> list[StepEvent | RangeEvent]:
        """Steps and (optionally) ranges merged in time order; at equal times steps come first."""
        out: list[StepEvent | RangeEvent] = list(self.steps)
        if ranging:
            out += self.ranges
        out.sort(key=lambda e: (e.t_s, isinstance(e, RangeEvent)))
        return out


FEET = ("left", "right")


def _foot_truth(plan: AgentPlan, foot_index: int, n_steps: int, cfg: SimulationConfig) -> FootTruth:
    phase = 0.5 * foot_index                              # right foot half a period after the left
    k = np.arange(n_steps + 1, dtype=np.float64)
    t = np.where(k == 0, 0.0, (k + phase - (1.0 if foot_index else 0.0)) / cfg.step_rate_hz)
    side = 0.5 * cfg.foot_spacing_m * (1.0 if foot_index == 0 else -1.0)  # left foot on the left
    if plan.path is None:
        pos = np.repeat(plan.static_n[None, :], n_steps + 1, axis=0)
        heading = np.full(n_steps + 1, plan.static_heading)
    else:
        s = (k + phase - (1.0 if foot_index else 0.0)) * cfg.step_length_m
        pos, heading = plan.path(s)
    normal = np.stack([-np.sin(heading), np.cos(heading), np.zeros_like(heading)], axis=-1)
    return FootTruth(t, pos + side * normal, heading)


def _increments(truth: FootTruth, cfg: SimulationConfig, static: bool,
                rng: np.random.Generator) -> list[StepIncrement]:
    out = []
    cov = np.zeros((FOOT_DIM, FOOT_DIM)) if static else cfg.step_cov()
    for k in range(1, truth.t_s.size):
        dp = rotation_z(float(truth.heading[k - 1])).T @ (truth.pos_n[k] - truth.pos_n[k - 1])
        dpsi = float(wrap_angle(truth.heading[k] - truth.heading[k - 1]))
        if not static:
            dp = dp + rng.normal(0.0, cfg.step_sigma_m, 3)
            dpsi += float(rng.normal(0.0, math.radians(cfg.heading_sigma_deg)))
        out.append(StepIncrement(float(truth.t_s[k]), k, dp, dpsi, cov))
    return out


def _body(plan: AgentPlan, speed_mps: float) -> Callable[[Array], Array]:
    """True radio position of an agent at given times: on its path at ``s = v t`` (or static)."""
    path = plan.path
    if path is None:
        return lambda t: np.repeat(plan.static_n[None, :], np.size(t), axis=0)
    return lambda t: path(speed_mps * np.asarray(t, dtype=np.float64))[0]


def build_scenario(plans: Iterable[AgentPlan], duration_s: float, cfg: SimulationConfig,
                   rng: np.random.Generator) -> Scenario:
    """Truth, noisy step summaries and round-robin Cauchy ranges for a set of agents."""
    plans = list(plans)
    if len({p.name for p in plans}) != len(plans):
        raise InputError("agent names must be distinct", field="agents")
    n_steps = int(math.floor(duration_s * cfg.step_rate_hz + 1e-9))
    truth: dict[FootKey, FootTruth] = {}
    steps: list[StepEvent] = []
    body: dict[str, Callable[[Array], Array]] = {}
    for plan in plans:
        for i, foot in enumerate(FEET):
            ft = _foot_truth(plan, i, n_steps, cfg)
            keep = ft.t_s <= duration_s + 1e-9
            ft = FootTruth(ft.t_s[keep], ft.pos_n[keep], ft.heading[keep])
            truth[FootKey(plan.name, foot)] = ft
            steps += [StepEvent(inc.t_s, plan.name, foot, inc)
                      for inc in _increments(ft, cfg, plan.path is None, rng)]
        body[plan.name] = _body(plan, cfg.speed_mps)
    steps.sort(key=lambda s: (s.t_s, s.agent, s.foot))
    names = [p.name for p in plans]
    pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    ranges: list[RangeEvent] = []
    if pairs:
        n_ranges = int(math.floor(duration_s * cfg.ranging_rate_hz + 1e-9))
        for j in range(n_ranges):
            t = (j + 1) / cfg.ranging_rate_hz
            a, b = pairs[j % len(pairs)]
            true = float(np.linalg.norm(body[a](np.array([t]))[0] - body[b](np.array([t]))[0]))
            measured = max(0.0, true + cfg.range_scale_m * float(rng.standard_cauchy()))
            ranges.append(RangeEvent(t, a, b, measured, true))
    return Scenario(tuple(names), truth, body, steps, ranges, float(duration_s))


def march_scenario(n_agents: int, duration_s: float, cfg: SimulationConfig, rng: np.random.Generator,
                   separation_m: float = 10.0) -> Scenario:
    """Sec. 5.1.1: ``n_agents`` marching east side by side, ``separation_m`` apart (north)."""
    if n_agents < 1:
        raise InputError("the march needs at least one agent", field="n_agents")
    plans = [AgentPlan(f"a{i}", straight_path(np.array([0.0, separation_m * i, 0.0]), 0.0))
             for i in range(n_agents)]
    return build_scenario(plans, duration_s, cfg, rng)


def static_circle_scenario(duration_s: float, cfg: SimulationConfig, rng: np.random.Generator,
                           side_m: float = 20.0, radius_m: float = 20.0) -> Scenario:
    """Sec. 5.1.2: three static agents on an equilateral triangle, a fourth walking a circle around them."""
    corners = [np.array([0.0, 0.0, 0.0]), np.array([side_m, 0.0, 0.0]),
               np.array([side_m / 2.0, side_m * math.sqrt(3.0) / 2.0, 0.0])]
    centre = np.mean(corners, axis=0)
    plans = [AgentPlan(f"s{i}", None, c, 0.0) for i, c in enumerate(corners)]
    plans.append(AgentPlan("mobile", circle_path(centre, radius_m, -math.pi / 2.0)))
    return build_scenario(plans, duration_s, cfg, rng)


@dataclass(frozen=True)
class RunResult:
    """Estimates of one simulation run at every reset of every foot.

    Attributes
    ----------
    estimate
        Foot -> (L+1, 3) estimated reset positions (row 0: the initial position), m.
    error
        Foot -> (L+1, 3) estimate minus truth, m.
    snapshots_t
        (S,) times of the state snapshots, s.
    snapshots_cov
        (S, m, m) state covariances at those times (empty unless requested).
    snapshots_mean
        (S, m) state means at those times (empty unless requested).
    snapshots_steps
        (S, F) step counts at those times.
    centre
        The fusion centre at the end of the run.
    """

    estimate: dict[FootKey, Array]
    error: dict[FootKey, Array]
    snapshots_t: Array
    snapshots_cov: Array
    snapshots_mean: Array
    snapshots_steps: NDArray[np.int64]
    centre: FusionCentre


def start_centre(scenario: Scenario, config: FusionConfig | None = None) -> FusionCentre:
    """A fusion centre with the scenario's agents at their true initial poses, known exactly."""
    centre = FusionCentre(config)
    for agent in scenario.agents:
        t0 = [scenario.truth[FootKey(agent, f)] for f in FEET]
        offsets = np.stack([t.pos_n[0] for t in t0]) - t0[0].pos_n[0]
        centre.add_agent(agent, t0[0].pos_n[0], float(t0[0].heading[0]), None, 0.0, offsets)
        for f, truth in zip(FEET, t0, strict=True):                # on a curve the feet start at other headings
            centre.state.mean[centre.state.block(FootKey(agent, f))[3]] = truth.heading[0]
    return centre


def run_scenario(scenario: Scenario, config: FusionConfig | None = None, ranging: bool = True,
                 snapshot_times: Array | None = None) -> RunResult:
    """Feed a scenario to a fusion centre (agents start at their true poses, known exactly)."""
    centre = start_centre(scenario, config)
    est = {k: np.full((v.t_s.size, 3), np.nan) for k, v in scenario.truth.items()}
    for k in est:
        est[k][0] = centre.state.position(k)
    snaps = np.asarray(snapshot_times if snapshot_times is not None else [], dtype=np.float64)
    snap_t: list[float] = []
    snap_cov: list[Array] = []
    snap_mean: list[Array] = []
    snap_steps: list[NDArray[np.int64]] = []
    j = 0

    def take_snapshots(upto: float) -> None:
        nonlocal j
        while j < snaps.size and snaps[j] < upto:
            snap_t.append(float(snaps[j]))
            snap_cov.append(centre.state.cov.copy())
            snap_mean.append(centre.state.mean.copy())
            snap_steps.append(centre.state.steps.copy())
            j += 1

    for ev in scenario.events(ranging):
        take_snapshots(ev.t_s)
        if isinstance(ev, StepEvent):
            centre.apply_step(ev.agent, ev.foot, ev.increment)
            key = FootKey(ev.agent, ev.foot)
            est[key][ev.increment.index] = centre.state.position(key)
        else:
            centre.apply_range(ev.agent_a, ev.agent_b, ev.measured_m)
    take_snapshots(math.inf)
    error = {k: est[k] - scenario.truth[k].pos_n for k in est}
    m = centre.state.dim
    steps = np.asarray(snap_steps, dtype=np.int64).reshape(len(snap_t), len(centre.state.feet))
    return RunResult(est, error, np.asarray(snap_t), np.asarray(snap_cov).reshape(-1, m, m),
                     np.asarray(snap_mean).reshape(-1, m), steps, centre)
