"""Floors from the barometer: altitude change, floor counting with hysteresis and drift re-anchoring.

Altitude from pressure with the standard atmosphere (:func:`pdr.frames.pressure_to_altitude_m`),
low-passed causally (first order, ``smooth_s``). The floor is ``floor0 + n`` where ``n`` changes by one
when the altitude relative to the reference moves more than ``hysteresis`` of the gap to the next floor's level
past the current floor's level. A floor's level is its altitude from the site (``altitudes_m``, e.g. a mezzanine
half a storey down) relative to ``floor0``'s, else ``n * floor_height_m`` (floors beyond the site's list continue
from the nearest listed one by ``floor_height_m``). While the user walks on the flat (no stairs, elevator or
escalator) the reference follows the altitude slowly (``drift_tau_s``)
so weather and ventilation drift do not count as floors. A floor is a level one stays on: the floor output changes
only once the altitude has settled (its rate, low-passed with ``smooth_s``, below ``settle_mps``) or the user walks
(the standard deviation of the specific-force magnitude over about ``smooth_s`` above ``walking_acc_std_mps2``: a
rider stands still in the cabin). An elevator ride thus changes the floor once, when the cabin stops or the rider
walks out, by the floors it crossed, and not at each floor passed on the way; on stairs the floor changes at once.

Without a site and without a stated floor height (:meth:`FloorConfig.assumes_default_height`), the floor height is
learnt from the first climb between two levels that stairs or an elevator made: both join floors, so such a climb
spans a whole number of floors. A level is an altitude that stayed settled for ``level_hold_s`` (a landing between
two flights lasts a stride or two; a floor is walked on for longer). The climb counts when it is one of these:

* stairs: the user walked through it (the specific force varied as in walking for most of its moving samples);
* an elevator ride (:mod:`pdr.phone.baro_rides`, the same rule as its events): stood through, peaking faster than
  an escalator can climb (``ESCALATOR_MAX_VERTICAL_MPS``), and walked out of within ``WALK_OUT_S`` of the
  altitude settling (the level waits for that). A car climbing a road carries a still user as a cabin does, but
  nobody walks off a hill seconds after it levels out.

and when exactly one whole number of floors, each within ``floor_height_range_m``, fits it (:func:`whole_floors`).
The range is the floor-to-floor heights of buildings: 2.5 m (a 2.2-2.4 m room height plus the slab) to 5 m. A climb
of 2.5-5 m is then one floor and one of 5-7.5 m two (IPIN trial 52 walks down two floors without stopping between
them: 5.9 m, 2.93 m a floor against the museum's 3.1 and 2.6 m; trial 53's first ride with a walk out, 0 to -2:
2.87 m); a longer one may be two floors or three, and is left alone. A ground floor over 5 m high climbed in one
go is read as two floors: a site's floor altitudes are the way to state such a building. A smaller altitude
change, at least half the lower bound, is a ramp or a half landing: the level the climb started from is kept.
From the learnt height on, every level is that far apart (:attr:`FloorTracker.learnt_height_m`).

Whether the altitude is still moving at each sample (its low-passed rate at ``settle_mps`` or more:
:attr:`FloorSamples.moving`) is also what the attitude filter needs: a user who stands in a moving cabin is carried
through the building's field and may turn with it, so such a stand does not calibrate the gyro
(:class:`pdr.phone.attitude.AttitudeFilter`, ``carried``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters.compiled import kernel
from pdr.frames import pressure_to_altitude_m
from pdr.phone.baro_rides import ESCALATOR_MAX_VERTICAL_MPS, WALK_OUT_S

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FloorConfig:
    """Floor height (m), hysteresis (fraction of a floor), smoothing and drift time constants (s), the vertical
    speed (m/s) below which the altitude has settled on a floor (an elevator moves at 0.3-2 m/s, a walker on stairs
    at about 0.3 m/s), the specific-force standard deviation (m/s^2) above which the user walks, and the site's
    per-floor altitudes ``altitudes_m``: ``(floor, altitude m)`` pairs (empty: every floor ``floor_height_m`` apart).
    ``learn_height``: learn the floor height from the first climb walked when the height is the default
    (module doc), with the time (s) a level holds and the range (m) of floor-to-floor heights.
    """

    floor_height_m: float = 4.0
    hysteresis: float = 0.6
    smooth_s: float = 1.0
    drift_tau_s: float = 120.0
    settle_mps: float = 0.2
    walking_acc_std_mps2: float = 1.0
    altitudes_m: tuple[tuple[float, float], ...] = ()
    learn_height: bool = True
    level_hold_s: float = 5.0
    floor_height_range_m: tuple[float, float] = (2.5, 5.0)

    def __post_init__(self) -> None:
        if not self.floor_height_m > 0:
            raise InputError("floor height must be positive", field="floor_height_m", source="floor config")
        try:
            alts = tuple(sorted((float(f), float(a)) for f, a in self.altitudes_m))
        except (TypeError, ValueError):
            raise InputError("altitudes_m must be [floor, altitude_m] pairs", field="altitudes_m",
                             source="floor config") from None
        if any(b[0] == a[0] or not b[1] > a[1] for a, b in zip(alts, alts[1:], strict=False)):
            raise InputError("floor altitudes must rise with the floor number, one altitude per floor",
                             field="altitudes_m", source="floor config")
        object.__setattr__(self, "altitudes_m", alts)
        lo, hi = (float(x) for x in self.floor_height_range_m)
        if not 0 < lo < hi:
            raise InputError("floor_height_range_m must be [low, high] with 0 < low < high",
                             field="floor_height_range_m", source="floor config")
        object.__setattr__(self, "floor_height_range_m", (lo, hi))

    def assumes_default_height(self) -> bool:
        """True when neither floor altitudes nor another floor height than the default were given."""
        return not self.altitudes_m and self.floor_height_m == FloorConfig.floor_height_m

    def learns_height(self) -> bool:
        """True when the floor height is learnt from the climbs walked (module doc)."""
        return self.learn_height and self.assumes_default_height()

    def altitude_m(self, floor: float) -> float:
        """Altitude of ``floor`` (m): the site's, else continued from the nearest listed floor by the floor height."""
        if not self.altitudes_m:
            return floor * self.floor_height_m
        f0, a0 = min(self.altitudes_m, key=lambda fa: abs(fa[0] - floor))
        return a0 + (floor - f0) * self.floor_height_m

    def levels(self, floor0: float) -> FloatArray:
        """Level (m) of floors ``floor0 + n`` above ``floor0``'s for ``n = -LEVEL_SPAN .. LEVEL_SPAN``."""
        n = np.arange(-LEVEL_SPAN, LEVEL_SPAN + 1)
        return np.array([self.altitude_m(floor0 + k) for k in n]) - self.altitude_m(floor0)


