"""A group of agents fused by one centre: time-ordered buffer of uploads, contact loss and merge.

Uploads arrive in bursts and out of order across agents (each agent sends its own summaries in time order).
The group buffers every event and applies them to the :class:`~pdr.fusion.centre.FusionCentre` in time order up
to a *watermark*: the oldest "latest time" among the agents in contact, so an event is only applied once every
agent in contact has reported up to its time. An agent whose latest report lags the newest one by more than
``contact_timeout_s`` is out of contact: it no longer holds the group back, and keeps dead-reckoning locally
(:class:`~pdr.fusion.agent.Agent`). When it returns, its buffered summaries are applied in time order (its own
feet's dead reckoning, anchors, fixes and pressure are unaffected by the delay).

The *fusion horizon* of an agent is the time of its state (its feet's latest applied step) less
``max_range_age_s``: a range between two agents can only be fused while its time is within both agents' horizons
(seed 001 Sec. 3.3: only the dead reckoning is recovered after an outage; the positions an older range relates
no longer exist in the state). :meth:`Group.submit` refuses a batch with :class:`StaleRangeError` when one of its
ranges is, or becomes once the batch is applied, older than a horizon, naming every such event and why (an agent
out of contact that the group did not wait for). A range accepted earlier that an agent's later steps overtake
while it waits for an agent out of contact is dropped when that happens and listed in :meth:`Group.process`'s
answer.

Repeated uploads of a step (same agent, foot and time or older) are ignored, so a client may resend a batch.

An event, or a joining agent, whose time lies more than :data:`MAX_CLOCK_JUMP_S` ahead of the group's newest event
is refused with an InputError naming it: the clients' common clock does not jump a day between uploads, and one such
event (a clock in another unit or epoch) would carry the group's newest time with it, leaving every agent out of
contact and every later range older than the horizon. The first event sets the clock: agents may join before it
without a time (at 0 s), and their events then come on whatever clock the clients chose (Unix time, a session's
shoe clock).
"""

from __future__ import annotations

import copy
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

#: Largest step forward (s) of the group's clock an event or a joining agent may take from the group's newest event: a
#: day, as a session's clock (:data:`pdr.phone.grid.MAX_JUMP_S`); a group used again later is a new group.
MAX_CLOCK_JUMP_S = 86400.0


class StaleRangeError(InputError):
    """Ranges of an upload older than the fusion horizon (module doc); ``events`` lists their indices."""

    code = "stale_range"

    def __init__(self, message: str, *, source: str, events: list[int], reasons: list[str]) -> None:
        self.events = events
        self.reasons = reasons
        super().__init__(message, source=source, field="t_s")

    def details(self) -> dict[str, object]:
        return {**super().details(), "events": self.events, "reasons": self.reasons}


def _check_clock(t_s: float, where: str | None, newest_s: float | None) -> None:
    """InputError naming ``t_s`` (of the event ``where``) when it lies more than :data:`MAX_CLOCK_JUMP_S` s ahead of
    the group's newest event ``newest_s`` (module doc; None before the first event: nothing to check).
    """
    if newest_s is not None and t_s > newest_s + MAX_CLOCK_JUMP_S:
        raise InputError(f"time {t_s:g} s is {(t_s - newest_s) / 86400:.3g} days ahead of the group's newest "
                         f"({newest_s:g} s): the group's clock does not jump more than a day (another clock or "
                         f"unit?); create a new group for a new mission", source=where, field="t_s")


