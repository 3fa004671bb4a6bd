"""A group of agents fused by one centre: time-ordered buffer of uploads, contact loss and merge.

Uploads arrive in bursts and out of order across agents (each agent sends its own summaries in time order).
The group buffers every event and applies them to the :class:`~pdr.fusion.centre.FusionCentre` in time order up
to a *watermark*: the oldest "latest time" among the agents in contact, so an event is only applied once every
agent in contact has reported up to its time. An agent whose latest report lags the newest one by more than
``contact_timeout_s`` is out of contact: it no longer holds the group back, and keeps dead-reckoning locally
(:class:`~pdr.fusion.agent.Agent`). When it returns, its buffered summaries are applied in time order (its own
feet's dead reckoning, anchors, fixes and pressure are unaffected by the delay). Inter-agent ranges that have
to an agent out of contact wait until it has reported up to their time; if by then an involved agent's state has
moved on by more than ``max_range_age_s`` they are stale, dropped and counted: the positions they relate no
longer exist in the state (seed 001 Sec. 3.3: only the dead reckoning is recovered after an outage).

Repeated uploads of a step (same agent, foot and time or older) are ignored, so a client may resend a batch.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.fusion.centre import AgentCorrection, FusionCentre, FusionConfig
from pdr.fusion.measurements import (
    AnchorRange,
    Event,
    HeightDifference,
    InterAgentRange,
    PositionFix,
    StepSummary,
    event_to_dict,
    parse_event,
)
from pdr.fusion.state import FootKey

Array = NDArray[np.float64]


def _entry(ev: Event, seq: int) -> tuple[float, int, str, int, Event]:
    """Heap entry: events in time order; at equal times steps first, by agent and foot (a canonical order, so
    the result does not depend on the order of the uploads), then the others in arrival order.
    """
    if isinstance(ev, StepSummary):
        return (ev.t_s, 0, f"{ev.agent}/{ev.foot}", seq, ev)
    return (ev.t_s, 1, "", seq, ev)


class Group:
    """Buffered, time-ordered cooperative fusion of a group (the server's per-group object).

    Parameters
    ----------
    config
        Fusion parameters.
    contact_timeout_s
        An agent whose latest report is this much older than the group's newest is out of contact, s.
    max_range_age_s
        A range older than an involved agent's state by more than this is stale and dropped, s.
    """

    def __init__(self, config: FusionConfig | None = None, contact_timeout_s: float = 10.0,
                 max_range_age_s: float = 2.0) -> None:
        for name, v in (("contact_timeout_s", contact_timeout_s), ("max_range_age_s", max_range_age_s)):
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"must be a positive time in s, got {v}", field=name)
        self.centre = FusionCentre(config)
        self.contact_timeout_s = float(contact_timeout_s)
        self.max_range_age_s = float(max_range_age_s)
        self._pending: list[tuple[float, int, str, int, Event]] = []
        self._seq = 0
        self.latest_s: dict[str, float] = {}
        self._last_step_s: dict[str, float] = {}
        self.clock_s = -math.inf
        self.tracks: dict[str, list[list[float]]] = {}
        self.counts: dict[str, int] = {"applied": 0, "duplicates": 0, "stale_ranges": 0}

    # ------------------------------------------------------------------------------------------- membership
    @property
    def agents(self) -> list[str]:
        return list(self.centre.agents)

    def join(self, agent: str, pos0_n: ArrayLike, heading0: float = 0.0, cov0: ArrayLike | None = None,
             t_s: float = 0.0, foot_offsets_n: ArrayLike | None = None) -> None:
        """Add an agent with its initial pose (see :meth:`FusionCentre.add_agent`)."""
        self.centre.add_agent(agent, pos0_n, heading0, cov0, t_s, foot_offsets_n)
        self.latest_s[agent] = float(t_s)
        for key in self.centre.feet_of(agent):
            self.tracks[str(key)] = [[float(t_s), *self.centre.state.position(key).tolist(),
                                      self.centre.state.heading(key)]]

    def in_contact(self, agent: str) -> bool:
        """Whether the agent reported recently enough to hold the group's processing back."""
        newest = max(self.latest_s.values())
        return self.latest_s[agent] >= newest - self.contact_timeout_s

    def watermark(self) -> float:
        """Events up to this time can be applied: every agent in contact has reported up to it, s."""
        if not self.latest_s:
            return -math.inf
        return min(t for a, t in self.latest_s.items() if self.in_contact(a))

    # ------------------------------------------------------------------------------------------- input
    def submit(self, events: Iterable[Event | dict[str, Any]], reporter: str | None = None) -> int:
        """Buffer events (objects or their JSON form); returns how many were accepted.

        The whole batch is checked first: an unknown agent or foot rejects it with an InputError naming the
        event. ``reporter`` (the uploading agent) also counts as having reported up to the batch's newest time.
        """
        batch: list[Event] = []
        for i, e in enumerate(events):
            where = f"events[{i}]"
            ev = parse_event(e, where) if isinstance(e, dict) else e
            for agent in ev.agents:
                if agent not in self.latest_s:
                    raise InputError(f"agent '{agent}' has not joined the group", source=where, field="agent")
            if isinstance(ev, StepSummary) and ev.foot not in self.centre.config.feet:
                raise InputError(f"foot must be one of {', '.join(self.centre.config.feet)}", source=where,
                                 field="foot")
            batch.append(ev)
        if reporter is not None and reporter not in self.latest_s:
            raise InputError(f"agent '{reporter}' has not joined the group", field="agent")
        accepted = 0
        for ev in sorted(batch, key=lambda e: e.t_s):
            if isinstance(ev, StepSummary):
                key = str(FootKey(ev.agent, ev.foot))
                if ev.t_s <= self._last_step_s.get(key, -math.inf):
                    self.counts["duplicates"] += 1
                    continue
                self._last_step_s[key] = ev.t_s
            reporting = ev.agents[0]
            self.latest_s[reporting] = max(self.latest_s[reporting], ev.t_s)
            heapq.heappush(self._pending, _entry(ev, self._seq))
            self._seq += 1
            accepted += 1
        if reporter is not None and batch:
            self.latest_s[reporter] = max(self.latest_s[reporter], max(e.t_s for e in batch))
        return accepted

    @property
    def pending(self) -> int:
        """Number of buffered events not applied yet."""
        return len(self._pending)

    # ------------------------------------------------------------------------------------------- processing
    def _stale(self, ev: Event) -> bool:
        for agent in ev.agents:
            rows = [self.centre.state.foot(k) for k in self.centre.feet_of(agent)]
            if float(np.max(self.centre.state.t_s[rows])) > ev.t_s + self.max_range_age_s:
                return True
        return False

    def _apply(self, ev: Event) -> None:
        c = self.centre
        if isinstance(ev, StepSummary):
            c.apply_step(ev.agent, ev.foot, ev.increment)
            key = FootKey(ev.agent, ev.foot)
            self.tracks[str(key)].append([ev.t_s, *c.state.position(key).tolist(), c.state.heading(key)])
        elif isinstance(ev, InterAgentRange):
            c.apply_range(ev.agent_a, ev.agent_b, ev.range_m)
        elif isinstance(ev, AnchorRange):
            c.apply_anchor_range(ev.agent, ev.anchor_n, ev.range_m, ev.model)
        elif isinstance(ev, PositionFix):
            c.apply_position_fix(ev.agent, ev.pos_n, ev.model, horizontal=ev.pos_n.size == 2)
        else:
            c.apply_height_difference(ev.agent_a, ev.agent_b, ev.dh_m, ev.model, ev.reference_height_m)

    def process(self, flush: bool = False) -> dict[str, int]:
        """Apply the buffered events up to the watermark (all of them with ``flush``) in time order.

        Returns the numbers applied and dropped in this call.
        """
        limit = math.inf if flush else self.watermark()
        applied = stale = 0
        held: list[tuple[float, int, str, int, Event]] = []
        while self._pending and self._pending[0][0] <= limit:
            item = heapq.heappop(self._pending)
            t, ev = item[0], item[4]
            two_agents = isinstance(ev, InterAgentRange) or (isinstance(ev, HeightDifference) and ev.agent_b)
            if two_agents and not flush and any(self.latest_s[a] < t - self.max_range_age_s for a in ev.agents):
                held.append(item)                  # an agent out of contact has not reported up to t yet
                continue
            if two_agents and self._stale(ev):
                stale += 1
                continue
            self._apply(ev)
            applied += 1
            self.clock_s = max(self.clock_s, t)
        for item in held:
            heapq.heappush(self._pending, item)
        self.counts["applied"] += applied
        self.counts["stale_ranges"] += stale
        return {"applied": applied, "stale_ranges": stale, "pending": len(self._pending)}

    # ------------------------------------------------------------------------------------------- output
    def correction(self, agent: str) -> AgentCorrection:
        """The fused estimate of the agent's feet, to send back to it."""
        return self.centre.correction(agent)

    def track(self, agent: str) -> dict[str, Array]:
        """Fused reset poses per foot: foot -> (K, 5) rows ``[t_s, x, y, z (m, ENU), chi (rad)]``."""
        return {k.foot: np.asarray(self.tracks[str(k)], dtype=np.float64) for k in self.centre.feet_of(agent)}

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state (buffer included); :meth:`from_dict` resumes exactly."""
        return {"centre": self.centre.to_dict(), "contact_timeout_s": self.contact_timeout_s,
                "max_range_age_s": self.max_range_age_s,
                "pending": [[item[3], event_to_dict(item[4])] for item in sorted(self._pending)], "seq": self._seq,
                "latest_s": dict(self.latest_s), "last_step_s": dict(self._last_step_s),
                "clock_s": None if math.isinf(self.clock_s) else self.clock_s, "tracks": self.tracks,
                "counts": dict(self.counts)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Group:
        """Inverse of :meth:`to_dict`."""
        try:
            out = cls(None, float(data["contact_timeout_s"]), float(data["max_range_age_s"]))
            out.centre = FusionCentre.from_dict(data["centre"])
            out._pending = [_entry(parse_event(e, "pending"), int(n)) for n, e in data["pending"]]
            heapq.heapify(out._pending)
            out._seq = int(data["seq"])
            out.latest_s = {str(k): float(v) for k, v in data["latest_s"].items()}
            out._last_step_s = {str(k): float(v) for k, v in data["last_step_s"].items()}
            out.clock_s = -math.inf if data["clock_s"] is None else float(data["clock_s"])
            out.tracks = {str(k): [[float(x) for x in row] for row in v] for k, v in data["tracks"].items()}
            out.counts.update({str(k): int(v) for k, v in data["counts"].items()})
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"malformed group state: {exc}", field="group") from None
        return out