#: Floors tracked above and below the start floor.
LEVEL_SPAN = 100


@dataclass(frozen=True)
class FloorSamples:
    """Per sample: the smoothed altitude above the start ``up_m`` (m), the floor, whether the altitude is still
    moving (``moving``: its low-passed rate ``rate_mps`` (m/s, up positive) at ``settle_mps`` or more) and whether
    the user walks (``walking``: the specific-force magnitude varies as in walking, or there is no accelerometer;
    module doc).
    """

    up_m: FloatArray
    floor: FloatArray
    moving: NDArray[np.bool_]
    walking: NDArray[np.bool_]
    rate_mps: FloatArray
    #: Whether the floor numbers still assume the default floor height (no site, none learnt yet).
    height_assumed: NDArray[np.bool_]


class FloorTracker:
    """Online floor estimate from pressure samples on a uniform grid."""

    def __init__(self, rate_hz: float, config: FloorConfig | None = None, floor0: float = 0.0) -> None:
        self.rate_hz = float(rate_hz)
        self.config = config or FloorConfig()
        self.floor0 = float(floor0)
        self.alt = math.nan          # smoothed altitude (m)
        self.ref = math.nan          # altitude of floor0 (m)
        self.n = 0                   # floors above floor0 by altitude
        self.shown = 0               # floors above floor0 output: n once the altitude settled
        self.v = 0.0                 # low-passed vertical speed (m/s)
        self.acc_mean = math.nan     # low-passed specific-force magnitude (m/s^2)
        self.acc_var = 0.0           # its low-passed variance (m^2/s^4)
        self.level_up = math.nan     # altitude above the reference of the last level (m; learning the height)
        self.held = 0                # samples settled in a row
        self.walked = 0              # moving samples walked since that level
        self.ridden = 0              # moving samples not walked since that level
        self.peak_mps = 0.0          # largest low-passed vertical speed of those samples (m/s)
        self.walked_out = 0          # samples walked since the last one climbed standing
        self.learnt_height_m = math.nan   # floor height learnt from a flight (m; NaN: not learnt)
        self.levels = self.config.levels(self.floor0)

    @property
    def floor_height_m(self) -> float:
        """The floor height in use (m): the learnt one, else the configured one."""
        return self.config.floor_height_m if math.isnan(self.learnt_height_m) else self.learnt_height_m

    def _set_levels(self) -> None:
        """The floors' levels: the configured ones, or every learnt height apart (as the kernel rewrites them)."""
        if math.isnan(self.learnt_height_m):
            self.levels = self.config.levels(self.floor0)
        else:
            self.levels = np.arange(-LEVEL_SPAN, LEVEL_SPAN + 1, dtype=np.float64) * self.learnt_height_m

    def track(self, p_hpa: FloatArray, flat: FloatArray, acc_norm: FloatArray | None = None) -> FloorSamples:
        """Smoothed altitude above the start (m), floor and whether the altitude moves, per sample; ``flat`` (bool)
        allows re-anchoring; ``acc_norm``: the specific-force magnitude (m/s^2) on the same samples (None: the user is
        taken as walking, the floor changes as soon as it is passed).
        """
        a = np.full(len(p_hpa), np.nan) if acc_norm is None else np.asarray(acc_norm, dtype=np.float64)
        h = pressure_to_altitude_m(np.asarray(p_hpa, dtype=np.float64))
        c = self.config
        ks = 1.0 / (1.0 + c.smooth_s * self.rate_hz)
        kd = 1.0 / (1.0 + c.drift_tau_s * self.rate_hz)
        up = np.empty(h.size)
        fl = np.empty(h.size)
        moving = np.empty(h.size, dtype=np.bool_)
        walking = np.empty(h.size, dtype=np.bool_)
        rate = np.empty(h.size)
        assumed = np.empty(h.size, dtype=np.bool_)
        st = np.array([self.alt, self.ref, self.v, self.acc_mean, self.acc_var, self.level_up, self.learnt_height_m,
                       self.peak_mps])
        counts = np.array([self.n, self.shown, self.held, self.walked, self.ridden, self.walked_out], dtype=np.int64)
        learn = c.learns_height()          # the kernel stops learning once a height is learnt
        _track_floors(h, a, np.asarray(flat, dtype=np.bool_), ks, kd, self.levels, c.hysteresis, c.settle_mps,
                      c.walking_acc_std_mps2 ** 2, self.rate_hz, self.floor0, learn,
                      max(1, int(round(c.level_hold_s * self.rate_hz))), c.floor_height_range_m[0],
                      c.floor_height_range_m[1], ESCALATOR_MAX_VERTICAL_MPS, int(round(WALK_OUT_S * self.rate_hz)),
                      c.assumes_default_height(), st, counts, up, fl, moving, walking, rate, assumed)
        (self.alt, self.ref, self.v, self.acc_mean, self.acc_var, self.level_up, self.learnt_height_m,
         self.peak_mps) = (float(x) for x in st)
        self.n, self.shown, self.held, self.walked, self.ridden, self.walked_out = (int(x) for x in counts)
        return FloorSamples(up, fl, moving, walking, rate, assumed)

    def floors_between(self, up0_m: float, up1_m: float) -> int:
        """Floors between the levels nearest two altitudes above the start (m, as :meth:`track` gives them)."""
        return abs(int(np.argmin(np.abs(self.levels - up1_m))) - int(np.argmin(np.abs(self.levels - up0_m))))

    def state(self) -> dict[str, Any]:
        return {"rate_hz": self.rate_hz, "config": asdict(self.config), "floor0": self.floor0, "alt": self.alt,
                "ref": self.ref, "n": self.n, "v": self.v, "shown": self.shown, "acc_mean": self.acc_mean,
                "acc_var": self.acc_var, "level_up": self.level_up, "held": self.held, "walked": self.walked,
                "ridden": self.ridden, "learnt_height_m": self.learnt_height_m, "peak_mps": self.peak_mps,
                "walked_out": self.walked_out}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> FloorTracker:
        try:
            t = cls(float(d["rate_hz"]), FloorConfig(**d["config"]), float(d["floor0"]))
            t.alt, t.ref, t.n = float(d["alt"]), float(d["ref"]), int(d["n"])
            # States saved before the settling rule showed n at once.
            t.v, t.shown = float(d.get("v", 0.0)), int(d.get("shown", t.n))
            t.acc_mean, t.acc_var = float(d.get("acc_mean", math.nan)), float(d.get("acc_var", 0.0))
            # States saved before the floor height was learnt have no level yet.
            t.level_up = float(d.get("level_up", math.nan))
            t.learnt_height_m = float(d.get("learnt_height_m", math.nan))
            t.held, t.walked, t.ridden = int(d.get("held", 0)), int(d.get("walked", 0)), int(d.get("ridden", 0))
            # States saved before rides counted: no climb's peak speed, no walk out.
            t.peak_mps, t.walked_out = float(d.get("peak_mps", 0.0)), int(d.get("walked_out", 0))
            t._set_levels()
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad floor state ({exc})", source="floor state") from None
        return t


