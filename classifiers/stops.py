"""Stops: stretches of at least ``MIN_STOP_S`` seconds with no step and a still device (labelled ``standing``).

The labelling rule, used for the modes timeline and for evaluation alike:

1. The accelerometer and gyroscope samples are cut into blocks of ``BLOCK_S`` seconds on a grid anchored at the
   first accelerometer sample. A block is *still* when the standard deviation of the specific-force norm is
   under ``STILL_ACC_STD_MPS2`` and the mean angular-rate norm under ``STILL_GYRO_RADPS`` (no gyroscope: the
   accelerometer alone decides). Why these values: a walking person's vertical acceleration swings by
   1-3 m/s^2 at the step frequency, whatever the carriage (hand-held IPIN walks: 0.8-1.5 m/s^2 per block),
   while a phone held by someone standing shows hand tremor and sway only (0.1-0.35 m/s^2); a phone being
   turned over or put away rotates faster than ~30 deg/s.
2. Runs of still blocks, bridging moving spells of up to ``BRIDGE_S`` (a hand adjusting the phone, the jerk of
   an elevator cabin), are cut by every step interval ``[t_start_s, t_s]`` of the step detector and
   by every other activity given as a busy interval (an elevator ride is its own mode, not a stop).
3. What remains of a run that lasts at least ``MIN_STOP_S`` is a stop.

:class:`StopDetector` applies the rule online, batch by batch (cost proportional to the batch, JSON-able
state): a closed stop is reported once the step detector has reported steps up to its end (its events lag the
samples), or when the session ends; :meth:`StopDetector.pending` gives what the session's end would add now.
:func:`stop_intervals` is the offline pass over a whole recording.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.phone.steps import detect_steps
from pdr.preprocess import resample
from pdr.recording import Recording

FloatArray = NDArray[np.float64]

#: Block length (s) of the stillness test.
BLOCK_S = 0.5
#: Standard deviation of the specific-force norm (m/s^2) under which a block is still.
STILL_ACC_STD_MPS2 = 0.4
#: Mean angular-rate norm (rad/s, ~30 deg/s) under which a block is still.
STILL_GYRO_RADPS = 0.5
#: Longest spell (s) of moving blocks without a step inside one stop.
BRIDGE_S = 1.0
#: Shortest stop (s) reported as its own timeline entry.
MIN_STOP_S = 2.0
#: Label of a stop in the modes timeline.
STOP_LABEL = "standing"

STATE_VERSION = 1


@dataclass(frozen=True)
class Stop:
    """A stop: ``[t_start_s, t_end_s]`` in seconds on the log's clock."""

    t_start_s: float
    t_end_s: float

    @property
    def duration_s(self) -> float:
        return self.t_end_s - self.t_start_s


def subtract(intervals: Sequence[tuple[float, float]], cut: tuple[float, float]) -> list[tuple[float, float]]:
    """The parts of ``intervals`` (s) outside ``cut`` (s), in order; empty parts dropped."""
    a, b = cut
    out: list[tuple[float, float]] = []
    for lo, hi in intervals:
        if b <= lo or a >= hi:
            out.append((lo, hi))
            continue
        if a > lo:
            out.append((lo, a))
        if b < hi:
            out.append((b, hi))
    return out


