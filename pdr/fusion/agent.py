"""An agent's processing device: local dead reckoning of its feet, uplink buffer, corrections from the centre.

Seed 001 Sec. 3.3: "since the computational cost of propagating (7) is marginal, this can be done both locally
on the processing device of each agent and in a global state estimation. This way, if an agent loses contact
[...] it can still perform the dead reckoning [...]. If contact is reestablished, all data can easily be
transferred [...]. The other way around, if corrections to the estimates of [x_l, chi_l] are made in the
central state estimation, these corrections can be transferred down to the agent. Since the recursion in (7)
is pure dead reckoning (no statistical conditioning), these corrections can directly be used to correct the
local estimates."

The local estimate is a one-agent :class:`~pdr.fusion.centre.FusionCentre` (the same propagation and the same
dual-foot separation constraint as the global one). A correction carries the centre's estimate of this
agent's feet after a known number of steps per foot; the agent adopts it and re-applies the steps the centre
had not yet seen, so local and global estimates agree whenever the centre is up to date.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from pdr.errors import InputError
from pdr.fusion.centre import AgentCorrection, FusionCentre, FusionConfig
from pdr.fusion.measurements import StepSummary, event_to_dict, parse_event
from pdr.fusion.state import FootKey
from pdr.step_increment import StepIncrement


class Agent:
    """Local step-wise dead reckoning of one agent's feet (Algorithm 1 line 19 on the agent's device).

    Parameters
    ----------
    agent
        Agent id (as known to the fusion centre).
    pos0_n, heading0, cov0, t_s, foot_offsets_n
        Initial pose as in :meth:`pdr.fusion.centre.FusionCentre.add_agent`.
    config
        Fusion parameters (the feet names and the separation constraint are used locally).
    """

    def __init__(self, agent: str, pos0_n: ArrayLike, heading0: float = 0.0, cov0: ArrayLike | None = None,
                 t_s: float = 0.0, foot_offsets_n: ArrayLike | None = None,
                 config: FusionConfig | None = None) -> None:
        self.agent = agent
        self.local = FusionCentre(config)
        self.local.add_agent(agent, pos0_n, heading0, cov0, t_s, foot_offsets_n)
        self.outbox: list[StepSummary] = []
        self._unconfirmed: list[tuple[int, StepSummary]] = []       # (per-foot step number, summary)

    def step(self, foot: str, increment: StepIncrement) -> None:
        """A step summary from one of the agent's foot units: propagate locally and queue it for the centre."""
        self.outbox.append(self._propagate(StepSummary(self.agent, foot, increment)))

    def _propagate(self, summary: StepSummary) -> StepSummary:
        self.local.apply_step(self.agent, summary.foot, summary.increment)
        n = int(self.local.state.steps[self.local.state.foot(FootKey(self.agent, summary.foot))])
        self._unconfirmed.append((n, summary))
        return summary

    def take_outbox(self) -> list[StepSummary]:
        """The summaries not sent yet (a lost link keeps them here until the next call)."""
        out, self.outbox = self.outbox, []
        return out

    def estimate(self) -> AgentCorrection:
        """The local estimate of the feet, in the same form as a correction."""
        return self.local.correction(self.agent)

    def apply_correction(self, correction: AgentCorrection) -> bool:
        """Adopt the centre's estimate and re-apply the steps it had not seen; False for a stale correction."""
        if correction.agent != self.agent or tuple(correction.feet) != tuple(self.local.config.feet):
            raise InputError(f"correction for {correction.agent} {list(correction.feet)} does not fit agent "
                             f"{self.agent}", field="correction")
        keys = self.local.feet_of(self.agent)
        rows = [self.local.state.foot(k) for k in keys]
        local_steps = self.local.state.steps[rows]
        confirmed = local_steps - np.array([sum(1 for _, s in self._unconfirmed if s.foot == k.foot) for k in keys])
        centre_steps = np.asarray(correction.steps, dtype=np.int64)
        if np.any(centre_steps > local_steps):
            raise InputError("the correction includes steps this agent never made", field="correction.steps")
        if np.any(centre_steps < confirmed):
            return False
        self.local.state.set_marginal(keys, correction.mean, correction.cov)
        self.local.state.t_s[rows] = correction.t_s
        self.local.state.steps[rows] = centre_steps
        by_foot = dict(zip((k.foot for k in keys), centre_steps.tolist(), strict=True))
        replay = [(n, s) for n, s in self._unconfirmed if n > by_foot[s.foot]]
        self._unconfirmed = []
        for _, s in replay:
            self._propagate(s)
        return True

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state."""
        return {"agent": self.agent, "local": self.local.to_dict(),
                "outbox": [event_to_dict(s) for s in self.outbox],
                "unconfirmed": [[n, event_to_dict(s)] for n, s in self._unconfirmed]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Agent:
        """Inverse of :meth:`to_dict`."""
        try:
            out = cls.__new__(cls)
            out.agent = str(data["agent"])
            out.local = FusionCentre.from_dict(data["local"])
            outbox = [parse_event(e, "outbox") for e in data["outbox"]]
            unconfirmed = [(int(n), parse_event(e, "unconfirmed")) for n, e in data["unconfirmed"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed agent state: {exc}", field="agent") from None
        if not all(isinstance(e, StepSummary) for e in outbox) or not all(isinstance(e, StepSummary)
                                                                        for _, e in unconfirmed):
            raise InputError("malformed agent state: only step summaries are buffered", field="agent")
        out.outbox = [e for e in outbox if isinstance(e, StepSummary)]
        out._unconfirmed = [(n, e) for n, e in unconfirmed if isinstance(e, StepSummary)]
        return out
