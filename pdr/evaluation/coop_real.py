"""``pdr eval coop --real``: cooperative fusion of real foot recordings, with ranges simulated from their truth.

Seed 001 claims that inter-agent ranging bounds the agents' relative errors and helps each agent's position
(Sec. 5.1, simulations only; its real-time system of Sec. 5.2 also ranges synthetically, from a positioning
system). No recording in ``../shared/data`` has several walkers or two shoes at once, so a group is built from
single-foot recordings played as if walked at the same time. The protocol (also in :data:`PROTOCOL`):

* **Agents**: K PyShoe VICON trials (``pyshoe_vicon``; bipedal ones, whose truth moves at least 1 m; by default the
  K longest), one foot-mounted IMU each, each trial's clock from its start. The group has one foot per agent
  (``FusionConfig(feet=("foot",))``): no separation constraint.
* **Steps**: the step-wise inertial navigation of each trial (``pdr foot --method stepwise``); the same increments
  feed the dead reckoning alone and the group, up to the time the shortest trial ends.
* **Frame and start**: each trial's VICON frame, agent k moved ``k * spacing_m`` north (walking side by side); the
  initial pose is the truth position at the start and the heading that aligns the agent's dead reckoning on the
  truth at its first reset 0.8 m from the start (the PyShoe ARMSE alignment), for both.
* **Ranges**: round robin over the pairs at 1 Hz in total (seed 001 Sec. 5.1), the distance between the two
  feet's VICON positions at that time (a radio on the foot, swing included) or at their last resets (the
  positions the group's state holds), plus noise (Cauchy of scale ``noise_m``, as the seed's simulations, or
  Gaussian), fused with the group's range model (``gamma_m``, ``sigma_m``).
* **Step errors**: the increments' covariance as the INS reports it, or with the seed's step error model
  (0.01 m, 0.2 deg a step, Sec. 5.1) or a larger one added: the fusion weighs ranges against it.
* **Condition**: optionally one agent's heading drifts by ``bias_deg_per_step`` (added to each of its step
  heading changes), the case where the others' ranges should pull it back.
* **Figures**: per agent, the horizontal RMSE (m) over its resets against VICON at the reset times, dead
  reckoning alone and in the group (mean over ``runs`` draws of the range noise), and whether the ranges help.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.evaluation.foot_metrics import ALIGN_DISTANCE_M, PYSHOE_EXCLUDED
from pdr.fusion.centre import FusionCentre, FusionConfig
from pdr.fusion.ranging import RangeModel
from pdr.fusion.state import FootKey
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]

FOOT = "foot"
#: The protocol, printed with the figures.
PROTOCOL = ("K PyShoe VICON trials (one foot IMU each) played as if walked at the same time, agent k moved k * "
            "spacing north; step-wise INS increments (pdr foot --method stepwise) for dead reckoning alone and the "
            "group (one foot per agent), up to the end of the shortest trial; start: VICON position, heading "
            "aligned on VICON at the first reset 0.8 m away, for both; ranges round robin over pairs at 1 Hz in "
            "total from the feet's VICON positions (at the range time, or at their last resets) plus noise; step "
            "errors as the INS reports them or with a step error model added; horizontal RMSE over each agent's "
            "resets against VICON, mean over the noise draws")


@dataclass(frozen=True)
class RealAgent:
    """One recording as an agent: its step increments and its truth.

    Attributes
    ----------
    name
        Recording name.
    t0_s
        Start of the navigation (the initial state), s.
    steps
        Step increments in time order (eqs. 7-8).
    truth_t_s
        (M,) times of the truth, s.
    truth_pos_n
        (M, 3) true foot positions, m (the recording's truth frame).
    """

    name: str
    t0_s: float
    steps: tuple[StepIncrement, ...]
    truth_t_s: Array
    truth_pos_n: Array

    def truth_at(self, t_s: Array | float) -> Array:
        """(..., 3) true position at ``t_s`` (linear between truth samples), m."""
        t = np.asarray(t_s, dtype=np.float64)
        return np.stack([np.interp(t, self.truth_t_s, self.truth_pos_n[:, i]) for i in range(3)], axis=-1)


def load_pyshoe_agents(root: Path, count: int = 3, names: Sequence[str] = ()) -> list[RealAgent]:
    """Agents from the PyShoe VICON trials of ``root``: those named, or the ``count`` longest bipedal trials
    whose truth moves at least 1 m horizontally (a trial in place is no walk to range against).
    """
    from pdr.foot.navigate import navigate
    from pdr.io import read_recording

    files = {f.stem: f for f in sorted(root.glob("*.mat"))}
    if names:
        missing = [n for n in names if n not in files]
        if missing:
            raise InputError(f"no trial {missing[0]} in {root}", field="--trials")
        chosen = [files[n] for n in names]
    else:
        chosen = [f for n, f in files.items() if n not in PYSHOE_EXCLUDED]
    agents: list[RealAgent] = []
    for f in chosen:
        rec = read_recording(f)
        truth = rec.truth.positions
        if truth is None:
            raise InputError(f"{f.name} has no truth positions", field="--trials")
        if not names and float(np.max(np.ptp(truth.pos_m[:, :2], axis=0))) < 1.0:
            continue
        imu, track = navigate(rec, "stepwise")
        agents.append(RealAgent(f.stem, float(imu.t_s[track.start_index]), tuple(track.steps),
                                np.asarray(truth.t_s, dtype=np.float64), np.asarray(truth.pos_m, dtype=np.float64)))
    if not names:
        agents.sort(key=lambda a: a.truth_t_s[-1] - a.truth_t_s[0], reverse=True)
        agents = agents[:count]
    if len(agents) < 2:
        raise InputError(f"a group needs two or more agents, {root} gives {len(agents)}", field="--agents")
    return agents


def _dead_reckoned(agent: RealAgent, steps: Sequence[StepIncrement]) -> Array:
    """(L+1, 3) positions at the start and every reset, dead-reckoned from the origin with heading 0, m."""
    centre = FusionCentre(FusionConfig(feet=(FOOT,)))
    centre.add_agent(agent.name, np.zeros(3), 0.0, None, agent.t0_s)
    out = [np.zeros(3)]
    for inc in steps:
        centre.apply_step(agent.name, FOOT, inc)
        out.append(centre.state.position(FootKey(agent.name, FOOT)).copy())
    return np.asarray(out)


def alignment_heading(est_n: Array, truth_n: Array) -> float:
    """Rotation (rad, counter-clockwise) that makes the estimate point as the truth at its first point
    :data:`ALIGN_DISTANCE_M` from the start (both taken from their first point; the last point if none is).
    """
    e = est_n[:, :2] - est_n[0, :2]
    g = truth_n[:, :2] - truth_n[0, :2]
    far = np.flatnonzero(np.linalg.norm(e, axis=1) >= ALIGN_DISTANCE_M)
    i = int(far[0]) if far.size else e.shape[0] - 1
    return math.atan2(g[i, 1], g[i, 0]) - math.atan2(e[i, 1], e[i, 0])


@dataclass(frozen=True)
class RealCoopResult:
    """Figures of one condition.

    Attributes
    ----------
    agents
        Recording names, in agent order.
    steps
        Resets of each agent used.
    duration_s
        Common span of the group, s.
    ranges
        Ranges per run.
    rmse_dead_reckoning_m
        (K,) horizontal RMSE over the resets, dead reckoning alone, m.
    rmse_group_m
        (K,) the same in the group, mean over the runs, m.
    rmse_group_runs_m
        (R, K) the group's RMSE of each run, m.
    biased_agent
        Index of the agent given a heading drift (-1: none).
    """

    agents: tuple[str, ...]
    steps: tuple[int, ...]
    duration_s: float
    ranges: int
    rmse_dead_reckoning_m: Array
    rmse_group_m: Array
    rmse_group_runs_m: Array
    biased_agent: int

    @property
    def helped(self) -> list[bool]:
        """Whether the ranges lowered each agent's RMSE."""
        return [bool(g < d) for g, d in zip(self.rmse_group_m, self.rmse_dead_reckoning_m, strict=True)]


def _noise(rng: np.random.Generator, kind: str, scale_m: float) -> float:
    if kind == "cauchy":
        return float(scale_m * rng.standard_cauchy())
    return float(scale_m * rng.standard_normal())


def real_coop_experiment(agents: Sequence[RealAgent], runs: int = 10, seed: int = 0, model: RangeModel | None = None,
                         noise: str = "cauchy", noise_m: float = 1.0, spacing_m: float = 10.0,
                         biased_agent: int = -1, bias_deg_per_step: float = 0.0,
                         range_rate_hz: float = 1.0, step_sigma_m: float = 0.0,
                         step_heading_sigma_deg: float = 0.0, at_resets: bool = False) -> RealCoopResult:
    """Dead reckoning alone and the group with simulated ranges, for one condition (module doc).

    ``step_sigma_m`` and ``step_heading_sigma_deg`` are added (as variances) to each increment's covariance of
    ``dp`` and ``dpsi``: the step error model of seed 001 Sec. 5.1 (0.01 m, 0.2 deg) on top of what the INS reports.
    ``at_resets``: the true range is between the feet's positions at their last resets before the range's time
    (the positions the group's state holds: a radio at the foot's reset point) instead of at that time.
    """
    if len(agents) < 2:
        raise InputError("a group needs two or more agents", field="agents")
    if runs < 1 or not (noise_m >= 0 and math.isfinite(noise_m)) or noise not in ("cauchy", "gaussian"):
        raise InputError("needs runs >= 1, a finite noise_m >= 0 and noise cauchy or gaussian", field="noise")
    if not (range_rate_hz > 0 and math.isfinite(range_rate_hz)):
        raise InputError("must be a positive rate in Hz", field="range_rate_hz")
    if biased_agent >= len(agents):
        raise InputError(f"agent index {biased_agent} out of range (0..{len(agents) - 1})", field="biased_agent")
    end_s = min(a.steps[-1].t_s for a in agents if a.steps)
    start_s = max(a.t0_s for a in agents)
    if not (step_sigma_m >= 0 and step_heading_sigma_deg >= 0):
        raise InputError("step error standard deviations must be >= 0", field="step_sigma_m")
    bias = math.radians(bias_deg_per_step)
    extra = np.diag([step_sigma_m**2] * 3 + [math.radians(step_heading_sigma_deg) ** 2])
    steps = [tuple(replace(s, dpsi=s.dpsi + (bias if k == biased_agent else 0.0), cov=np.asarray(s.cov) + extra)
                   for s in a.steps if s.t_s <= end_s) for k, a in enumerate(agents)]
    offsets = [np.array([0.0, k * spacing_m, 0.0]) for k in range(len(agents))]
    poses, truths = [], []
    for k, a in enumerate(agents):
        dr = _dead_reckoned(a, steps[k])
        t = np.array([a.t0_s, *(s.t_s for s in steps[k])])
        truth = a.truth_at(t) + offsets[k]
        poses.append((truth[0], alignment_heading(dr, truth)))
        truths.append(truth)
    pairs = list(itertools.combinations(range(len(agents)), 2))
    range_t = np.arange(start_s + 1.0 / range_rate_hz, end_s, 1.0 / range_rate_hz)
    config = FusionConfig(ranging=model or RangeModel(), feet=(FOOT,))

    reset_t = [np.array([a.t0_s, *(s.t_s for s in steps[k])]) for k, a in enumerate(agents)]

    def truth_pos(k: int, t: float) -> Array:
        """The true position of agent k's foot for a range at ``t`` (module doc, ``at_resets``), m."""
        if at_resets:
            return truths[k][int(np.searchsorted(reset_t[k], t, side="right")) - 1]
        return agents[k].truth_at(t) + offsets[k]

    def run(rng: np.random.Generator | None) -> Array:
        centre = FusionCentre(config)
        for a, (pos0, heading0) in zip(agents, poses, strict=True):
            centre.add_agent(a.name, pos0, heading0, None, a.t0_s)
        events: list[tuple[float, int, int, float]] = [(s.t_s, 0, k, i) for k in range(len(agents))
                                                       for i, s in enumerate(steps[k])]
        if rng is not None:
            for j, t in enumerate(range_t):
                ka, kb = pairs[j % len(pairs)]
                true_m = float(np.linalg.norm(truth_pos(ka, t) - truth_pos(kb, t)))
                events.append((float(t), 1, ka * len(agents) + kb, max(true_m + _noise(rng, noise, noise_m), 0.0)))
        pos: list[list[Array]] = [[] for _ in agents]
        for _, kind, k, value in sorted(events):
            if kind == 0:
                name = agents[k].name
                centre.apply_step(name, FOOT, steps[k][int(value)])
                pos[k].append(centre.state.position(FootKey(name, FOOT)).copy())
            else:
                ka, kb = divmod(k, len(agents))
                centre.apply_range(agents[ka].name, agents[kb].name, value)
        return np.array([math.sqrt(float(np.mean(np.sum((np.asarray(p)[:, :2] - tr[1:, :2]) ** 2, axis=1))))
                         for p, tr in zip(pos, truths, strict=True)])

    alone = run(None)
    group = np.stack([run(np.random.default_rng([seed, r])) for r in range(runs)])
    return RealCoopResult(tuple(a.name for a in agents), tuple(len(s) for s in steps), float(end_s - start_s),
                          int(range_t.size), alone, group.mean(axis=0), group, biased_agent)


#: Conditions of :func:`real_coop_report`: (name, fusion range model, range noise kind and m, step error model
#: added to the increments' covariance: m, deg; ranges between the reset positions).
CONDITIONS: tuple[tuple[str, RangeModel, str, float, float, float, bool], ...] = (
    ("seed ranging, increments as reported", RangeModel(1.0, 1.0), "cauchy", 1.0, 0.0, 0.0, False),
    ("seed ranging, seed step errors added", RangeModel(1.0, 1.0), "cauchy", 1.0, 0.01, 0.2, False),
    ("tight ranging (0.1 m Gaussian), seed step errors added", RangeModel(0.3, 0.1), "gaussian", 0.1, 0.01, 0.2,
     False),
    ("tight ranging, 1 deg/step heading error added", RangeModel(0.3, 0.1), "gaussian", 0.1, 0.03, 1.0, False),
    ("tight ranging between reset positions, seed step errors added", RangeModel(0.1, 0.1), "gaussian", 0.1, 0.01,
     0.2, True),
    ("tight ranging between reset positions, 1 deg/step heading error added", RangeModel(0.1, 0.1), "gaussian", 0.1,
     0.03, 1.0, True),
)

#: An RMSE change smaller than this is no change, m.
CHANGE_TOLERANCE_M = 0.001


def real_coop_report(agents: Sequence[RealAgent], runs: int = 10, seed: int = 0, spacing_m: float = 10.0,
                     bias_deg_per_step: float = 3.0) -> dict[str, object]:
    """Every condition of :data:`CONDITIONS`, without and with agent 0's heading drift: JSON-serialisable figures."""
    out: list[dict[str, object]] = []
    for biased in ((-1, 0.0), (0, bias_deg_per_step)) if bias_deg_per_step else ((-1, 0.0),):
        for name, model, noise, noise_m, step_m, step_deg, at_resets in CONDITIONS:
            r = real_coop_experiment(agents, runs, seed, model, noise, noise_m, spacing_m, biased[0], biased[1],
                                     step_sigma_m=step_m, step_heading_sigma_deg=step_deg, at_resets=at_resets)
            change = r.rmse_group_m - r.rmse_dead_reckoning_m
            out.append({
                "condition": name, "biased_agent": r.agents[biased[0]] if biased[0] >= 0 else None,
                "bias_deg_per_step": biased[1], "range_model": {"gamma_m": model.gamma_m, "sigma_m": model.sigma_m},
                "range_noise": {"kind": noise, "scale_m": noise_m},
                "step_errors_added": {"sigma_m": step_m, "heading_sigma_deg": step_deg},
                "ranges_between": "reset positions" if at_resets else "positions at the range time",
                "ranges": r.ranges,
                "rmse_dead_reckoning_m": dict(zip(r.agents, r.rmse_dead_reckoning_m.tolist(), strict=True)),
                "rmse_group_m": dict(zip(r.agents, r.rmse_group_m.tolist(), strict=True)),
                "helped": {a: bool(c < -CHANGE_TOLERANCE_M) for a, c in zip(r.agents, change, strict=True)},
                "hurt": {a: bool(c > CHANGE_TOLERANCE_M) for a, c in zip(r.agents, change, strict=True)},
            })
    first = real_coop_experiment(agents, 1, seed, spacing_m=spacing_m)
    return {"protocol": PROTOCOL, "agents": list(first.agents), "steps": list(first.steps),
            "duration_s": first.duration_s, "runs": runs, "spacing_m": spacing_m, "conditions": out}
