"""Strides of one foot from its zero-velocity flags: a stride is a swing, a motion long enough to be one, that ends
when the foot comes to rest (:func:`swing_onsets`).

The zero-velocity detectors break a stance into pieces: at 200 Hz the foot rolls or shifts for 0.02-0.26 s between
still stretches of one stance, and counting every return to rest overcounts (:data:`MIN_SWING_S`). The step-wise
navigation's resets (seed 001 Algorithm 1) are not strides either: while the foot stands, a reset falls every
``c_max_s`` (:class:`pdr.foot.zupt.Segmentation`); :class:`SwingsSinceReset` tells the resets that close a stride
from those that close a stand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Shortest swing (s) of a stride: a foot's swing phase lasts about 40 % of a gait cycle of 0.8 s or more when
#: walking, and longer when running, so a return to rest after a shorter motion is the foot rolling or shifting within
#: one stance. Measured on the stride-indexed walks of ``foot_stride_gcp/LLIO_training_data``: every raw return to
#: rest counts 249 strides too many over 26 walks (0 of 26 right); 0.2-0.35 s gives the 20 PyShoe trials exactly, on
#: which it was chosen, and 0.3 s also the 6 SensorConnect walks (0.2 s: 5 of 6).
MIN_SWING_S = 0.3


def swing_onsets(zero_velocity: ArrayLike, t_s: ArrayLike, still_s: float,
                 min_swing_s: float = MIN_SWING_S) -> tuple[NDArray[np.int64], float]:
    """Samples ``j >= 1`` where the foot comes to rest after a swing: ``zero_velocity[j]`` (N,) true after false
    ones that lasted ``min_swing_s`` (s) or more, from the last still sample before them to ``j`` (times ``t_s``
    (N,), s). ``still_s``: the time (s) of the last still sample before sample 0, for a motion under way at sample 0
    (NaN: none known; such a motion counts no swing). Returns the onsets and the time of the last still sample
    before the last sample's motion (``still_s`` carried when no motion starts here), for the next samples.
    """
    zv = np.asarray(zero_velocity, dtype=bool)
    t = np.asarray(t_s, dtype=np.float64)
    onsets = np.flatnonzero(zv[1:] & ~zv[:-1]) + 1
    starts = np.flatnonzero(zv[:-1] & ~zv[1:]) + 1            # first moving sample of each motion
    before = np.searchsorted(starts, onsets) - 1              # the motion each onset ends (-1: under way at 0)
    still = np.concatenate([[still_s], t[starts - 1]])        # last still sample before each motion
    since = still[before + 1]
    with np.errstate(invalid="ignore"):
        swung = t[onsets] - since >= min_swing_s
    return onsets[swung].astype(np.int64), float(t[starts[-1] - 1]) if starts.size else still_s


def stance_onsets(zero_velocity: ArrayLike, t_s: ArrayLike, min_swing_s: float = MIN_SWING_S) -> NDArray[np.int64]:
    """Indices where a foot comes to rest after a swing (:func:`swing_onsets`) in a whole record: a motion under way
    at its start counts from its first sample; a record that starts at rest does not count its first stance. One
    per stride of that foot.
    """
    t = np.asarray(t_s, dtype=np.float64)
    return swing_onsets(zero_velocity, t, float(t[0]) if t.size else math.nan, min_swing_s)[0]


@dataclass
class SwingsSinceReset:
    """Online: whether each reset of the step-wise navigation closes a stride (a swing ended since the reset before
    it) or a stand. State: the last still sample's time (s, NaN: none yet), whether a swing ended since the last
    reset, and the last sample's flag (None before the first call).
    """

    still_s: float = math.nan
    swung: bool = False
    last_zv: bool | None = None

    def update(self, zero_velocity: ArrayLike, t_s: ArrayLike, resets: ArrayLike) -> list[bool]:
        """Samples ``1..N-1`` of ``zero_velocity``, ``t_s`` (N,) are new, sample 0 the last one of the previous
        call (its flag is taken from there: only the first call's is used as given); ``resets`` (indices >= 1,
        increasing) the resets among them. One flag per reset: a swing ended at a sample after the previous reset
        and at or before this one.
        """
        zv = np.array(zero_velocity, dtype=bool)
        if self.last_zv is not None and zv.size:
            zv[0] = self.last_zv
        onsets, self.still_s = swing_onsets(zv, t_s, self.still_s)
        if zv.size:
            self.last_zv = bool(zv[-1])
        out = []
        prev = 0
        for r in np.asarray(resets, dtype=np.int64).tolist():
            out.append(self.swung or bool(np.any((onsets > prev) & (onsets <= r))))
            self.swung, prev = False, r
        self.swung = self.swung or bool(np.any(onsets > prev))
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state (NaN as None)."""
        return {"still_s": None if math.isnan(self.still_s) else self.still_s, "swung": self.swung,
                "last_zv": self.last_zv}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SwingsSinceReset:
        """The tracker :meth:`to_dict` saved."""
        still, last = d["still_s"], d["last_zv"]
        return cls(math.nan if still is None else float(still), bool(d["swung"]), None if last is None else bool(last))


def reset_strides(zero_velocity: ArrayLike, t_s: ArrayLike, start: int,
                  resets: ArrayLike) -> tuple[list[bool], bool]:
    """Whole track: whether each reset (sample indices ``resets``, increasing, after ``start``) closes a stride,
    as :class:`pdr.foot.online.OnlineFootNavigator` flags them online, and whether a stride ended after the last
    reset (the recording's end closes it). ``zero_velocity``, ``t_s`` (N,): the track's flags and times (s);
    ``start``: the sample navigation starts from (the end of the initial rest).
    """
    swings = SwingsSinceReset()
    flags = swings.update(np.asarray(zero_velocity, dtype=bool)[start:], np.asarray(t_s, dtype=np.float64)[start:],
                          np.asarray(resets, dtype=np.int64) - start)
    return flags, swings.swung