class StopDetector:
    """Online stop detection (module docstring).

    Parameters
    ----------
    block_s, still_acc_std_mps2, still_gyro_radps, min_stop_s
        The rule's constants (defaults: the module's).

    Call :meth:`update` with each sensor batch and the step (and busy) intervals the step detector reported
    for it, in time order; it returns the stops that are final. :meth:`finish` returns the rest.
    """

    def __init__(self, block_s: float = BLOCK_S, still_acc_std_mps2: float = STILL_ACC_STD_MPS2,
                 still_gyro_radps: float = STILL_GYRO_RADPS, min_stop_s: float = MIN_STOP_S) -> None:
        if not (block_s > 0 and min_stop_s >= block_s and still_acc_std_mps2 > 0 and still_gyro_radps > 0):
            raise InputError("stop rule: block_s, thresholds must be positive and min_stop_s >= block_s",
                             field="stops")
        self.block_s = float(block_s)
        self.still_acc_std_mps2 = float(still_acc_std_mps2)
        self.still_gyro_radps = float(still_gyro_radps)
        self.min_stop_s = float(min_stop_s)
        self.t0_s: float | None = None
        self.block = 0                       # index of the block being accumulated
        self.acc = [0.0, 0.0, 0.0]           # count, sum and sum of squares of |f| (m/s^2) in that block
        self.gyro = [0.0, 0.0]               # count and sum of |w| (rad/s) in that block
        self.open_start: float | None = None  # start (s) of the run of still blocks in progress
        self.moving_since: float | None = None  # start (s) of the moving spell inside that run
        self.closed: list[tuple[float, float]] = []  # runs ended by a moving block, not yet reported
        self.steps_until = -math.inf          # end (s) of the latest step reported

    # ------------------------------------------------------------------ input
    def update(self, batch: Recording, busy: Iterable[tuple[float, float]] = ()) -> list[Stop]:
        """Add a batch (log clock) and the step/busy intervals (s) reported with it; returns final stops."""
        if batch.has("acc") and len(batch.stream("acc")):
            self._blocks(batch)
        self.add_busy(busy)
        return self._report(final=False)

    def finish(self) -> list[Stop]:
        """End of the session: every remaining stop, the run in progress included (up to the last block)."""
        if self.t0_s is not None and self.acc[0] > 0:  # the last, partial block
            self._close_block(self.block, *self.acc, *self.gyro)
            self.block += 1
            self.acc, self.gyro = [0.0, 0.0, 0.0], [0.0, 0.0]
        if self.open_start is not None and self.t0_s is not None:
            end = self.moving_since if self.moving_since is not None else self.t0_s + self.block * self.block_s
            self.closed.append((self.open_start, end))
            self.open_start = self.moving_since = None
        return self._report(final=True)

    def pending(self) -> list[Stop]:
        """What :meth:`finish` would add if the session ended now (the detector is not changed)."""
        copy = StopDetector.from_state(self.state())
        return copy.finish()

    def _blocks(self, batch: Recording) -> None:
        t_a = batch.t_s("acc")
        a = np.linalg.norm(batch.values("acc"), axis=1)
        if self.t0_s is None:
            self.t0_s = float(t_a[0])
        t0 = self.t0_s
        g_t = batch.t_s("gyro") if batch.has("gyro") else np.zeros(0)
        g = np.linalg.norm(batch.values("gyro"), axis=1) if batch.has("gyro") else np.zeros(0)
        idx_a = np.floor((t_a - t0) / self.block_s).astype(np.int64)
        idx_g = np.floor((g_t - t0) / self.block_s).astype(np.int64)
        keep_a, keep_g = idx_a >= self.block, idx_g >= self.block  # re-sent samples of closed blocks dropped
        idx_a, a, idx_g, g = idx_a[keep_a], a[keep_a], idx_g[keep_g], g[keep_g]
        if idx_a.size == 0:
            return
        last = int(idx_a[-1])  # the block of the newest sample stays open (more samples may come)
        n_blocks = last - self.block + 1
        rel_a, rel_g = idx_a - self.block, idx_g - self.block
        cnt = np.bincount(rel_a, minlength=n_blocks).astype(np.float64)
        s1 = np.bincount(rel_a, a, minlength=n_blocks)
        s2 = np.bincount(rel_a, a * a, minlength=n_blocks)
        inside = rel_g < n_blocks
        gcnt = np.bincount(rel_g[inside], minlength=n_blocks).astype(np.float64)
        gs = np.bincount(rel_g[inside], g[inside], minlength=n_blocks)
        cnt[0] += self.acc[0]
        s1[0] += self.acc[1]
        s2[0] += self.acc[2]
        gcnt[0] += self.gyro[0]
        gs[0] += self.gyro[1]
        for k in range(n_blocks - 1):
            self._close_block(self.block + k, cnt[k], s1[k], s2[k], gcnt[k], gs[k])
        self.block = last
        self.acc = [float(cnt[-1]), float(s1[-1]), float(s2[-1])]
        self.gyro = [float(gcnt[-1]), float(gs[-1])]

    def _close_block(self, k: int, n: float, s1: float, s2: float, gn: float, gs: float) -> None:
        assert self.t0_s is not None
        start = self.t0_s + k * self.block_s
        still = False
        if n >= 3:
            mean = s1 / n
            std = math.sqrt(max(s2 / n - mean * mean, 0.0))
            still = std < self.still_acc_std_mps2 and (gn == 0 or gs / gn < self.still_gyro_radps)
        if still:
            if self.open_start is None:
                self.open_start = start
            self.moving_since = None
        elif self.open_start is not None:
            if self.moving_since is None:
                self.moving_since = start
            if start + self.block_s - self.moving_since > BRIDGE_S:
                if self.moving_since > self.open_start:
                    self.closed.append((self.open_start, self.moving_since))
                self.open_start = self.moving_since = None

    def add_busy(self, busy: Iterable[tuple[float, float]]) -> None:
        """Cut the runs by step/busy intervals ``(t_start_s, t_end_s)``; steps are known up to the latest end."""
        for a, b in busy:
            a, b = float(a), float(b)
            if not b >= a:
                raise InputError(f"busy interval ends ({b}) before it starts ({a})", field="steps")
            self.closed = subtract(self.closed, (a, b))
            if self.open_start is not None and a < self.open_start < b:
                self.open_start = b
            elif self.open_start is not None and self.open_start <= a:
                end = a if self.moving_since is None else min(a, self.moving_since)
                self.closed.append((self.open_start, end))
                self.open_start = b
                self.moving_since = None
            self.steps_until = max(self.steps_until, b)
        self.closed.sort()

    def _report(self, final: bool) -> list[Stop]:
        out: list[Stop] = []
        keep: list[tuple[float, float]] = []
        for a, b in self.closed:
            if final or b <= self.steps_until:
                if b - a >= self.min_stop_s:
                    out.append(Stop(a, b))
            else:
                keep.append((a, b))
        self.closed = keep
        return out

    # ------------------------------------------------------------------ state
    def state(self) -> dict[str, Any]:
        """JSON-able state for :meth:`from_state`."""
        return {"version": STATE_VERSION, "block_s": self.block_s, "still_acc_std_mps2": self.still_acc_std_mps2,
                "still_gyro_radps": self.still_gyro_radps, "min_stop_s": self.min_stop_s, "t0_s": self.t0_s,
                "block": self.block, "acc": list(self.acc), "gyro": list(self.gyro), "open_start": self.open_start,
                "moving_since": self.moving_since,
                "closed": [list(c) for c in self.closed],
                "steps_until": None if math.isinf(self.steps_until) else self.steps_until}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> StopDetector:
        """Resume from :meth:`state`."""
        try:
            if state["version"] != STATE_VERSION:
                raise InputError(f"stop detector state version {state['version']} is not {STATE_VERSION}",
                                 field="version")
            d = cls(state["block_s"], state["still_acc_std_mps2"], state["still_gyro_radps"], state["min_stop_s"])
            d.t0_s = None if state["t0_s"] is None else float(state["t0_s"])
            d.block = int(state["block"])
            d.acc = [float(x) for x in state["acc"]]
            d.gyro = [float(x) for x in state["gyro"]]
            d.open_start = None if state["open_start"] is None else float(state["open_start"])
            d.moving_since = None if state["moving_since"] is None else float(state["moving_since"])
            d.closed = [(float(a), float(b)) for a, b in state["closed"]]
            d.steps_until = -math.inf if state["steps_until"] is None else float(state["steps_until"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not a stop detector state ({exc})", field="state") from None
        return d


def stop_intervals(rec: Recording, steps: Iterable[tuple[float, float]]) -> list[Stop]:
    """Offline: the stops of a whole recording given its step (and busy) intervals in seconds."""
    det = StopDetector()
    return det.update(rec, list(steps)) + det.finish()


#: Rate (Hz) the accelerometer is resampled to for :func:`step_intervals`.
STEP_RATE_HZ = 50.0


def step_intervals(rec: Recording) -> list[tuple[float, float]]:
    """Step intervals ``(t_start_s, t_end_s)`` of the step detector (:func:`pdr.phone.steps.detect_steps`) on the
    recording's accelerometer resampled to ``STEP_RATE_HZ`` (offline; the service uses its pipeline's steps).
    """
    out: list[tuple[float, float]] = []
    for seg in resample(rec, STEP_RATE_HZ, ["acc"]):
        st = detect_steps(seg.data["acc"], STEP_RATE_HZ)
        t = seg.t_s
        for a, b in zip(st.start_idx, st.end_idx, strict=True):
            out.append((float(t[min(int(a), t.size - 1)]), float(t[min(int(b), t.size) - 1])))
    return out