def _two_agents(ev: Event) -> bool:
    """Whether the event relates two agents' positions (it then needs both states at its time)."""
    return isinstance(ev, InterAgentRange) or (isinstance(ev, HeightDifference) and ev.agent_b is not None)


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
        _check_clock(float(t_s), None, self.newest_event_s())
        self.centre.add_agent(agent, pos0_n, heading0, cov0, t_s, foot_offsets_n)
        self.latest_s[agent] = float(t_s)
        for key in self.centre.feet_of(agent):
            self.tracks[str(key)] = [[float(t_s), *self.centre.state.position(key).tolist(),
                                      self.centre.state.heading(key)]]

    def newest_event_s(self) -> float | None:
        """Time of the newest event accepted, s: of the applied ones (``clock_s``) and the buffered ones; None before
        the first.
        """
        times = [item[0] for item in self._pending] + ([self.clock_s] if math.isfinite(self.clock_s) else [])
        return max(times) if times else None

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
        event, and ranges older than the fusion horizon once the batch is applied reject it with a
        :class:`StaleRangeError` (module doc). ``reporter`` (the uploading agent) also counts as having reported
        up to the batch's newest time.
        """
        batch: list[Event] = []
        newest = self.newest_event_s()      # once: it scans the buffer
        for i, e in enumerate(events):
            where = f"events[{i}]"
            ev = parse_event(e, where) if isinstance(e, dict) else e
            for agent in ev.agents:
                if agent not in self.latest_s:
                    raise InputError(f"agent '{agent}' has not joined the group", source=where, field="agent")
            if isinstance(ev, StepSummary) and ev.foot not in self.centre.config.feet:
                raise InputError(f"foot must be one of {', '.join(self.centre.config.feet)}", source=where,
                                 field="foot")
            _check_clock(ev.t_s, where, newest)
            batch.append(ev)
        if reporter is not None and reporter not in self.latest_s:
            raise InputError(f"agent '{reporter}' has not joined the group", field="agent")
        if any(_two_agents(ev) for ev in batch):
            self._refuse_stale(batch, reporter)
        return len(self._accept(batch, reporter))

    def _accept(self, batch: list[Event], reporter: str | None) -> dict[int, int]:
        """Buffer a checked batch; returns {buffer sequence number: index in the batch} of the accepted events."""
        accepted: dict[int, int] = {}
        for i in sorted(range(len(batch)), key=lambda j: batch[j].t_s):
            ev = batch[i]
            if isinstance(ev, StepSummary):
                key = str(FootKey(ev.agent, ev.foot))
                if ev.t_s <= self._last_step_s.get(key, -math.inf):
                    self.counts["duplicates"] += 1
                    continue
                self._last_step_s[key] = ev.t_s
            reporting = ev.agents[0]
            self.latest_s[reporting] = max(self.latest_s[reporting], ev.t_s)
            heapq.heappush(self._pending, _entry(ev, self._seq))
            accepted[self._seq] = i
            self._seq += 1
        if reporter is not None and batch:
            self.latest_s[reporter] = max(self.latest_s[reporter], max(e.t_s for e in batch))
        return accepted

    def _refuse_stale(self, batch: list[Event], reporter: str | None) -> None:
        """Raise StaleRangeError for the batch's ranges that could never be fused (applied on a copy)."""
        trial = copy.deepcopy(self)
        accepted = trial._accept(batch, reporter)
        report = trial.process()
        refused = {accepted[d["seq"]]: d["reason"] for d in report["dropped"] if d["seq"] in accepted}
        for item in trial._pending:
            reason = trial._stale_reason(item[4]) if item[3] in accepted else None
            if reason:
                refused[accepted[item[3]]] = reason
        if refused:
            order = sorted(refused)
            first = order[0]
            raise StaleRangeError(f"{len(order)} range(s) older than the fusion horizon, refused: {refused[first]}",
                                  source=f"events[{first}]", events=order, reasons=[refused[i] for i in order])

    def last_step_s(self, agent: str, foot: str) -> float:
        """Time of the newest step of the agent's foot accepted so far (-inf before its first), s."""
        return self._last_step_s.get(str(FootKey(agent, foot)), -math.inf)

    @property
    def pending(self) -> int:
        """Number of buffered events not applied yet."""
        return len(self._pending)

    # ------------------------------------------------------------------------------------------- processing
    def _stale_reason(self, ev: Event) -> str | None:
        """Why a two-agent event can no longer be fused (an involved agent's state is past its horizon), or None."""
        for agent in ev.agents:
            rows = [self.centre.state.foot(k) for k in self.centre.feet_of(agent)]
            state_s = float(np.max(self.centre.state.t_s[rows]))
            if state_s > ev.t_s + self.max_range_age_s:
                why = (f"the range at {ev.t_s:g} s between {' and '.join(ev.agents)} is older than the fusion "
                       f"horizon of agent '{agent}', whose state is at {state_s:g} s (max_range_age_s = "
                       f"{self.max_range_age_s:g} s)")
                lagging = [a for a in ev.agents if not self.in_contact(a)]
                if lagging:
                    other = lagging[0]
                    why += (f"; agent '{other}' has reported only up to {self.latest_s[other]:g} s and is out of "
                            f"contact (contact_timeout_s = {self.contact_timeout_s:g} s), so the group did not wait "
                            "for it: upload every agent's events in slices shorter than contact_timeout_s, or "
                            "create the group with a longer contact_timeout_s")
                return why
        return None

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

    @staticmethod
    def _dropped(item: tuple[float, int, str, int, Event], reason: str) -> dict[str, Any]:
        ev = item[4]
        return {"seq": item[3], "t_s": item[0], "type": event_to_dict(ev)["type"], "agents": list(ev.agents),
                "reason": reason}

    def process(self, flush: bool = False) -> dict[str, Any]:
        """Apply the buffered events up to the watermark (all of them with ``flush``) in time order.

        Returns the numbers applied, dropped (``stale_ranges``) and still pending, and ``dropped``: the events
        dropped in this call, each ``{"seq", "t_s", "type", "agents", "reason"}``.
        """
        limit = math.inf if flush else self.watermark()
        applied = 0
        dropped: list[dict[str, Any]] = []
        held: list[tuple[float, int, str, int, Event]] = []
        while self._pending and self._pending[0][0] <= limit:
            item = heapq.heappop(self._pending)
            t, ev = item[0], item[4]
            if _two_agents(ev):
                reason = self._stale_reason(ev)
                if reason:                         # states only move forward: it can never be fused
                    dropped.append(self._dropped(item, reason))
                    continue
                if not flush and any(self.latest_s[a] < t - self.max_range_age_s for a in ev.agents):
                    held.append(item)              # an agent out of contact has not reported up to t yet
                    continue
            self._apply(ev)
            applied += 1
            self.clock_s = max(self.clock_s, t)
        for item in held:
            reason = self._stale_reason(item[4])           # overtaken by later steps while it waited
            if reason:
                dropped.append(self._dropped(item, reason))
            else:
                heapq.heappush(self._pending, item)
        self.counts["applied"] += applied
        self.counts["stale_ranges"] += len(dropped)
        return {"applied": applied, "stale_ranges": len(dropped), "pending": len(self._pending), "dropped": dropped}

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
