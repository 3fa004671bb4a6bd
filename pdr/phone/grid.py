"""Online resampling of several sensor streams onto one uniform grid, batch by batch.

The grid is ``t_k = k / rate_hz`` seconds on the log's own clock (``k`` integer, the convention of
:mod:`pdr.preprocess`), so every batch of a session lands on the same grid. A grid point is emitted once
every stream of the session has a sample at or after it; its value is the linear interpolation between
the two samples that bracket it. The result therefore does not depend on how the samples were split into
batches. :meth:`OnlineGrid.flush` ends the session: the remaining grid points up to the last sample of
the primary stream (the accelerometer) are emitted, and a stream that ended shortly before holds its last value.

A stream that stops while the accelerometer goes on (an app that pauses its magnetometer or barometer, a phone
that stops sending one sensor) does not stall the session, and is not held at a stale value. Two samples more than
:data:`MAX_STREAM_GAP_S` apart are not bridged: the grid points between them are emitted without that stream, as
if the session had none there (:meth:`OnlineGrid.pull` gives the points in runs over which the same streams are
present), and the consumers run without it (no gyroscope, no magnetometer, ...) until it resumes. A live session
waits for a stream at most twice that gap behind the accelerometer: the first half is the gap itself, the second
the slack allowed to a stream whose samples arrive in a later batch than the accelerometer's of the same time.
Within that slack the grid is the same whatever the batches; none of the shared recordings has a gap that long.

Unlike :func:`pdr.preprocess.resample` (zero-phase filtering for offline use) there is no anti-alias
filter: the consumers low-pass what they need (the step detector at a few Hz).

Quaternion streams (``orientation``) are made sign-continuous as they arrive
(:func:`pdr.phone.phone_orientation.sign_continuous`, against the last buffered sample), so their interpolation,
renormalised by the consumer, is the nlerp of the attitudes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.phone.phone_orientation import sign_continuous
from pdr.recording import Recording

#: Streams of quaternions (sign-continuous in the buffer).
QUATERNION_KINDS = ("orientation",)

#: Longest gap (s) between two samples of a stream that the grid bridges by interpolation: twice the period of the
#: slowest stream the pipeline takes (a barometer that reports once a second, as some phones' do only on change).
#: A longer gap is a stream that stopped (module doc).
MAX_STREAM_GAP_S = 2.0

FloatArray = NDArray[np.float64]


class OnlineGrid:
    """Uniform grid over the streams ``kinds`` (fixed at the first batch that has them; the first is the primary
    stream, present at every grid point), bridging gaps of at most ``max_gap_s`` seconds within a stream.
    """

    def __init__(self, rate_hz: float, kinds: tuple[str, ...], max_gap_s: float = MAX_STREAM_GAP_S) -> None:
        if not rate_hz > 0:
            raise InputError(f"grid rate must be positive, got {rate_hz}", field="rate_hz", source="grid")
        self.rate_hz = float(rate_hz)
        self.kinds = kinds
        self.max_gap_s = float(max_gap_s)
        self.buf_t: dict[str, FloatArray] = {k: np.zeros(0) for k in kinds}
        self.buf_v: dict[str, FloatArray] = {k: np.zeros((0, 0)) for k in kinds}
        self.next_k: int | None = None   # next grid index to emit
        self.first_k: int | None = None  # first grid index ever emitted

    def push(self, rec: Recording) -> None:
        """Append a batch's samples (times on the log clock, seconds)."""
        for k in self.kinds:
            if not rec.has(k):
                continue
            s = rec.stream(k)
            t = (s.t_ns.astype(np.float64) / 1e9)
            v = s.values
            bt = self.buf_t[k]
            if bt.size and t[0] <= bt[-1]:
                keep = t > bt[-1]
                t, v = t[keep], v[keep]
                if t.size == 0:
                    continue
            if k in QUATERNION_KINDS:
                v = sign_continuous(v, self.buf_v[k][-1] if self.buf_v[k].size else None)
            self.buf_t[k] = np.concatenate([bt, t])
            self.buf_v[k] = v.copy() if self.buf_v[k].size == 0 else np.concatenate([self.buf_v[k], v])

    def _present(self, kind: str, tg: FloatArray) -> NDArray[np.bool_]:
        """Whether ``kind`` has a value at the grid times ``tg`` (s): at one of its samples, between two samples at
        most ``max_gap_s`` apart, or after its last sample while the primary stream is at most that far ahead (held).
        """
        bt = self.buf_t[kind]
        i = np.searchsorted(bt, tg, side="right") - 1               # bt[i] <= t < bt[i + 1]; i >= 0 (buffer kept)
        nxt = bt[np.minimum(i + 1, bt.size - 1)]
        after_last = i == bt.size - 1
        held = float(self.buf_t[self.kinds[0]][-1]) - float(bt[-1]) <= self.max_gap_s
        return (tg == bt[i]) | np.where(after_last, held, nxt - bt[i] <= self.max_gap_s)

    def _emit(self, k_end: int) -> tuple[FloatArray, dict[str, FloatArray]]:
        """Grid points next_k .. k_end (inclusive), up to the first at which a stream starts or stops being present
        (:meth:`_present`); the values of the streams present over them.
        """
        assert self.next_k is not None
        if k_end < self.next_k:
            return np.zeros(0), {k: np.zeros((0, max(self.buf_v[k].shape[1], 1))) for k in self.kinds}
        tg = np.arange(self.next_k, k_end + 1) / self.rate_hz
        tg, present = self._leading_run(tg)
        out = {}
        for k in self.kinds:
            bt, bv = self.buf_t[k], self.buf_v[k]
            # The last sample at or before the last grid time: the buffer keeps it and everything after it.
            i = max(int(np.searchsorted(bt, tg[-1], side="right")) - 1, 0)
            if k not in present or present[k]:
                # The samples that bracket the run only (the same values): np.interp copies a strided column whole,
                # and a whole log pushed at once would be copied for every run.
                lo = max(int(np.searchsorted(bt, tg[0], side="right")) - 1, 0)
                out[k] = np.column_stack([np.interp(tg, bt[lo:i + 2], bv[lo:i + 2, j]) for j in range(bv.shape[1])])
            self.buf_t[k], self.buf_v[k] = bt[i:], bv[i:]
        self.next_k += tg.size
        return tg, out

    def _leading_run(self, tg: FloatArray) -> tuple[FloatArray, dict[str, bool]]:
        """The leading grid times of ``tg`` over which the same streams are present, and whether each stream but
        the primary is present over them.

        The first change is looked for in windows that double in length: a buffer that falls into many runs (a
        whole log pushed at once) would otherwise cost time quadratic in its length, the presence of every
        remaining grid point being computed again for each run.
        """
        n = 4096
        while True:
            w = tg[:n]
            present = {k: self._present(k, w) for k in self.kinds[1:]}
            changes = [int(np.argmax(p != p[0])) for p in present.values() if not (p == p[0]).all()]
            if changes or w.size == tg.size:
                run = tg[:min(changes)] if changes else tg
                return run, {k: bool(p[0]) for k, p in present.items()}
            n *= 2

    def pull(self) -> tuple[FloatArray, dict[str, FloatArray]]:
        """The next run of grid points that the streams already cover, over which the same streams are present:
        (times (n,), kind -> (n, k) values of the streams present). Call again until it gives no points.

        A stream more than ``2 max_gap_s`` behind the primary one has stopped: the grid goes on without it up to
        ``max_gap_s`` behind the primary (module doc).
        """
        if any(self.buf_t[k].size == 0 for k in self.kinds):
            return self._empty()
        if self.next_k is None:
            start = max(float(self.buf_t[k][0]) for k in self.kinds)
            self.next_k = self.first_k = int(math.ceil(start * self.rate_hz - 1e-9))
        lead = float(self.buf_t[self.kinds[0]][-1])
        end = min([lead] + [float(self.buf_t[k][-1]) if lead - float(self.buf_t[k][-1]) <= 2.0 * self.max_gap_s
                            else lead - self.max_gap_s for k in self.kinds[1:]])
        return self._emit(int(math.floor(end * self.rate_hz + 1e-9)))

    def flush(self) -> tuple[FloatArray, dict[str, FloatArray]]:
        """End of session: the next run of grid points up to the last sample of the primary stream; a stream that
        ended at most ``max_gap_s`` before it holds its last value. Call again until it gives no points.
        """
        if self.next_k is None or any(self.buf_t[k].size == 0 for k in self.kinds):
            return self._empty()
        end = float(self.buf_t[self.kinds[0]][-1])
        return self._emit(int(math.floor(end * self.rate_hz + 1e-9)))

    def _empty(self) -> tuple[FloatArray, dict[str, FloatArray]]:
        return np.zeros(0), {k: np.zeros((0, 1)) for k in self.kinds}

    def state(self) -> dict[str, Any]:
        return {"rate_hz": self.rate_hz, "kinds": list(self.kinds), "next_k": self.next_k, "first_k": self.first_k,
                "buf_t": {k: v.tolist() for k, v in self.buf_t.items()},
                "buf_v": {k: v.tolist() for k, v in self.buf_v.items()}}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> OnlineGrid:
        try:
            g = cls(float(d["rate_hz"]), tuple(d["kinds"]))
            g.next_k = None if d["next_k"] is None else int(d["next_k"])
            g.first_k = None if d["first_k"] is None else int(d["first_k"])
            g.buf_t = {k: np.array(v, dtype=np.float64) for k, v in d["buf_t"].items()}
            g.buf_v = {k: np.array(v, dtype=np.float64).reshape(len(v), -1) if len(v) else np.zeros((0, 0))
                       for k, v in d["buf_v"].items()}
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad grid state ({exc})", source="grid state") from None
        return g
