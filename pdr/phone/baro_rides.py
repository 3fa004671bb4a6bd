"""Elevator rides from the barometer: the altitude moved while the user stood still, then the user walked out.

The accelerometer's ride detector (:class:`pdr.phone.landmarks.ElevatorDetector`) needs the cabin's start and stop
as two opposite impulses of the vertical specific force (0.2 m/s^2 for 0.8 s). A slow lift starts and stops more
gently than a hand-held phone's own motion lets that be seen: on IPIN 2023's elevator walk (``.mat`` trial 53, the
museum's 0.4 m/s lift) it found none of the four rides, and on the simulated torso walk
(``mobile_logs/sim/torso_elevator.zip``) none either. With a barometer the ride is what the floor tracker
(:mod:`pdr.phone.floors`) already sees, per grid sample:

* a *climb*: a stretch of samples whose low-passed vertical speed is at ``settle_mps`` or more
  (:attr:`pdr.phone.floors.FloorSamples.moving`), during which the user stood for most of the samples (the
  specific force still, :attr:`~pdr.phone.floors.FloorSamples.walking` false: a rider stands in the cabin; a
  climb walked is stairs);
* of at least half the lowest floor height (``min_climb_m``: a ride crosses at least one floor; smaller changes
  are a ramp or the weather), moving for at most ``max_ride_s``;
* faster than an escalator at its peak: an escalator climbs at most ``ESCALATOR_MAX_VERTICAL_MPS`` (0.375 m/s,
  0.75 m/s along a 30 deg incline, EN 115-1), a passenger elevator cruises at 0.4 m/s (a slow low-rise lift, the
  museum's: peak low-passed speeds of 0.46-0.52 m/s on its four rides) to several m/s;
* and the user walks within ``walk_out_s`` of the altitude settling: a rider walks out once the doors open. A car
  climbing a road also carries a still user, but nobody walks off a road's hill seconds after it levels out.

Climbs one after the other with no walking between them (the cabin stopped at a floor on the way and the rider
stayed in) are one ride, from the first climb's start to the last one's end. The ride is reported when the user
walks out (:class:`BaroRide`), with its start and end and the altitude change from the first climb's start to the
last one's settling.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]

#: Highest vertical speed (m/s) of an escalator: 0.75 m/s along a 30 deg incline (EN 115-1's upper limit).
ESCALATOR_MAX_VERTICAL_MPS = 0.75 * math.sin(math.radians(30.0))
#: Longest time (s) from the altitude settling to the rider's first step out: doors open, a few seconds' pause.
WALK_OUT_S = 10.0


@dataclass(frozen=True)
class BaroRide:
    """A ride: grid indices ``start``/``end`` and times ``t_start_s``/``t_end_s`` (s, log clock) of its first
    climb's start and last climb's settling, the altitude there (m above the floor tracker's reference) and its
    change (m, up positive).
    """

    start: int
    end: int
    t_start_s: float
    t_end_s: float
    up_start_m: float
    altitude_change_m: float


@dataclass
class BaroRides:
    """Online elevator rides from the floor tracker's samples (module doc); feed every batch with :meth:`update`.

    State: the grid index of the next sample (``index``); the climb in progress (``start``: its grid index, -1
    when the altitude is settled; ``up0``: the altitude (m) where the ride began; ``walked``/``ridden``: moving
    samples walked and stood; ``peak_mps``: the largest vertical speed; ``t_start_s``: its start time) and the ride
    waiting for the rider to walk out (``pending``, or None).
    """

    rate_hz: float
    max_ride_s: float = 60.0
    walk_out_s: float = WALK_OUT_S
    index: int = 0
    start: int = -1
    up0: float = math.nan
    walked: int = 0
    ridden: int = 0
    peak_mps: float = 0.0
    t_start_s: float = math.nan
    pending: BaroRide | None = None

    def update(self, t_s: FloatArray, moving: NDArray[np.bool_], walking: NDArray[np.bool_], up_m: FloatArray,
               rate_mps: FloatArray, min_climb_m: float) -> list[BaroRide]:
        """Rides whose rider walked out in this batch. ``t_s`` are the batch's grid times (s, log clock), the other
        arrays its :class:`pdr.phone.floors.FloorSamples` (``moving``, ``walking``, ``up_m``, ``rate_mps``);
        ``min_climb_m`` (m) is the least altitude change of a ride.
        """
        n = moving.size
        if not (t_s.size == walking.size == up_m.size == rate_mps.size == n):
            raise InputError("t_s, moving, walking, up_m and rate_mps must have one value per sample",
                             source="rides")
        out: list[BaroRide] = []
        code = moving.astype(np.int8) * 2 + walking.astype(np.int8)
        bounds = np.flatnonzero(np.diff(code)) + 1
        for a, b in zip([0, *bounds.tolist()], [*bounds.tolist(), n], strict=True):
            if a == b:
                continue
            if moving[a]:
                self._climb(a, b, float(t_s[a]), walking, up_m, rate_mps)
            else:
                if self.start >= 0:
                    self._settled(a, float(t_s[a]), float(up_m[a]), min_climb_m)
                self._stand_or_walk(a, b, bool(walking[a]), out)
        self.index += n
        return out

    def _climb(self, a: int, b: int, t_a: float, walking: NDArray[np.bool_], up_m: FloatArray,
               rate_mps: FloatArray) -> None:
        """Samples ``a:b`` of the batch move (a climb starts at time ``t_a`` or goes on)."""
        if self.start < 0:
            if self.pending is not None:
                # The cabin moves on with the rider in it (no walking since it stopped): the same ride.
                p = self.pending
                self.start, self.up0, self.t_start_s, self.pending = p.start, p.up_start_m, p.t_start_s, None
            else:
                self.start, self.up0, self.t_start_s = self.index + a, float(up_m[a]), t_a
                self.walked = self.ridden = 0
                self.peak_mps = 0.0
        w = int(np.count_nonzero(walking[a:b]))
        self.walked += w
        self.ridden += (b - a) - w
        self.peak_mps = max(self.peak_mps, float(np.max(np.abs(rate_mps[a:b]))))

    def _settled(self, a: int, t_a: float, up_a: float, min_climb_m: float) -> None:
        """The altitude settled at sample ``a`` of the batch (time ``t_a``, altitude ``up_a`` m): the climb that
        ends there may be a ride.
        """
        dh = up_a - self.up0
        if (self.ridden > self.walked and abs(dh) >= min_climb_m and self.peak_mps > ESCALATOR_MAX_VERTICAL_MPS
                and self.walked + self.ridden <= self.max_ride_s * self.rate_hz):
            self.pending = BaroRide(self.start, self.index + a, self.t_start_s, t_a, self.up0, dh)
        self.start = -1

    def _stand_or_walk(self, a: int, b: int, walks: bool, out: list[BaroRide]) -> None:
        """Samples ``a:b`` of the batch are settled, all walked (``walks``) or all stood."""
        if self.pending is None:
            return
        deadline = self.pending.end + int(round(self.walk_out_s * self.rate_hz))
        if walks and self.index + a < deadline:
            out.append(self.pending)
            self.pending = None
        elif walks or self.index + b >= deadline:
            self.pending = None          # no one walked out: not a ride (a car's hill)

    def state(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> BaroRides:
        try:
            p = d["pending"]
            pending = None if p is None else BaroRide(int(p["start"]), int(p["end"]), float(p["t_start_s"]),
                                                      float(p["t_end_s"]), float(p["up_start_m"]),
                                                      float(p["altitude_change_m"]))
            return cls(float(d["rate_hz"]), float(d["max_ride_s"]), float(d["walk_out_s"]), int(d["index"]),
                       int(d["start"]), float(d["up0"]), int(d["walked"]), int(d["ridden"]), float(d["peak_mps"]),
                       float(d["t_start_s"]), pending)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad barometric ride state ({exc})", source="rides") from None
