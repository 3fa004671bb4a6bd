"""The stop and elevator entries of a session's modes timeline, built online from the phone pipeline's events.

:class:`StopTimeline` feeds each sensor batch and the pipeline's events for it to a
:class:`classifiers.stops.StopDetector` (steps and the pipeline's elevator rides are its busy intervals) and
turns what it reports into timeline entries (:class:`ModeEntry`):

* a stop during which the pipeline reports a floor change (``floor_change`` event between the stop's start and
  ``FLOOR_LAG_S`` after its end: the barometric floor decision lags the pressure) is a ride,
  ``elevator_up/down`` or, when its altitude profile is an escalator's (:mod:`classifiers.rides`, from the
  batches' barometer), ``escalator_up/down``, with its floor change (``from_floor``, ``floor``, ``floors``; the floors
  are the pipeline's, counted with its floor height unless a site gives the floors' altitudes) and the altitude
  change between the steps before and after it (``altitude_change_m``). While the pipeline's floor numbers still
  assume the default floor height (its ``floor_change`` events say ``height_assumed``), the floor count is the
  whole number of floors that altitude change spans (:func:`pdr.phone.floors.whole_floors`: exactly one count of
  2.5-5 m floors fits it), when one does: the rule by which the pipeline then learns the height from this very ride
  once its rider walks out, renumbering the floors (a 5.8 m ride with the 4 m default reads as one floor until
  then; it is two of 2.9 m). A person
  who takes no step and holds the phone still while the altitude changes by a floor rides a cabin or a belt;
  ``vertical_speed_mps`` and ``tail_s`` are the ride's profile;
* any other stop is ``standing``;
* an ``elevator`` event of the pipeline from the vertical-acceleration impulse pair (a phone without a barometer)
  is an ``elevator_up/down`` entry with its altitude change (the pipeline's detector drops a pair of impulses with
  a walk between them). One from the barometer (``source`` ``barometer``, :mod:`pdr.phone.baro_rides`) is the ride
  the stop rule above finds with its floor change and profile, and is not added twice.

The state (:meth:`StopTimeline.state`) is JSON-able, for the session processor's stored state.

:class:`StepModes` turns the pipeline's per-step modes into timeline entries: an entry where the mode changes,
except that a stairs entry needs ``MIN_FLIGHT_STEPS`` consecutive stairs steps of one direction (a flight of
stairs has at least three risers; one or two steps labelled stairs are the barometer settling after an elevator
ride or a door's pressure change, and stay in the walking entry), and that stairs steps starting less than
``RIDE_REACH_S`` after a ride's end are not stairs: the pipeline labels a step stairs from the barometric
vertical rate over the ``STEP_RATE_WINDOW_S`` before the step's end, of an altitude low-passed with a
``ALTITUDE_SMOOTH_S`` time constant (:mod:`pdr.phone.landmarks`, :mod:`pdr.phone.floors`), so the first steps
off an elevator or escalator still read the ride's climb. For the same reason an entry into or out of stairs is
placed ``RATE_DELAY_S`` before the end of the step that shows it (the delay of that rate: half its window plus the
low-pass time constant), but not before the latest entry: a flight's first steps, and the level steps after
its last, show the stairs label late.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from classifiers.rides import AltitudeRecord, ride_kind
from classifiers.stops import STOP_LABEL, Stop, StopDetector
from pdr.errors import InputError
from pdr.phone.floors import FloorConfig, whole_floors
from pdr.phone.landmarks import RATE_WINDOW_S
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
#: Window (s) before a step's end over which the pipeline takes its barometric vertical rate (pdr.phone.landmarks).
STEP_RATE_WINDOW_S = RATE_WINDOW_S
#: Time constant (s) of the pipeline's altitude low-pass (pdr.phone.floors.FloorConfig.smooth_s, its default).
ALTITUDE_SMOOTH_S = FloorConfig().smooth_s
#: Seconds after a ride's end within which a step's stairs label is the ride's climb (module docstring).
RIDE_REACH_S = STEP_RATE_WINDOW_S + ALTITUDE_SMOOTH_S
#: Delay (s) of the step's barometric rate behind the step's end: half its window plus the low-pass lag.
RATE_DELAY_S = 0.5 * STEP_RATE_WINDOW_S + ALTITUDE_SMOOTH_S
#: Labels of rides (entries the stairs rule looks back to).
RIDE_PREFIXES = ("elevator_", "escalator_")

#: 2: the detector's and altitude record's times are on the log clock (version 1: on the first batch's axis).
STATE_VERSION = 2


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
        self.altitude = AltitudeRecord()
        # (t_s, from_floor, floor, 1.0 when the floor numbers assume the default height else 0.0)
        self.floor_changes: list[tuple[float, float, float, float]] = []
        self.step_up: list[tuple[float, float, float]] = []  # recent steps: (t_start_s, t_s, up_m)

    def update(self, batch: Recording, events: Sequence[dict[str, Any]]) -> list[ModeEntry]:
        """Entries that became final with this batch and the pipeline's events for it (time order)."""
        # The detector and the altitude record read the batch's own time axis (t_ns - t0_ns): put it on the log
        # clock of the events and entries (t_ns / 1e9), whatever t0_ns each batch of the session carries.
        batch = batch if batch.t0_ns == 0 else replace(batch, t0_ns=0)
        busy, rides = self._read(events)
        self.altitude.update(batch)
        entries = rides + self._entries(self.detector.update(batch, busy))
        self._trim()
        return entries

    def finish(self, events: Sequence[dict[str, Any]] = ()) -> list[ModeEntry]:
        """End of the session: the entries still open, with the pipeline's last events."""
        busy, rides = self._read(events)
        self.detector.add_busy(busy)
        entries = rides + self._entries(self.detector.finish())
        self._trim()
        return entries

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
                                           float(e["floor"]), float(bool(e.get("height_assumed", False)))))
            elif kind == "elevator" and e.get("source", "impulses") == "impulses":
                a, b = float(e["t_start_s"]), float(e["t_end_s"])
                busy.append((a, b))
                data = {"altitude_change_m": e.get("altitude_change_m"), "source": "impulses"}
                if e.get("floors") is not None:
                    data["floors"] = e["floors"]
                rides.append(ModeEntry(a, b, f"elevator_{e.get('direction', 'up')}", data))
        return busy, rides

    def _trim(self) -> None:
        """Keep the recent floor changes and steps only, once the stops they label have been reported (a batch
        with many steps, or a whole recording, reads them all first).
        """
        self.floor_changes = self.floor_changes[-KEEP_FLOOR_CHANGES:]
        self.step_up = self.step_up[-KEEP_STEPS:]

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
                climb = self._altitude_change(s)
                if math.isfinite(change) and change != 0 and climb is not None and any(f[3] for f in inside):
                    floors = whole_floors(abs(climb), *FloorConfig().floor_height_range_m)
                    if floors > 0 and (climb > 0) == (change > 0):
                        end = start + math.copysign(floors, change)
                        change = end - start
                if math.isfinite(change) and change != 0:
                    profile = self.altitude.profile(s.t_start_s, s.t_end_s)
                    kind = ride_kind(profile)
                    out.append(ModeEntry(s.t_start_s, s.t_end_s, f"{kind}_up" if change > 0 else f"{kind}_down",
                                         {"from_floor": start, "floor": end, "floors": abs(change),
                                          "altitude_change_m": climb,
                                          "vertical_speed_mps": None if profile is None
                                          else profile.vertical_speed_mps,
                                          "tail_s": None if profile is None else profile.tail_s,
                                          "source": "stop with a floor change"}))
                    continue
            out.append(ModeEntry(s.t_start_s, s.t_end_s, STOP_LABEL, {"duration_s": s.duration_s}))
        return out

    def state(self) -> dict[str, Any]:
        return {"version": STATE_VERSION, "detector": self.detector.state(),
                "floor_changes": [list(f) for f in self.floor_changes], "step_up": [list(u) for u in self.step_up],
                "altitude": self.altitude.state()}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> StopTimeline:
        try:
            if state["version"] not in (1, STATE_VERSION):
                raise InputError(f"stop timeline state version {state['version']} is not {STATE_VERSION}",
                                 field="version")
            tl = cls()
            # A version 1 state's detector and altitude record count from its first batch's t0_ns, not the log
            # clock: they start again (the stop in progress is lost); its steps and floor changes are on the log clock.
            old_clock = state["version"] == 1
            if not old_clock:
                tl.detector = StopDetector.from_state(state["detector"])
            # States saved before floor changes said whether the height was assumed: not assumed.
            tl.floor_changes = [(float(f[0]), float(f[1]), float(f[2]), float(f[3]) if len(f) > 3 else 0.0)
                                for f in state["floor_changes"]]
            tl.step_up = [(float(a), float(b), float(c)) for a, b, c in state.get("step_up", [])]
            if state.get("altitude") is not None and not old_clock:  # states saved before the record: a new one
                tl.altitude = AltitudeRecord.from_state(state["altitude"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not a stop timeline state ({exc})", field="state") from None
        return tl


class StepModes:
    """Timeline entries from per-step modes (module docstring); ``last`` is the mode of the latest entry."""

    def __init__(self, last: str = "") -> None:
        self.last = last
        self.pending: tuple[str, float, int] | None = None  # stairs run not yet long enough: label, start, steps
        self.ride_end_s = -math.inf  # end (s) of the latest ride entry
        self.last_t_s = -math.inf    # time (s) of the latest entry

    def step(self, mode: str, t_start_s: float, t_end_s: float | None = None) -> list[tuple[float, str]]:
        """A step of ``mode`` on ``[t_start_s, t_end_s]`` (s); returns the entries ``(t_s, label)`` it opens.
        Without ``t_end_s`` an entry into or out of stairs is placed at the step's start (no rate delay).
        """
        if mode in STAIRS_MODES and t_start_s < self.ride_end_s + RIDE_REACH_S:
            mode = "walking"  # the ride's climb in the step's barometric rate window
        if not mode or mode == self.last:
            self.pending = None
            return []
        t = t_start_s
        if t_end_s is not None and (mode in STAIRS_MODES or self.last in STAIRS_MODES):
            t = min(t_start_s, max(t_end_s - RATE_DELAY_S, self.last_t_s, self.ride_end_s))
        if mode in STAIRS_MODES:
            label, t0, n = self.pending if self.pending and self.pending[0] == mode else (mode, t, 0)
            if n + 1 < MIN_FLIGHT_STEPS:
                self.pending = (label, t0, n + 1)
                return []
            self.pending = None
            return self._open(t0, mode)
        self.pending = None
        return self._open(t, mode)

    def _open(self, t_s: float, mode: str) -> list[tuple[float, str]]:
        self.last, self.last_t_s = mode, max(self.last_t_s, t_s)
        return [(t_s, mode)]

    def entry(self, label: str, t_end_s: float | None = None) -> None:
        """Another entry (a stop, a ride) ending at ``t_end_s`` (s) now holds the timeline."""
        self.last, self.pending = label, None
        if t_end_s is not None:
            self.last_t_s = max(self.last_t_s, float(t_end_s))
        if t_end_s is not None and label.startswith(RIDE_PREFIXES):
            self.ride_end_s = max(self.ride_end_s, float(t_end_s))

    def state(self) -> dict[str, Any]:
        return {"last": self.last, "pending": None if self.pending is None else list(self.pending),
                "ride_end_s": None if math.isinf(self.ride_end_s) else self.ride_end_s,
                "last_t_s": None if math.isinf(self.last_t_s) else self.last_t_s}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> StepModes:
        try:
            m = cls(str(state["last"]))
            p = state.get("pending")
            m.pending = None if p is None else (str(p[0]), float(p[1]), int(p[2]))
            r = state.get("ride_end_s")
            m.ride_end_s = -math.inf if r is None else float(r)
            lt = state.get("last_t_s")
            m.last_t_s = -math.inf if lt is None else float(lt)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise InputError(f"not a step-modes state ({exc})", field="state") from None
        return m
