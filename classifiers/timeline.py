"""The stop and elevator entries of a session's modes timeline, built online from the phone pipeline's events.

:class:`StopTimeline` feeds each sensor batch and the pipeline's events for it to a
:class:`classifiers.stops.StopDetector` (steps and the pipeline's elevator rides are its busy intervals) and
turns what it reports into timeline entries (:class:`ModeEntry`):

* a stop during which the pipeline reports a floor change (``floor_change`` event between the stop's start and
  ``FLOOR_LAG_S`` after its end: the barometric floor decision lags the pressure) is an elevator ride,
  ``elevator_up`` or ``elevator_down``, with its floor change (``from_floor``, ``floor``, ``floors``; the floors
  are the pipeline's, counted with its floor height unless a site gives the floors' altitudes) and the altitude
  change between the steps before and after it (``altitude_change_m``): a person
  who takes no step and holds the phone still while the altitude changes by a floor rides a cabin;
* any other stop is ``standing``;
* an ``elevator`` event of the pipeline (vertical-acceleration impulse pair) is an ``elevator_up/down`` entry
  with its altitude change.

The state (:meth:`StopTimeline.state`) is JSON-able, for the session processor's stored state.

:class:`StepModes` turns the pipeline's per-step modes into timeline entries: an entry where the mode changes,
except that a stairs entry needs ``MIN_FLIGHT_STEPS`` consecutive stairs steps of one direction (a flight of
stairs has at least three risers; one or two steps labelled stairs are the barometer settling after an elevator
ride or a door's pressure change, and stay in the walking entry).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from classifiers.stops import STOP_LABEL, Stop, StopDetector
from pdr.errors import InputError
from pdr.recording import Recording

#: Seconds after a stop's end within which a floor change still belongs to it.
FLOOR_LAG_S = 3.0
#: Steps kept in the state for the altitude change across a stop.
KEEP_STEPS = 64
#: Floor changes kept in the state to label stops reported later (a stop is reported after its closing step).
KEEP_FLOOR_CHANGES = 16

#: Fewest consecutive stairs steps (one direction) that open a stairs entry.
MIN_FLIGHT_STEPS = 3
STAIRS_MODES = ("stairs_up", "stairs_down")

STATE_VERSION = 1


@dataclass(frozen=True)
class ModeEntry:
    """One timeline entry: ``label`` on ``[t_start_s, t_end_s]`` s (log clock) with JSON-able ``data``."""

    t_start_s: float
    t_end_s: float
    label: str
    data: dict[str, Any] = field(default_factory=dict)


class StopTimeline:
    """Online stop and elevator entries of one session (module docstring)."""

    def __init__(self) -> None:
        self.detector = StopDetector()
        self.floor_changes: list[tuple[float, float, float]] = []  # (t_s, from_floor, floor)
        self.step_up: list[tuple[float, float, float]] = []  # recent steps: (t_start_s, t_s, up_m)

    def update(self, batch: Recording, events: Sequence[dict[str, Any]]) -> list[ModeEntry]:
        """Entries that became final with this batch and the pipeline's events for it (time order)."""
        busy, rides = self._read(events)
        return rides + self._entries(self.detector.update(batch, busy))

    def finish(self, events: Sequence[dict[str, Any]] = ()) -> list[ModeEntry]:
        """End of the session: the entries still open, with the pipeline's last events."""
        busy, rides = self._read(events)
        self.detector.add_busy(busy)
        return rides + self._entries(self.detector.finish())

    def pending(self, events: Sequence[dict[str, Any]] = ()) -> list[ModeEntry]:
        """What :meth:`finish` would add if the session ended now (this object is not changed)."""
        return StopTimeline.from_state(self.state()).finish(events)

    def _read(self, events: Sequence[dict[str, Any]]) -> tuple[list[tuple[float, float]], list[ModeEntry]]:
        busy: list[tuple[float, float]] = []
        rides: list[ModeEntry] = []
        for e in events:
            kind = e.get("type")
            if kind == "step":
                busy.append((float(e.get("t_start_s", e["t_s"])), float(e["t_s"])))
                if e.get("up_m") is not None:
                    self.step_up.append((busy[-1][0], busy[-1][1], float(e["up_m"])))
            elif kind == "floor_change":
                self.floor_changes.append((float(e["t_s"]), float(e.get("from_floor", float("nan"))),
                                           float(e["floor"])))
            elif kind == "elevator":
                a, b = float(e["t_start_s"]), float(e["t_end_s"])
                busy.append((a, b))
                data = {"altitude_change_m": e.get("altitude_change_m"), "source": "impulses"}
                if e.get("floors") is not None:
                    data["floors"] = e["floors"]
                rides.append(ModeEntry(a, b, f"elevator_{e.get('direction', 'up')}", data))
        self.floor_changes = self.floor_changes[-KEEP_FLOOR_CHANGES:]
        self.step_up = self.step_up[-KEEP_STEPS:]
        return busy, rides

    def _altitude_change(self, s: Stop) -> float | None:
        """Barometric altitude (m) of the first step after the stop minus that of the last step before it."""
        before = [u for a, b, u in self.step_up if b <= s.t_start_s + 1e-9]
        after = [u for a, b, u in self.step_up if a >= s.t_end_s - 1e-9]
        return after[0] - before[-1] if before and after else None

    def _entries(self, stops: list[Stop]) -> list[ModeEntry]:
        out: list[ModeEntry] = []
        for s in stops:
            inside = [f for f in self.floor_changes if s.t_start_s <= f[0] <= s.t_end_s + FLOOR_LAG_S]
            if inside:
                start, end = inside[0][1], inside[-1][2]
                change = end - start
                if math.isfinite(change) and change != 0:
                    out.append(ModeEntry(s.t_start_s, s.t_end_s, "elevator_up" if change > 0 else "elevator_down",
                                         {"from_floor": start, "floor": end, "floors": abs(change),
                                          "altitude_change_m": self._altitude_change(s),
                                          "source": "stop with a floor change"}))
                    continue
            out.append(ModeEntry(s.t_start_s, s.t_end_s, STOP_LABEL, {"duration_s": s.duration_s}))
        return out

    def state(self) -> dict[str, Any]:
        return {"version": STATE_VERSION, "detector": self.detector.state(),
                "floor_changes": [list(f) for f in self.floor_changes], "step_up": [list(u) for u in self.step_up]}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> StopTimeline:
        try:
            if state["version"] != STATE_VERSION:
                raise InputError(f"stop timeline state version {state['version']} is not {STATE_VERSION}",
                                 field="version")
            tl = cls()
            tl.detector = StopDetector.from_state(state["detector"])
            tl.floor_changes = [(float(a), float(b), float(c)) for a, b, c in state["floor_changes"]]
            tl.step_up = [(float(a), float(b), float(c)) for a, b, c in state.get("step_up", [])]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not a stop timeline state ({exc})", field="state") from None
        return tl


