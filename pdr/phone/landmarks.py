"""Landmarks (seed 003 Sec. 3): identification by a three-level decision tree, and a site description.

Decision tree (seed 003 Fig. 2), evaluated on the intervals the step detector gives:

1. **elevator**: a pair of opposite impulses of the vertical specific force (hyper- then hypo-gravity or
   the reverse) with a stationary ride between them, no steps during it, walked into and out of (a step
   shortly before the first impulse and shortly after the second: a vehicle's vertical jolts come with no
   walking around them); the magnetic magnitude change at entry and exit marks the doors (reported as
   ``mag_change_uT``). When a barometer is present, the altitude change during the ride must exceed half a
   floor.
2. **walking/stairs vs escalator/standing**: acceleration variance (steps exist only in the first group);
   between steps, **escalator vs standing** by the variance of the magnetic magnitude.
3. **walking vs stairs up/down**: for a trouser-pocket phone the leg-pitch pattern (eqs. 1-3: the opening
   angle ``Delta Pitch = Pitch_max - Pitch_min`` is larger upstairs and smaller downstairs than on the
   flat, ``Pitch_max`` is larger upstairs and ``Pitch_min`` larger downstairs), compared with a running
   baseline of flat walking; when a barometer is present its vertical rate decides (it is also the only
   cue for hand-held phones, whose pitch does not follow the leg).

Neighbour-step correction (Sec. 3): a step whose label differs from both neighbours, which agree, takes
their label.

Site description (JSON)::

    {"name": "...", "floor_height_m": 4.0,
     "landmarks": [{"id": "S1", "type": "stairs_up" | "stairs_down" | "stairs" | "elevator" | "escalator",
                    "east_m": 12.0, "north_m": 3.5, "floor": 0,
                    "heading_deg": [80, 100],      # interval of compass headings (clockwise from north)
                    "radius_m": 8.0}]}

A detected landmark is matched to the nearest site landmark of a compatible type on the current floor
within its radius; its heading interval gives ``UH_landmark`` (centre) with a standard deviation of a sixth
of the width (three-sigma interval, Sec. 5) for both UKFs, and its position fixes the track. A flight of
stairs is matched at its first step (which fixes the position) and then observed at every step the tree
labels stairs (:class:`pdr.phone.pipeline.PdrPipeline`). :func:`pdr.sim.site_document` writes the site
description of a simulated scenario.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.frames import heading_deg_to_yaw
from pdr.json_number import json_number
from pdr.phone.baro_rides import WALK_OUT_S
from pdr.phone.history import SampleHistory
from pdr.site.document import floor_altitude_m, floor_height_m, floors_list, read_site_document

FloatArray = NDArray[np.float64]

MODES: tuple[str, ...] = ("walking", "stairs_up", "stairs_down", "elevator", "escalator", "standing")
LANDMARK_TYPES: tuple[str, ...] = ("stairs_up", "stairs_down", "stairs", "elevator", "escalator")


#: Window (s) before a step's end over which its barometric vertical rate is taken.
RATE_WINDOW_S = 2.0


@dataclass(frozen=True)
class LandmarkConfig:
    """Thresholds of the decision tree.

    Attributes
    ----------
    stairs_rate_mps
        Barometric vertical rate above which a step is on stairs (m/s).
    pitch_open_ratio_up, pitch_open_ratio_down
        Eq. 2: opening-angle ratio to the flat baseline above which (below which) a step is up (down) stairs.
    pitch_shift_deg
        Eq. 3: shift of ``Pitch_max`` (up) or ``Pitch_min`` (down) above the flat baseline (deg).
    elevator_impulse_mps2, elevator_impulse_s
        Vertical specific-force impulse of an elevator start/stop: magnitude (m/s^2) and minimum duration (s).
    elevator_max_ride_s
        Longest time between the two impulses (s).
    elevator_max_steps
        Most steps between the two impulses of a ride: a rider stands in the cabin (a shuffle or a turn may make a
        step or two); a walk between two jolts (a flight of stairs between landings) is no ride.
    elevator_walk_s
        Longest pause (s) from the rider's last step in to the first impulse, and from the second impulse to the
        first step out: the doors close and open (as :data:`pdr.phone.baro_rides.WALK_OUT_S`). Jolts with no
        walking that close around them (a car's, a bus's) are no ride.
    """

    stairs_rate_mps: float = 0.12
    pitch_open_ratio_up: float = 1.25
    pitch_open_ratio_down: float = 0.8
    pitch_shift_deg: float = 8.0
    elevator_impulse_mps2: float = 0.2
    elevator_impulse_s: float = 0.8
    elevator_max_ride_s: float = 60.0
    elevator_max_steps: int = 2
    elevator_walk_s: float = WALK_OUT_S


def classify_step(vertical_rate_mps: float | None, pitch_max_deg: float | None, pitch_min_deg: float | None,
                  baseline: tuple[float, float, float] | None, config: LandmarkConfig) -> str:
    """Third level of the tree for one step: ``walking``, ``stairs_up`` or ``stairs_down``.

    ``baseline`` is the flat-walking (opening angle, Pitch_max, Pitch_min) in degrees.
    """
    if vertical_rate_mps is not None and math.isfinite(vertical_rate_mps):
        if vertical_rate_mps > config.stairs_rate_mps:
            return "stairs_up"
        if vertical_rate_mps < -config.stairs_rate_mps:
            return "stairs_down"
        return "walking"
    if pitch_max_deg is None or pitch_min_deg is None or baseline is None:
        return "walking"
    opening = pitch_max_deg - pitch_min_deg                         # eq. 1
    b_open, b_max, b_min = baseline
    if opening > config.pitch_open_ratio_up * b_open and pitch_max_deg > b_max + config.pitch_shift_deg:
        return "stairs_up"                                          # eqs. 2-3
    if opening < config.pitch_open_ratio_down * b_open and pitch_min_deg > b_min + config.pitch_shift_deg:
        return "stairs_down"                                        # eqs. 2-3
    return "walking"


def neighbour_correction(prev: str, cur: str, nxt: str) -> str:
    """Seed 003 Sec. 3: a label that differs from two agreeing neighbours takes theirs."""
    return prev if prev == nxt and cur != prev else cur


class StepModeLabeller:
    """The pipeline's landmark-label stage: the third level of the tree per step (:func:`classify_step`) against a
    running baseline of the leg pitch on flat walking, and the neighbour-step correction at output.

    ``prev_mode`` is the (corrected) label of the last step output (``""`` before the first).
    """

    def __init__(self, config: LandmarkConfig, rate_hz: float) -> None:
        self.config = config
        self.rate_hz = rate_hz
        self.pitch_baseline: list[float] | None = None
        self.prev_mode = ""

    def label(self, h: SampleHistory, s: int, e: int, placement: str | None, has_baro: bool) -> str:
        """Label of the step of grid samples ``[s, e)``: the barometric vertical rate over the 2 s before its end,
        and for a trouser pocket the leg pitch (deg) over the step (eqs. 1-3).
        """
        sl = h.sl(s, e)
        rate = None
        if has_baro:
            back = h.sl(s - int(RATE_WINDOW_S * self.rate_hz), e)
            tt, uu = h.t[back], h.up[back]
            # As Python floats: the same IEEE operations as on numpy scalars, without their dispatch per step.
            if tt.size > 2 and tt.item(-1) > tt.item(0):
                rate = (uu.item(-1) - uu.item(0)) / (tt.item(-1) - tt.item(0))
        pmax = pmin = None
        if placement == "pocket":
            pitch = np.degrees(np.arcsin(np.clip(h.y_up[sl], -1, 1)))
            pmax, pmin = float(pitch.max()), float(pitch.min())
        base = tuple(self.pitch_baseline) if self.pitch_baseline else None
        mode = classify_step(rate, pmax, pmin, base, self.config)  # type: ignore[arg-type]
        if mode == "walking" and pmax is not None and pmin is not None:
            nb = [pmax - pmin, pmax, pmin]
            self.pitch_baseline = nb if self.pitch_baseline is None else [
                0.9 * a + 0.1 * b for a, b in zip(self.pitch_baseline, nb, strict=True)]
        return mode

    def corrected(self, mode: str, next_mode: str | None) -> str:
        """The label of the step being output, between the last output step's and the next step's (None: no next
        step within a step's duration).
        """
        if next_mode is not None and self.prev_mode:
            return neighbour_correction(self.prev_mode, mode, next_mode)
        return mode

    def state(self) -> dict[str, Any]:
        return {"prev_mode": self.prev_mode, "pitch_baseline": self.pitch_baseline}

    @classmethod
    def from_state(cls, d: dict[str, Any], config: LandmarkConfig, rate_hz: float) -> StepModeLabeller:
        o = cls(config, rate_hz)
        o.prev_mode, o.pitch_baseline = str(d["prev_mode"]), d["pitch_baseline"]
        return o


@dataclass(frozen=True)
class SiteLandmark:
    """A surveyed landmark: type, position (m, site ENU), floor, compass heading interval (deg), match radius."""

    id: str
    type: str
    east_m: float
    north_m: float
    floor: float
    heading_deg: tuple[float, float]
    radius_m: float = 8.0

    def yaw_and_var(self) -> tuple[float, float]:
        """Centre of the heading interval as internal yaw (rad) and its variance (sigma = width / 6)."""
        lo, hi = self.heading_deg
        width = (hi - lo) % 360.0
        centre = lo + width / 2.0
        sigma = math.radians(max(width, 1.0)) / 6.0
        return float(heading_deg_to_yaw(centre)), sigma * sigma

    def matches(self, mode: str) -> bool:
        if self.type == "stairs":
            return mode in ("stairs_up", "stairs_down")
        return self.type == mode


@dataclass(frozen=True)
class Site:
    """A site description: named landmarks, the floor height and optionally the magnetic declination and grid.

    ``declination_deg`` (deg, east positive; JSON key of the same name, optional): when given, the pipeline's
    attitude filter uses it instead of ``AttitudeConfig.mag_declination_deg``.
    ``grid_deg`` (deg, compass bearing clockwise from north of one of the building's main axes, optional): when
    given, the heuristic drift elimination of hand-held and torso headings snaps to this grid instead of learning
    the walk's dominant directions (:class:`pdr.phone.heading.StepDriftElimination`).
    ``floor_altitudes_m``: ``(floor, altitude m)`` of the floors whose entry in the ``floors`` list (the floor-plan
    layout of :mod:`pdr.site.plan`) states an ``altitude_m``; the floor tracker uses them instead of
    ``floor_height_m`` (which still counts floors beyond them).
    """

    name: str
    landmarks: tuple[SiteLandmark, ...]
    floor_height_m: float = 4.0
    declination_deg: float | None = None
    grid_deg: float | None = None
    floor_altitudes_m: tuple[tuple[float, float], ...] = ()

    @classmethod
    def from_dict(cls, d: Any, source: str = "site") -> Site:
        if not isinstance(d, dict):
            raise InputError("expected an object with a 'landmarks' list", source=source)
        floors = floors_list(d, source, required=False)   # before the landmarks: a bad one is not a missing list
        landmarks = d.get("landmarks", [] if d.get("floors") is not None else None)   # a plan-only site
        if not isinstance(landmarks, list):
            raise InputError("expected an object with a 'landmarks' list (it may be left out where a 'floors' list "
                             "of floor plans is given)", source=source, field="landmarks")
        name = d.get("name", "")
        if not isinstance(name, str):           # str() of it would be the site's name: "{'a': 1}", "5", "None"
            raise InputError(f"name must be text, not {type(name).__name__} {name!r:.40}", source=source,
                             field="name")
        out = []
        for i, lm in enumerate(landmarks):
            where = f"{source} landmark {i}"
            try:
                landmark_id = lm.get("id", i) if isinstance(lm, dict) else i
                if isinstance(landmark_id, bool) or not isinstance(landmark_id, str | int):
                    raise InputError(f"id must be text or a whole number, not {type(landmark_id).__name__} "
                                     f"{landmark_id!r:.40}", source=where, field="id")
                typ = str(lm["type"])
                if typ not in LANDMARK_TYPES:
                    raise InputError(f"type must be one of {LANDMARK_TYPES}", source=where, field="type")
                hd = lm["heading_deg"]
                if not (isinstance(hd, list | tuple) and len(hd) == 2):
                    raise InputError("heading_deg must be [from, to] in degrees", source=where, field="heading_deg")
                radius = _finite(lm.get("radius_m", 8.0), "radius_m", where)
                if radius <= 0:
                    raise InputError(f"radius_m must be positive, not {radius:g}", source=where, field="radius_m")
                out.append(SiteLandmark(str(landmark_id), typ, _finite(lm["east_m"], "east_m", where),
                                        _finite(lm["north_m"], "north_m", where),
                                        _finite(lm.get("floor", 0), "floor", where),
                                        (_finite(hd[0], "heading_deg", where), _finite(hd[1], "heading_deg", where)),
                                        radius))
            except KeyError as exc:
                raise InputError(f"missing field {exc}", source=where) from None
            except InputError:
                raise
            except (TypeError, ValueError) as exc:
                raise InputError(f"bad value ({exc})", source=where) from None
        fh = floor_height_m(d, source)
        decl, grid = (_site_angle(d, name, source) for name in ("declination_deg", "grid_deg"))
        return cls(name, tuple(out), fh, decl, grid, _floor_altitudes(floors, source))

    @classmethod
    def load(cls, path: str | Path) -> Site:
        return cls.from_dict(read_site_document(path), source=str(path))

    def to_dict(self) -> dict[str, Any]:
        extra: dict[str, Any] = {k: v for k, v in (("declination_deg", self.declination_deg),
                                                   ("grid_deg", self.grid_deg)) if v is not None}
        if self.floor_altitudes_m:
            extra["floors"] = [{"floor": f, "altitude_m": a} for f, a in self.floor_altitudes_m]
        return {"name": self.name, "floor_height_m": self.floor_height_m, **extra,
                "landmarks": [{"id": lm.id, "type": lm.type, "east_m": lm.east_m, "north_m": lm.north_m,
                               "floor": lm.floor, "heading_deg": list(lm.heading_deg), "radius_m": lm.radius_m}
                              for lm in self.landmarks]}

    def by_id(self, landmark_id: str) -> SiteLandmark | None:
        """The landmark with this id, or None."""
        return next((lm for lm in self.landmarks if lm.id == landmark_id), None)

    def match(self, mode: str, east_m: float, north_m: float, floor: float) -> SiteLandmark | None:
        """Nearest landmark of a compatible type within its radius (same floor when the floor is known)."""
        best, best_d = None, math.inf
        for lm in self.landmarks:
            if not lm.matches(mode):
                continue
            if math.isfinite(floor) and math.isfinite(lm.floor) and abs(lm.floor - floor) > 1.0:
                continue
            d = math.hypot(lm.east_m - east_m, lm.north_m - north_m)
            if d <= lm.radius_m and d < best_d:
                best, best_d = lm, d
        return best


def _finite(value: Any, name: str, where: str) -> float:
    """A landmark's number ``name``: a finite JSON number (:func:`pdr.json_number.json_number`; a NaN or infinite
    position, floor or heading was taken, and a session on the site had its position fixed at NaN, and a string or a
    boolean was read as a number); :class:`InputError` naming the field otherwise.
    """
    return json_number(value, where, name)


def _site_angle(d: dict[str, Any], name: str, source: str) -> float | None:
    """The optional angle ``d[name]`` in degrees, a JSON number in [-180, 180] (None when absent)."""
    v = d.get(name)
    if v is None:
        return None
    a = json_number(v, source, name)
    if not -180.0 <= a <= 180.0:
        raise InputError(f"{name} must be a number of degrees in [-180, 180]", source=source, field=name)
    return a


class ElevatorDetector:
    """First level of the tree: a pair of opposite vertical specific-force impulses with no steps between, walked
    into and out of.

    Feed the low-passed vertical specific force minus gravity (m/s^2) on the grid; reports
    ``(start_idx, end_idx, direction)`` with direction +1 (up: positive impulse first) or -1. Steps reported with
    :meth:`add_step` (grid index of their start) count against the pair when they fall between the impulses: with
    more than ``elevator_max_steps`` there it is no ride, and the second impulse may open a new pair. A pair is a
    ride only when a step starts within ``elevator_walk_s`` before the first impulse (the rider walked in) and
    one within ``elevator_walk_s`` after the second (the rider walks out): it waits in ``pending`` for that step,
    which the step detector confirms a few seconds late, and is reported by the :meth:`update` after it. A pair
    still waiting ``elevator_max_ride_s`` after its walk-out window closed is forgotten (no one walked out).
    """

    def __init__(self, rate_hz: float, config: LandmarkConfig | None = None) -> None:
        self.rate_hz = float(rate_hz)
        self.config = config or LandmarkConfig()
        self.run_sign = 0
        self.run_start = -1
        self.run_len = 0
        self.first: tuple[int, int, int] | None = None   # (start, end, sign) of a pending first impulse
        self.index = 0
        self.steps: list[int] = []                        # grid indices of recent step starts
        self.pending: list[tuple[int, int, int]] = []     # walked-in pairs waiting for a step out

    def add_step(self, idx: int) -> None:
        """A step starting at grid index ``idx``."""
        self.steps.append(int(idx))

    def update(self, dv: FloatArray, moving: NDArray[np.bool_]) -> list[tuple[int, int, int]]:
        c = self.config
        need = int(round(c.elevator_impulse_s * self.rate_hz))
        max_ride = int(round(c.elevator_max_ride_s * self.rate_hz))
        sign = np.where(dv > c.elevator_impulse_mps2, 1, np.where(dv < -c.elevator_impulse_mps2, -1, 0))
        out: list[tuple[int, int, int]] = []
        # Only sign changes and their run lengths matter: loop over run boundaries, not samples.
        change = np.flatnonzero(np.diff(np.concatenate([[self.run_sign], sign])) != 0)
        bounds = [int(b) for b in change] + [int(sign.size)]
        pos = 0
        for b in bounds:
            self.run_len += b - pos
            if b < sign.size:
                self._end_run(self.index + b, need, max_ride, moving, pos, out)
                self.run_sign = int(sign[b])
                self.run_start = self.index + b
                self.run_len = 0
            pos = b
        self.index += sign.size
        self._walked_out(self.index, max_ride, out)
        return out

    def _end_run(self, end: int, need: int, max_ride: int, moving: NDArray[np.bool_], _pos: int,
                 out: list[tuple[int, int, int]]) -> None:
        if self.run_sign == 0 or self.run_len < need:
            return
        self._walked_out(end, max_ride, out)         # before the steps it needs are forgotten below
        if self.first is not None and end - self.first[1] > max_ride:
            self.first = None
        if self.first is not None and self.first[2] != self.run_sign:
            a = self.first[1]
            if sum(1 for i in self.steps if a < i < self.run_start) > self.config.elevator_max_steps:
                self.first = None  # a walk between two jolts
        if self.first is None or self.first[2] == self.run_sign:
            self.first = (self.run_start, end, self.run_sign)
        else:
            start = self.first[0]
            if any(start - self._walk() <= i < start for i in self.steps):   # walked in: else a vehicle's jolts
                self.pending.append((start, end, self.first[2]))
                self._walked_out(end, max_ride, out)
            self.first = None
        keep = min([end - max_ride, *(p[1] - 1 for p in self.pending)])
        self.steps = [i for i in self.steps if i > keep]

    def _walk(self) -> int:
        """``elevator_walk_s`` in grid samples."""
        return int(round(self.config.elevator_walk_s * self.rate_hz))

    def _walked_out(self, now: int, max_ride: int, out: list[tuple[int, int, int]]) -> None:
        """Report the pending pairs that a step starts within ``elevator_walk_s`` after; forget those whose window
        closed ``max_ride`` samples before grid index ``now``.
        """
        walk, keep = self._walk(), []
        for ride in self.pending:
            if any(ride[1] <= i <= ride[1] + walk for i in self.steps):
                out.append(ride)
            elif now <= ride[1] + walk + max_ride:
                keep.append(ride)
        self.pending = keep

    def state(self) -> dict[str, Any]:
        return {"rate_hz": self.rate_hz, "run_sign": self.run_sign, "run_start": self.run_start,
                "run_len": self.run_len, "first": list(self.first) if self.first else None, "index": self.index,
                "steps": list(self.steps), "pending": [list(p) for p in self.pending]}

    @classmethod
    def from_state(cls, d: dict[str, Any], config: LandmarkConfig | None = None) -> ElevatorDetector:
        e = cls(float(d["rate_hz"]), config)
        e.run_sign, e.run_start, e.run_len = int(d["run_sign"]), int(d["run_start"]), int(d["run_len"])
        f = d["first"]
        e.first = (int(f[0]), int(f[1]), int(f[2])) if f else None
        e.index = int(d["index"])
        e.steps = [int(i) for i in d.get("steps", [])]  # states saved before steps were counted have none
        e.pending = [(int(p[0]), int(p[1]), int(p[2])) for p in d.get("pending", [])]
        return e


def _floor_altitudes(floors: list[Any], source: str) -> tuple[tuple[float, float], ...]:
    """``(floor, altitude m)`` of the ``floors`` entries that state ``altitude_m``."""
    out = []
    for i, f in enumerate(floors):
        if not isinstance(f, dict) or f.get("altitude_m") is None:
            continue
        where = f"{source} floor {i}"
        if "floor" not in f:
            raise InputError("missing field 'floor'", source=where, field="floor")
        out.append((json_number(f["floor"], where, "floor"), floor_altitude_m(f["altitude_m"], where)))
    return tuple(sorted(out))
