"""Elevator or escalator: what carried a person who stood still while their floor changed.

A stop (:mod:`classifiers.stops`) during which the floor changes is a ride. Its barometric altitude profile
(:class:`RideProfile`) tells the carrier:

* the *cruise vertical speed*: the time the altitude takes to go from 10 % to 90 % of the ride's change, over 80 %
  of that change (crossing times of block means, so pressure noise does not inflate it as a peak of the derivative
  would). An escalator's rated speed along its incline is at most 0.75 m/s at 30 deg (EN 115-1), a vertical speed
  of at most ``ESCALATOR_MAX_VERTICAL_MPS`` (0.25 m/s for the common 0.5 m/s); a passenger elevator cruises at
  0.4 m/s (a slow low-rise lift, such as the IPIN museum's) to several m/s;
* the *tail*: the time from the end of the climb to the end of the stop (the rider's first step), the climb's
  end being where the cruise line through the 90 % crossing reaches the final altitude. An elevator's doors open
  only once the cabin has stopped, and the rider then walks out: seconds of still altitude; an escalator rider
  must step off the belt once it levels out at the exit landing (at most 1.6 m of flat travel at 0.75 m/s,
  EN 115-1), so the tail is at most ``ESCALATOR_MAX_TAIL_S``.

A ride is an escalator when both hold (speed at most an escalator's, tail at most an exit landing's); otherwise
an elevator. The lead (altitude still after the stop began) is not used: a person may wait before either.
A hydraulic lift slower than an escalator whose doors open at once would be misnamed an escalator.

:class:`AltitudeRecord` keeps the barometric altitude of a session's recent past in ``BLOCK_S`` blocks (online,
batch by batch, JSON-able state) so that the ride's profile can be read once the stop is reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.frames import pressure_to_altitude_m
from pdr.phone.baro_rides import ESCALATOR_MAX_VERTICAL_MPS
from pdr.recording import Recording

#: Longest time (s) from the end of the climb to the first step off an escalator: its exit landing's flat travel
#: (1.6 m at most) at 0.75 m/s, plus the stop rule's block (0.5 s).
ESCALATOR_MAX_TAIL_S = 1.6 / 0.75 + 0.5
#: Block length (s) of the altitude record.
BLOCK_S = 1.0
#: Seconds of altitude kept (a ride is reported a few seconds after it ends; rides last under a few minutes).
KEEP_S = 300.0
#: Fractions of the altitude change between which the cruise speed is measured.
LOW, HIGH = 0.1, 0.9
#: Seconds at each end of the interval whose mean altitude is the ride's start and end altitude.
END_S = 2.0

STATE_VERSION = 1


@dataclass(frozen=True)
class RideProfile:
    """A ride's cruise vertical speed (m/s, unsigned) and tail (s) (module docstring)."""

    vertical_speed_mps: float
    tail_s: float


class AltitudeRecord:
    """Barometric altitude (m, standard atmosphere) of the last ``KEEP_S`` seconds in ``BLOCK_S`` block means."""

    def __init__(self) -> None:
        self.t0_s: float | None = None
        self.first = 0                        # index of the first kept block
        self.sums: list[list[float]] = []     # per kept block: [count, sum of altitudes]

    def update(self, batch: Recording) -> None:
        """Add the batch's pressure samples (none: nothing to add)."""
        if not batch.has("baro") or not len(batch.stream("baro")):
            return
        t = batch.t_s("baro")
        h = pressure_to_altitude_m(batch.values("baro")[:, 0])
        if self.t0_s is None:
            self.t0_s = float(t[0])
        idx = np.floor((t - self.t0_s) / BLOCK_S).astype(np.int64) - self.first
        keep = idx >= 0
        idx, h = idx[keep], h[keep]
        if idx.size == 0:
            return
        n = int(idx.max()) + 1
        cnt = np.bincount(idx, minlength=n)
        s = np.bincount(idx, h, minlength=n)
        while len(self.sums) < n:
            self.sums.append([0.0, 0.0])
        for k in np.flatnonzero(cnt):
            self.sums[k][0] += float(cnt[k])
            self.sums[k][1] += float(s[k])
        drop = max(0, len(self.sums) - int(KEEP_S / BLOCK_S))
        if drop:
            self.sums = self.sums[drop:]
            self.first += drop

    def series(self, t0_s: float, t1_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Block centre times (s) and mean altitudes (m) of the kept blocks inside ``[t0_s, t1_s]``."""
        if self.t0_s is None:
            return np.zeros(0), np.zeros(0)
        t = self.t0_s + (self.first + np.arange(len(self.sums)) + 0.5) * BLOCK_S
        c = np.array([b[0] for b in self.sums])
        h = np.array([b[1] for b in self.sums]) / np.maximum(c, 1.0)
        m = (c > 0) & (t >= t0_s) & (t <= t1_s)
        return t[m], h[m]

    def profile(self, t0_s: float, t1_s: float) -> RideProfile | None:
        """Cruise vertical speed and tail of the altitude change over ``[t0_s, t1_s]`` (module docstring); None
        when the record does not cover the interval's ends or the altitude does not change.
        """
        t, h = self.series(t0_s, t1_s)
        if t.size < 4 or t[0] > t0_s + END_S or t[-1] < t1_s - END_S:
            return None
        h0 = float(h[t <= t[0] + END_S].mean())
        h1 = float(h[t >= t[-1] - END_S].mean())
        dh = h1 - h0
        if dh == 0:
            return None
        frac = (h - h0) / dh
        lo, hi = np.flatnonzero(frac >= LOW), np.flatnonzero(frac >= HIGH)
        if lo.size == 0 or hi.size == 0:
            return None
        ta, tb = _crossing(t, frac, int(lo[0]), LOW), _crossing(t, frac, int(hi[0]), HIGH)
        speed = abs((HIGH - LOW) * dh) / max(tb - ta, BLOCK_S)
        return RideProfile(speed, max(0.0, t1_s - (tb + (1.0 - HIGH) * abs(dh) / speed)))

    def state(self) -> dict[str, Any]:
        return {"version": STATE_VERSION, "t0_s": self.t0_s, "first": self.first,
                "sums": [list(b) for b in self.sums]}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> AltitudeRecord:
        try:
            if state["version"] != STATE_VERSION:
                raise InputError(f"altitude record state version {state['version']} is not {STATE_VERSION}",
                                 field="version")
            r = cls()
            r.t0_s = None if state["t0_s"] is None else float(state["t0_s"])
            r.first = int(state["first"])
            r.sums = [[float(a), float(b)] for a, b in state["sums"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not an altitude record state ({exc})", field="state") from None
        return r


def _crossing(t: np.ndarray, frac: np.ndarray, i: int, level: float) -> float:
    """Time (s) at which ``frac`` reaches ``level`` between samples ``i - 1`` and ``i`` (linear)."""
    if i == 0 or frac[i] == frac[i - 1]:
        return float(t[i])
    w = (level - frac[i - 1]) / (frac[i] - frac[i - 1])
    return float(t[i - 1] + w * (t[i] - t[i - 1]))


def ride_kind(profile: RideProfile | None) -> str:
    """``escalator`` when the ride's profile is an escalator's (module docstring), else ``elevator`` (also when it
    is unknown: a stop with a floor change and no record of its altitude is most often a lift).
    """
    if (profile is not None and profile.vertical_speed_mps <= ESCALATOR_MAX_VERTICAL_MPS
            and profile.tail_s <= ESCALATOR_MAX_TAIL_S):
        return "escalator"
    return "elevator"