class StepModes:
    """Timeline entries from per-step modes (module docstring); ``last`` is the mode of the latest entry."""

    def __init__(self, last: str = "") -> None:
        self.last = last
        self.pending: tuple[str, float, int] | None = None  # stairs run not yet long enough: label, start, steps

    def step(self, mode: str, t_start_s: float) -> list[tuple[float, str]]:
        """A step of ``mode`` starting at ``t_start_s`` (s); returns the entries ``(t_s, label)`` it opens."""
        if not mode or mode == self.last:
            self.pending = None
            return []
        if mode in STAIRS_MODES:
            label, t0, n = self.pending if self.pending and self.pending[0] == mode else (mode, t_start_s, 0)
            if n + 1 < MIN_FLIGHT_STEPS:
                self.pending = (label, t0, n + 1)
                return []
            self.pending = None
            self.last = mode
            return [(t0, mode)]
        self.pending = None
        self.last = mode
        return [(t_start_s, mode)]

    def entry(self, label: str) -> None:
        """Another entry (a stop, an elevator ride) now holds the timeline."""
        self.last, self.pending = label, None

    def state(self) -> dict[str, Any]:
        return {"last": self.last, "pending": None if self.pending is None else list(self.pending)}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> StepModes:
        try:
            m = cls(str(state["last"]))
            p = state.get("pending")
            m.pending = None if p is None else (str(p[0]), float(p[1]), int(p[2]))
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise InputError(f"not a step-modes state ({exc})", field="state") from None
        return m