@kernel
def whole_floors(climb_m: float, min_h: float, max_h: float) -> int:
    """The number of floors a climb of ``climb_m`` (m) between two levels spans when exactly one whole number of
    floors, each ``min_h`` to ``max_h`` m high, fits it; 0 when none or several do (a 2.5-5 m floor: 1 floor up to
    5 m, 2 floors from 5 to 7.5 m, then 2 or 3).
    """
    fewest, most = math.ceil(climb_m / max_h), math.floor(climb_m / min_h)
    return int(fewest) if fewest == most and fewest >= 1 else 0


@kernel
def _track_floors(h: FloatArray, acc: FloatArray, flat: NDArray[np.bool_], ks: float, kd: float, levels: FloatArray,
                  hysteresis: float, settle_mps: float, walking_var: float, rate_hz: float, floor0: float,
                  learn: bool, hold_n: int, min_h: float, max_h: float, ride_min_v: float, walk_out_n: int,
                  default_height: bool, st: FloatArray,
                  counts: NDArray[np.int64], up: FloatArray, fl: FloatArray, moving: NDArray[np.bool_],
                  walks: NDArray[np.bool_], rate: FloatArray,
                  assumed: NDArray[np.bool_]) -> None:  # pragma: no cover - compiled
    """The per-sample loop of :meth:`FloorTracker.track` (module doc): altitudes ``h`` (m) in, the smoothed
    altitude above the reference ``up`` (m), the floor ``fl``, whether the altitude moves ``moving``, whether
    the user walks ``walks``, the low-passed vertical speed ``rate`` (m/s) and whether the floor numbers still
    assume the default height ``assumed`` (``default_height`` and none learnt) out; ``st``
    is the state ``(alt, ref, v, acc_mean, acc_var, level_up, learnt_height, peak_mps)`` and ``counts`` ``(n, shown,
    held, walked, ridden, walked_out)``, both updated in place. ``acc``: the specific-force magnitude (m/s^2; NaN:
    walking).
    ``levels[k]``: the level (m) of floor ``floor0 + k - (levels.size - 1) // 2`` (:meth:`FloorConfig.levels`),
    rewritten in place when the floor height is learnt (``learn``: a level holds ``hold_n`` samples, a floor's
    height is within ``[min_h, max_h]`` m, an elevator peaks above ``ride_min_v`` m/s and a level reached by a ride
    waits ``walk_out_n`` samples for the rider to walk out).
    """
    mid = (levels.size - 1) // 2
    alt, ref, v, am, av, level_up, learnt, peak = st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7]
    n, shown, held, walked, ridden, walked_out = counts[0], counts[1], counts[2], counts[3], counts[4], counts[5]
    for i in range(h.size):
        if math.isnan(alt):
            alt = ref = h[i]
        prev = alt
        alt += ks * (h[i] - alt)
        v += ks * ((alt - prev) * rate_hz - v)
        if math.isnan(am):
            am = acc[i]
        elif not math.isnan(acc[i]):
            am += ks * (acc[i] - am)
            av += ks * ((acc[i] - am) ** 2 - av)
        k = min(max(n + mid, 1), levels.size - 2)
        rel = alt - ref - levels[k]
        if rel > hysteresis * (levels[k + 1] - levels[k]):
            n += 1
        elif rel < -hysteresis * (levels[k] - levels[k - 1]):
            n -= 1
        elif flat[i]:
            ref += kd * rel
        settled = abs(v) < settle_mps
        walking = av > walking_var or math.isnan(acc[i])
        if settled or walking:   # settled, walking, no accelerometer
            shown = n
        moving[i] = not settled
        walks[i] = walking
        rate[i] = v
        up[i] = alt - ref
        if learn and math.isnan(learnt):
            held = held + 1 if settled else 0
            if not settled:
                peak = max(peak, abs(v))
                if walking:
                    walked += 1
                else:
                    ridden += 1
                    walked_out = 0
            if walking:
                walked_out += 1                         # walking since the last sample climbed standing
            if settled and held >= hold_n:
                # On a level. Its altitude is taken once it has held, not followed: the low-passed rate lags the
                # first second of a climb.
                d = abs(up[i] - level_up)
                if math.isnan(level_up):                # the first level
                    level_up, walked, ridden, peak, walked_out = up[i], 0, 0, 0.0, 0
                elif d < 0.5 * min_h:                   # the same level again: a new climb starts from it
                    walked, ridden, peak, walked_out = 0, 0, 0.0, 0
                elif d < min_h:                         # a ramp or half landing: the level the climb left is kept
                    pass
                else:
                    floors = whole_floors(d, min_h, max_h)
                    lift = peak > ride_min_v            # faster than an escalator climbs
                    if floors > 0 and (walked > ridden or (lift and walked_out > 0)):
                        # Stairs walked, or a lift walked out of, between floors a whole number apart
                        learnt = d / floors
                        for j in range(levels.size):
                            levels[j] = (j - mid) * learnt
                        n = int(round(up[i] / learnt))
                        shown = n
                    elif floors > 0 and lift and held < walk_out_n:
                        pass                            # a ride whose rider has not walked out yet
                    else:                               # a car's climb, or an ambiguous floor count: a new level
                        level_up, walked, ridden, peak, walked_out = up[i], 0, 0, 0.0, 0
        fl[i] = floor0 + shown
        assumed[i] = default_height and math.isnan(learnt)
    st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7] = alt, ref, v, am, av, level_up, learnt, peak
    counts[0], counts[1], counts[2], counts[3], counts[4], counts[5] = n, shown, held, walked, ridden, walked_out


