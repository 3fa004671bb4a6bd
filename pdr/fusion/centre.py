"""The fusion centre: joint state of every foot of every agent, updated as information arrives (seed 001 Sec. 4.4).

"The central sensor fusion keeps the position and heading of all feet in the global state vector x. From all
agents, it receives dead reckoning updates [dp_l, dpsi_l] with their covariances, and inter-agent range
measurements. The dead reckoning updates are used to propagate the corresponding states and covariances
according to (7). At each dead reckoning update, the range constraint is imposed on the state space [...] and
the corrections are sent back to the agent. The inter-agent range measurements are used to condition the state
space" (Sec. 4.4). Updates arrive asynchronously: each foot has its own time and step count.

An agent's position for ranging, anchors, fixes and pressure is the position of its most recently updated
foot (``gamma_r`` of the likelihood covers the separation between that foot and the radio, Sec. 4.3).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.fusion.aiding import anchor_range_update, height_difference_update, position_fix_update
from pdr.fusion.constraints import SeparationConfig, impose_separation
from pdr.fusion.dead_reckoning import propagate_step
from pdr.fusion.ranging import (
    Lattice,
    RangeModel,
    kalman_range_update,
    points_per_axis_for,
    range_update,
    square_lattice,
)
from pdr.fusion.state import FOOT_DIM, FootKey, GlobalState, as_cov, as_vector
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FusionConfig:
    """Parameters of the fusion centre.

    Attributes
    ----------
    separation
        Dual-foot separation constraint (eq. 13).
    ranging
        Inter-agent range likelihood (eq. 20): ``gamma_r`` and the Cauchy scale ``sigma_r``, m.
    feet
        Names of the feet of every agent.
    lattice_points
        Lattice points per axis of the sampled 3-D updates (Algorithm 3); 1-D and 2-D updates use about as
        many samples in total.
    lattice_extent
        Half-width of the lattice in prior standard deviations.
    robust
        ``False`` replaces the sampled range update by the linearised Kalman update (reference only).
    kalman_range_variance_m2
        Range error variance of the Kalman reference, m^2.
    """

    separation: SeparationConfig = field(default_factory=SeparationConfig)
    ranging: RangeModel = field(default_factory=RangeModel)
    feet: tuple[str, ...] = ("left", "right")
    lattice_points: int = 9
    lattice_extent: float = 4.0
    robust: bool = True
    kalman_range_variance_m2: float = 1.0

    def __post_init__(self) -> None:
        if not self.feet or len(set(self.feet)) != len(self.feet) or not all(isinstance(f, str) and f
                                                                           for f in self.feet):
            raise InputError("feet must be distinct non-empty names", field="feet")
        if self.lattice_points < 2 or not (math.isfinite(self.lattice_extent) and self.lattice_extent > 0):
            raise InputError("the lattice needs >= 2 points per axis and a positive extent", field="lattice_points")
        if not (math.isfinite(self.kalman_range_variance_m2) and self.kalman_range_variance_m2 > 0):
            raise InputError("must be a positive variance in m^2", field="kalman_range_variance_m2")

    def lattice(self, dim: int) -> Lattice:
        """The sampling lattice for a ``dim``-dimensional ``z_1``."""
        return square_lattice(dim, points_per_axis_for(dim, self.lattice_points), self.lattice_extent)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""
        out = asdict(self)
        out["feet"] = list(self.feet)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FusionConfig:
        """Inverse of :meth:`to_dict`; missing keys take their defaults (InputError on unknown keys)."""
        try:
            d = dict(data)
            sep = SeparationConfig(**d.pop("separation", {}))
            rng = RangeModel(**d.pop("ranging", {}))
            if "feet" in d:
                d["feet"] = tuple(d["feet"])
            return cls(separation=sep, ranging=rng, **d)
        except TypeError as exc:
            raise InputError(f"malformed fusion configuration: {exc}", field="config") from None


@dataclass(frozen=True)
class AgentCorrection:
    """The fused estimate of one agent's feet, sent back to the agent (Sec. 3.3).

    Attributes
    ----------
    agent
        Agent id.
    feet
        Foot names, in block order.
    steps
        (F,) number of dead-reckoning updates of each foot the estimate includes.
    t_s
        (F,) time of each foot's last update, s.
    mean
        (4F,) per foot ``[x, y, z, chi]`` (m, ENU; rad).
    cov
        (4F, 4F) joint covariance of the agent's feet (marginal of the global state).
    """

    agent: str
    feet: tuple[str, ...]
    steps: NDArray[np.int64]
    t_s: Array
    mean: Array
    cov: Array

    def values_per_foot(self) -> int:
        """Numbers that must reach the agent per foot: the corrected position and heading (Sec. 3.4)."""
        return FOOT_DIM

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""
        return {"agent": self.agent, "feet": list(self.feet), "steps": self.steps.tolist(), "t_s": self.t_s.tolist(),
                "mean": self.mean.tolist(), "cov": self.cov.tolist()}


class FusionCentre:
    """Global state estimation for a group of agents with dual foot-mounted units and ranging radios.

    Parameters
    ----------
    config
        Fusion parameters.
    """

    def __init__(self, config: FusionConfig | None = None) -> None:
        self.config = config if config is not None else FusionConfig()
        self.state = GlobalState()
        self.agents: list[str] = []
        self.counts: dict[str, int] = {"steps": 0, "constraints_active": 0, "ranges": 0, "anchors": 0,
                                       "fixes": 0, "heights": 0}

    # ----------------------------------------------------------------------------------------------- agents
    def feet_of(self, agent: str) -> list[FootKey]:
        """Keys of the feet of ``agent`` (InputError when unknown)."""
        if agent not in self.agents:
            raise InputError(f"unknown agent '{agent}'", field="agent")
        return [FootKey(agent, f) for f in self.config.feet]

    def add_agent(self, agent: str, pos0_n: ArrayLike, heading0: float = 0.0, cov0: ArrayLike | None = None,
                  t_s: float = 0.0, foot_offsets_n: ArrayLike | None = None) -> None:
        """Add an agent standing at ``pos0_n`` (3, m, ENU) with heading ``heading0`` (rad, CCW from east).

        ``cov0`` (4, 4) is the uncertainty of the agent's initial position and heading; it is common to its
        feet (their initial errors are fully correlated). ``foot_offsets_n`` (F, 3) places the feet
        relative to ``pos0_n`` (default: all at ``pos0_n``).
        """
        if not isinstance(agent, str) or not agent:
            raise InputError("an agent id must be a non-empty string", field="agent")
        if agent in self.agents:
            raise InputError(f"agent '{agent}' is already in the group", field="agent")
        pos0 = as_vector(pos0_n, 3, "pos0_n")
        c0 = np.zeros((FOOT_DIM, FOOT_DIM)) if cov0 is None else as_cov(cov0, FOOT_DIM, "cov0")
        n_feet = len(self.config.feet)
        offsets = np.zeros((n_feet, 3)) if foot_offsets_n is None else np.asarray(foot_offsets_n, dtype=np.float64)
        if offsets.shape != (n_feet, 3) or not np.all(np.isfinite(offsets)):
            raise InputError(f"foot offsets must be ({n_feet}, 3) finite numbers (m)", field="foot_offsets_n")
        if not (math.isfinite(heading0) and math.isfinite(t_s)):
            raise InputError("initial heading and time must be finite", field="heading0")
        first = self.state.dim
        for f, off in zip(self.config.feet, offsets, strict=True):
            self.state.add_foot(FootKey(agent, f), pos0 + off, heading0, c0, t_s)
        idx = np.arange(first, self.state.dim)
        self.state.cov[np.ix_(idx, idx)] = np.kron(np.ones((n_feet, n_feet)), c0)
        self.agents.append(agent)

    def ranging_foot(self, agent: str) -> FootKey:
        """The agent's most recently updated foot (the one used for ranges, anchors and fixes)."""
        keys = self.feet_of(agent)
        times = [self.state.t_s[self.state.foot(k)] for k in keys]
        return keys[int(np.argmax(times))]

    # ----------------------------------------------------------------------------------------------- updates
    def apply_step(self, agent: str, foot: str, increment: StepIncrement) -> bool:
        """Propagate one foot with a dead-reckoning update (eqs. 7-8), then impose the separation constraint
        between it and each other foot of the agent (Algorithm 2). Returns whether a constraint was active.
        """
        key = FootKey(agent, foot)
        if agent not in self.agents or foot not in self.config.feet:
            raise InputError(f"unknown foot {key}", field="foot")
        propagate_step(self.state, key, increment)
        self.counts["steps"] += 1
        active = False
        for other in self.feet_of(agent):
            if other != key:
                active |= impose_separation(self.state, key, other, self.config.separation)
        self.counts["constraints_active"] += int(active)
        return active

    def apply_range(self, agent_a: str, agent_b: str, range_m: float) -> bool:
        """Condition on a range (m) between two agents' radios (Algorithm 3; Kalman if not ``robust``)."""
        if agent_a == agent_b:
            raise InputError("a range needs two different agents", field="agent_b")
        fa, fb = self.ranging_foot(agent_a), self.ranging_foot(agent_b)
        if self.config.robust:
            applied = range_update(self.state, fa, fb, float(range_m), self.config.ranging, self.config.lattice(3))
        else:
            applied = kalman_range_update(self.state, fa, fb, float(range_m), self.config.kalman_range_variance_m2)
        self.counts["ranges"] += int(applied)
        return applied

    def apply_anchor_range(self, agent: str, anchor_n: ArrayLike, range_m: float,
                           model: RangeModel | None = None) -> bool:
        """Condition on a range (m) from an agent to an anchor at ``anchor_n`` (3, m, ENU)."""
        applied = anchor_range_update(self.state, self.ranging_foot(agent), anchor_n, float(range_m),
                                      model or self.config.ranging, self.config.lattice(3))
        self.counts["anchors"] += int(applied)
        return applied

    def apply_position_fix(self, agent: str, pos_n: ArrayLike, model: RangeModel, horizontal: bool = True) -> bool:
        """Condition on a position fix (2 or 3 values, m, ENU) as a zero range (``model``: fix error bounds)."""
        applied = position_fix_update(self.state, self.ranging_foot(agent), pos_n, model, horizontal,
                                      self.config.lattice(2 if horizontal else 3))
        self.counts["fixes"] += int(applied)
        return applied

    def apply_height_difference(self, agent_a: str, agent_b: str | None, dh_m: float, model: RangeModel,
                                reference_height_m: float = 0.0) -> bool:
        """Condition on the height (m) of ``agent_a`` above ``agent_b`` (or above ``reference_height_m``)."""
        fb = None if agent_b is None else self.ranging_foot(agent_b)
        applied = height_difference_update(self.state, self.ranging_foot(agent_a), fb, float(dh_m), model,
                                           reference_height_m, self.config.lattice(1))
        self.counts["heights"] += int(applied)
        return applied

    # ----------------------------------------------------------------------------------------------- output
    def correction(self, agent: str) -> AgentCorrection:
        """The fused estimate of the agent's feet to send back to it."""
        keys = self.feet_of(agent)
        mean, cov = self.state.marginal(keys)
        rows = [self.state.foot(k) for k in keys]
        return AgentCorrection(agent, tuple(k.foot for k in keys), self.state.steps[rows].copy(),
                               self.state.t_s[rows].copy(), mean, cov)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state; :meth:`from_dict` resumes the fusion exactly."""
        return {"config": self.config.to_dict(), "agents": list(self.agents), "state": self.state.to_dict(),
                "counts": dict(self.counts)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FusionCentre:
        """Inverse of :meth:`to_dict`."""
        try:
            out = cls(FusionConfig.from_dict(data["config"]))
            out.agents = [str(a) for a in data["agents"]]
            out.state = GlobalState.from_dict(data["state"])
            out.counts.update({str(k): int(v) for k, v in data.get("counts", {}).items()})
        except (KeyError, TypeError) as exc:
            raise InputError(f"malformed fusion centre state: {exc}", field="state") from None
        if len(out.state.feet) != len(out.agents) * len(out.config.feet):
            raise InputError("fusion centre state does not match its agents", field="state")
        return out