#: Stairs steps in a row that make a flight: building codes ask for at least three risers per flight.
FLIGHT_MIN_STEPS = 3


class StairFlights:
    """Online stair flights from the track's steps: a run of at least ``min_steps`` consecutive steps labelled
    ``stairs_up`` (or all ``stairs_down``), closed by the first step of another mode or direction. Its height change is
    the barometric altitude (m, above the start) at its last step minus the altitude at the step before its first
    (the foot of the flight; the first step's own when the walk starts on the stairs). A flight still open when the
    walk ends is not reported.
    """

    def __init__(self, min_steps: int = FLIGHT_MIN_STEPS) -> None:
        self.min_steps = int(min_steps)
        self.direction: str | None = None     # "up"/"down" while on a run of stairs steps
        self.t0 = self.t1 = math.nan          # start of its first step, end of its last (s)
        self.up0 = self.up1 = math.nan        # altitude at its foot and at its last step (m)
        self.n = 0                            # its steps
        self.prev_up = math.nan               # altitude at the last step off the run (m)
        self.prev_floor = math.nan            # floor at the last step off the run
        self.floor0 = math.nan                # floor at the run's foot

    def step(self, t_start_s: float, t_s: float, mode: str, up_m: float, floor: float
             ) -> tuple[float, float, str, int, float, float, int] | None:
        """Take one step; returns the flight it closed, ``(t_start_s, t_end_s, direction, steps, up0_m, up1_m,
        floors)``.
        """
        direction = {"stairs_up": "up", "stairs_down": "down"}.get(mode)
        closed = None
        if direction != self.direction and self.direction is not None:
            if self.n >= self.min_steps:
                closed = (self.t0, self.t1, self.direction, self.n, self.up0, self.up1,
                          int(round(abs(float(floor) - self.floor0))))
            self.direction, self.n = None, 0
        if direction is None:
            self.prev_up, self.prev_floor = float(up_m), float(floor)
            return closed
        if self.direction is None:
            self.direction, self.t0, self.n = direction, float(t_start_s), 0
            self.up0 = self.prev_up if math.isfinite(self.prev_up) else float(up_m)
            self.floor0 = self.prev_floor if math.isfinite(self.prev_floor) else float(floor)
        self.n += 1
        self.t1, self.up1 = float(t_s), float(up_m)
        self.prev_up, self.prev_floor = float(up_m), float(floor)
        return closed

    def state(self) -> dict[str, Any]:
        return {"min_steps": self.min_steps, "direction": self.direction, "t0": self.t0, "t1": self.t1,
                "up0": self.up0, "up1": self.up1, "n": self.n, "prev_up": self.prev_up, "prev_floor": self.prev_floor,
                "floor0": self.floor0}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> StairFlights:
        try:
            f = cls(int(d["min_steps"]))
            f.direction = None if d["direction"] is None else str(d["direction"])
            f.t0, f.t1, f.up0, f.up1 = (float(d[k]) for k in ("t0", "t1", "up0", "up1"))
            f.n, f.prev_up, f.prev_floor, f.floor0 = (int(d["n"]), float(d["prev_up"]), float(d["prev_floor"]),
                                                      float(d["floor0"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad stair flight state ({exc})", source="stair flight state") from None
        return f
