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
A gap that the primary stream shares is a pause of the recording, not a stream that stopped: a short one (the primary's
own gap at most that long, the joins of a tiled log) is bridged when what is left of it beyond the primary's gap is at
most that long too; a long one (an app suspended) leaves the stream absent, since a rate bridged over it would turn
the attitude.
A slow stream (a barometer at 0.5 Hz, whose every interval is near or over that gap) has its gaps measured in its
own periods instead: gaps of up to :data:`SLOW_GAP_PERIODS` of its median period are bridged (at most
:data:`MAX_SLOW_GAP_S`), and the wait scales with them.
A stream that was taken as stopped but goes on where it left off (its samples come a whole batch late, batches
longer than the slack) was only late: from then on the grid waits for it that long and a little more (at most
:data:`MAX_LAG_S`), and :meth:`OnlineGrid.push` says so in a notice; the points already emitted stay without it.

A stream of ``may_join`` that the first batch lacks joins the grid when a later batch brings it (a phone starts its
sensors one by one, or a stream's first samples arrive a batch late): :meth:`OnlineGrid.push` says so in a notice, and
the stream is absent at the grid points before its first sample, present from there on, as after a gap.

Samples at or before the last one taken of their stream are dropped (a batch sent twice, a sender that repeats the
end of its last batch). When a batch's primary samples go back further (:data:`BACK_TOLERANCE_S`) and the batch is
not one already sent, the phone's clock went back (a clock correction, an app restarted with a new clock): the grid
cannot place them among what it has processed, and :meth:`OnlineGrid.push` says so in a notice.

A gap in every stream (an app suspended for a while) is bridged: the primary stream is interpolated across it, in
runs of at most :data:`MAX_RUN_S`, and a notice says so when it is over :data:`GAP_NOTICE_S`; a jump of the
primary's clock longer than :data:`MAX_JUMP_S` is refused.

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
from pdr.recording import STREAM_KINDS, Recording

#: How far (s) a batch's primary samples may overlap those already taken (a sender that repeats the end of its last
#: batch) before a notice says that the phone's clock went back (:meth:`OnlineGrid.push`).
BACK_TOLERANCE_S = 0.5

#: A slow stream (period over MAX_STREAM_GAP_S / SLOW_GAP_PERIODS) has gaps of this many of its periods bridged, up to
#: MAX_SLOW_GAP_S seconds; its median period is taken over its last RECENT_INTERVALS sampling intervals.
SLOW_GAP_PERIODS = 2.5
MAX_SLOW_GAP_S = 10.0
RECENT_INTERVALS = 16

#: Longest lag (s) behind the primary stream that the grid learns to wait for (module doc); also how much of the other
#: streams it keeps while the primary stream has stopped.
MAX_LAG_S = 30.0

#: A gap (s) in the primary stream longer than this is said in a notice (:meth:`OnlineGrid.push`).
GAP_NOTICE_S = 10.0

#: Longest run (s) of grid points that :meth:`OnlineGrid.pull` gives at once: a long gap (an app suspended for hours)
#: is bridged run by run, in bounded memory.
MAX_RUN_S = 600.0

#: Longest jump forward (s) of the primary stream's clock that a session bridges (interpolating, run by run); a
#: longer one (a clock reset by years) is refused with an :class:`InputError` instead of filling it for hours.
MAX_JUMP_S = 86400.0

#: Batches of the primary stream remembered to know one that is sent again.
RECENT_BATCHES = 16

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

    def __init__(self, rate_hz: float, kinds: tuple[str, ...], max_gap_s: float = MAX_STREAM_GAP_S,
                 may_join: tuple[str, ...] = ()) -> None:
        if not rate_hz > 0:
            raise InputError(f"grid rate must be positive, got {rate_hz}", field="rate_hz", source="grid")
        self.rate_hz = float(rate_hz)
        self.kinds = kinds
        self.max_gap_s = float(max_gap_s)
        self.may_join = tuple(k for k in may_join if k not in kinds)   # streams that may join later (module doc)
        self.buf_t: dict[str, FloatArray] = {k: np.zeros(0) for k in kinds}
        self.buf_v: dict[str, FloatArray] = {k: np.zeros((0, 0)) for k in kinds}
        self.next_k: int | None = None   # next grid index to emit
        self.first_k: int | None = None  # first grid index ever emitted
        #: (first, last) sample times (ns) of the primary stream in the last batches: a batch sent again is no news.
        self.recent: list[tuple[int, int]] = []
        self.going_back = False          # the last batch's primary samples went back (one notice per episode)
        #: How far (s) behind the primary stream a stream may be before it is taken as stopped (learnt, module doc).
        self.wait_s: dict[str, float] = {}
        self.primary_stopped = False     # the primary stream is far behind the others (:meth:`_primary_stopped`)
        #: The last sampling intervals (s) of each stream but the primary (a slow stream's gaps, :meth:`_gap`).
        self.intervals: dict[str, list[float]] = {}

    def push(self, rec: Recording) -> list[str]:
        """Append a batch's samples (times on the log clock, seconds); notices for the user (module doc: a stream that
        joins or comes a batch late, a clock that went back, a gap, a primary stream that stopped).
        """
        primary, notices = self.kinds[0], []
        if rec.has(primary) and self.buf_t[primary].size:
            jump_s = float(rec.stream(primary).t_ns[0]) / 1e9 - float(self.buf_t[primary][-1])
            if jump_s > MAX_JUMP_S:     # refused before anything changes: a later batch meets the same jump
                raise InputError(f"the {_sensor(primary)}'s clock jumps {jump_s:.0f} s forward "
                                 f"(from t={float(self.buf_t[primary][-1]):.2f} s), more than a session can bridge "
                                 f"({MAX_JUMP_S:g} s): the phone's clock was reset; start a new session",
                                 source=rec.source or None, field="t_ns")
        for k in self.may_join:
            if k not in self.kinds and rec.has(k):
                self.kinds += (k,)
                self.buf_t[k], self.buf_v[k] = np.zeros(0), np.zeros((0, 0))
                notices.append(f"{_sensor(k)} data starts at t={rec.stream(k).t_ns[0] / 1e9:.2f} s, "
                               "after the session's first batch: used from there on")
        for k in self.kinds:
            if not rec.has(k):
                continue
            s = rec.stream(k)
            t = (s.t_ns.astype(np.float64) / 1e9)
            v = s.values
            bt = self.buf_t[k]
            if k == self.kinds[0]:
                notices += self._went_back(s.t_ns, bt)
            if bt.size and t[0] <= bt[-1]:
                keep = t > bt[-1]
                t, v = t[keep], v[keep]
                if t.size == 0:
                    continue
            if k == self.kinds[0]:
                notices += self._gaps(np.concatenate([bt[-1:], t]))
            else:
                notices += self._late(k, t, bt)
                dt = np.diff(np.concatenate([bt[-1:], t]))
                self.intervals[k] = [*self.intervals.get(k, []), *dt[-RECENT_INTERVALS:].tolist()][-RECENT_INTERVALS:]
            if k in QUATERNION_KINDS:
                v = sign_continuous(v, self.buf_v[k][-1] if self.buf_v[k].size else None)
            self.buf_t[k] = np.concatenate([bt, t])
            self.buf_v[k] = v.copy() if self.buf_v[k].size == 0 else np.concatenate([self.buf_v[k], v])
        return notices + self._primary_stopped()

    def _primary_stopped(self) -> list[str]:
        """While the primary stream is more than :data:`MAX_LAG_S` behind another (it stopped, the others go on),
        keep of each other stream what the primary's grid points need (up to the first sample after its last one) and
        its last ``MAX_LAG_S`` (before, their buffers grew with the session), and say so once.
        """
        primary = self.buf_t[self.kinds[0]]
        ahead = [float(self.buf_t[k][-1]) for k in self.kinds[1:] if self.buf_t[k].size]
        if not primary.size or not ahead or max(ahead) - float(primary[-1]) <= MAX_LAG_S:
            self.primary_stopped = False
            return []
        for k in self.kinds[1:]:
            bt = self.buf_t[k]
            if bt.size:
                keep = bt >= bt[-1] - MAX_LAG_S
                keep[:int(np.searchsorted(bt, primary[-1], side="right")) + 1] = True
                self.buf_t[k], self.buf_v[k] = bt[keep], self.buf_v[k][keep]
        if self.primary_stopped:
            return []
        self.primary_stopped = True
        name = _sensor(self.kinds[0])
        return [f"no {name} data since t={float(primary[-1]):.2f} s while the other sensors go on (to t="
                f"{max(ahead):.2f} s): nothing is processed until the {name} resumes"]

    def _late(self, kind: str, t: FloatArray, bt: FloatArray) -> list[str]:
        """Learn to wait longer for ``kind`` when its new samples ``t`` (s) go on from its last one (``bt``) at most
        ``max_gap_s`` later, but grid points after that were emitted without it: it was late, not stopped.
        """
        if self.next_k is None or not bt.size or t[0] - bt[-1] > self._gap(kind):
            return []
        emitted_s = (self.next_k - 1) / self.rate_hz
        lag_s = float(self.buf_t[self.kinds[0]][-1]) - float(t[-1])
        if emitted_s <= bt[-1] or lag_s + self._gap(kind) <= self._wait(kind):
            return []
        self.wait_s[kind] = min(lag_s + self._gap(kind), MAX_LAG_S)
        name = _sensor(kind)
        return [f"{name} data comes {lag_s:.1f} s behind the {_sensor(self.kinds[0])}'s "
                f"(a batch late): t={float(bt[-1]):.2f} to {emitted_s:.2f} s were processed without it; the live "
                f"track now waits up to {self.wait_s[kind]:.1f} s for it"]

    def _wait(self, kind: str) -> float:
        """How far (s) behind the primary stream ``kind`` may be before it is taken as stopped."""
        return max(self.wait_s.get(kind, 0.0), 2.0 * self._gap(kind))

    def _gap(self, kind: str) -> float:
        """Longest gap (s) within ``kind`` that is bridged: ``max_gap_s``, or for a slow stream (a barometer at 0.5 Hz)
        :data:`SLOW_GAP_PERIODS` of its median sampling period (at most :data:`MAX_SLOW_GAP_S`).
        """
        dt = self.intervals.get(kind)
        return self.max_gap_s if not dt else min(max(self.max_gap_s, SLOW_GAP_PERIODS * float(np.median(dt))),
                                                  MAX_SLOW_GAP_S)

    def _gaps(self, t: FloatArray) -> list[str]:
        """A notice for each gap over :data:`GAP_NOTICE_S` between the primary stream's samples ``t`` (s)."""
        name = _sensor(self.kinds[0])
        at = np.flatnonzero(np.diff(t) > GAP_NOTICE_S)        # vectorised: a whole log is pushed at once
        return [f"no {name} data from t={t[i]:.2f} to {t[i + 1]:.2f} s ({t[i + 1] - t[i]:.1f} s: the app suspended, "
                "or the phone stopped sending): it is bridged by interpolation, no step is counted in it and the track "
                "goes on from where it was" for i in at.tolist()]

    def _went_back(self, t_ns: NDArray[np.int64], bt: FloatArray) -> list[str]:
        """A notice when a batch's primary samples go back more than :data:`BACK_TOLERANCE_S` before the last one
        already taken (they are dropped), unless the batch is one already sent; once per run of such batches.
        """
        span = (int(t_ns[0]), int(t_ns[-1]))
        repeat = span in self.recent
        self.recent = [*self.recent, span][-RECENT_BATCHES:] if not repeat else self.recent
        back_s = float(bt[-1]) - float(t_ns[0]) / 1e9 if bt.size else -math.inf
        went_back = back_s > BACK_TOLERANCE_S and not repeat
        notice = went_back and not self.going_back
        self.going_back = went_back and float(t_ns[-1]) / 1e9 <= float(bt[-1])
        if not notice:
            return []
        return [f"a batch's {_sensor(self.kinds[0])} data (from t={t_ns[0] / 1e9:.2f} s) "
                f"goes {back_s:.2f} s back before data already processed (up to t={float(bt[-1]):.2f} s): the "
                "phone's clock went back or the app restarted with a new clock; what comes before that time again is "
                "dropped (start a new session when the app restarts)"]

    def _present(self, kind: str, tg: FloatArray) -> NDArray[np.bool_]:
        """Whether ``kind`` has a value at the grid times ``tg`` (s): at one of its samples, between two samples at
        most ``max_gap_s`` apart, or after its last sample while the primary stream is at most that far ahead (held);
        not before its first sample (a stream that joined late).
        """
        bt = self.buf_t[kind]
        i = np.searchsorted(bt, tg, side="right") - 1               # bt[i] <= t < bt[i + 1]
        before = i < 0                                              # only for a stream that joined late
        i = np.maximum(i, 0)
        nxt = bt[np.minimum(i + 1, bt.size - 1)]
        after_last = i == bt.size - 1
        gap = self._gap(kind)
        held = float(self.buf_t[self.kinds[0]][-1]) - float(bt[-1]) <= gap
        bridged = nxt - bt[i] <= gap
        for j in np.unique(i[~after_last & ~bridged]).tolist():     # a long gap: a short pause of every stream?
            bridged[i == j] = self._short_pause(float(bt[j]), float(bt[j + 1]), gap)
        return ~before & ((tg == bt[i]) | np.where(after_last, held, bridged))

    def _short_pause(self, a: float, b: float, gap: float) -> bool:
        """Whether a stream's gap from ``a`` to ``b`` (s) is a short pause of the whole recording, not a stream that
        stopped: the primary stream has a gap of its own, itself at most ``gap`` s (bridged, as the primary's gaps
        are), over all of it but at most ``gap`` s (the joins of a tiled log; a longer pause of every stream, an app
        suspended, leaves the stream absent, as a rate held over it would turn the attitude). The primary's samples
        from before ``a`` must still be buffered: once the grid went on past ``a`` without the stream, it had taken
        it as stopped while the primary went on.
        """
        p = self.buf_t[self.kinds[0]]
        if not p.size or p[0] > a:
            return False
        inside = p[(p > a) & (p < b)]
        longest = float(np.max(np.diff(np.concatenate([[a], inside, [b]]))))
        return longest <= gap and (b - a) - longest <= gap

    def _emit(self, k_end: int) -> tuple[FloatArray, dict[str, FloatArray]]:
        """Grid points next_k .. k_end (inclusive), up to the first at which a stream starts or stops being present
        (:meth:`_present`); the values of the streams present over them.
        """
        assert self.next_k is not None
        k_end = min(k_end, self.next_k + int(MAX_RUN_S * self.rate_hz) - 1)     # memory bounded over a long gap
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

        A stream more than ``2 max_gap_s`` (or the lag learnt for it) behind the primary one has stopped: the grid
        goes on without it up to ``max_gap_s`` behind the primary (module doc).
        """
        if any(self.buf_t[k].size == 0 for k in self.kinds):
            return self._empty()
        if self.next_k is None:
            start = max(float(self.buf_t[k][0]) for k in self.kinds)
            self.next_k = self.first_k = int(math.ceil(start * self.rate_hz - 1e-9))
        lead = float(self.buf_t[self.kinds[0]][-1])
        end = min([lead] + [float(self.buf_t[k][-1]) if lead - float(self.buf_t[k][-1]) <= self._wait(k)
                            else lead - self._gap(k) for k in self.kinds[1:]])
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
        return {"rate_hz": self.rate_hz, "kinds": list(self.kinds), "may_join": list(self.may_join),
                "next_k": self.next_k, "first_k": self.first_k, "recent": [list(r) for r in self.recent],
                "going_back": self.going_back, "wait_s": dict(self.wait_s),
                "intervals": {k: list(v) for k, v in self.intervals.items()}, "primary_stopped": self.primary_stopped,
                "buf_t": {k: v.tolist() for k, v in self.buf_t.items()},
                "buf_v": {k: v.tolist() for k, v in self.buf_v.items()}}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> OnlineGrid:
        try:
            # "may_join" is absent in states saved before late streams joined: theirs keep the streams they have.
            g = cls(float(d["rate_hz"]), tuple(d["kinds"]), may_join=tuple(d.get("may_join", ())))
            g.next_k = None if d["next_k"] is None else int(d["next_k"])
            g.first_k = None if d["first_k"] is None else int(d["first_k"])
            # Absent in states saved before batches going back were noticed.
            g.recent = [(int(a), int(b)) for a, b in d.get("recent", [])]
            g.going_back = bool(d.get("going_back", False))
            g.wait_s = {str(k): float(v) for k, v in d.get("wait_s", {}).items()}   # absent before lags were learnt
            g.intervals = {str(k): [float(x) for x in v] for k, v in d.get("intervals", {}).items()}   # likewise
            g.primary_stopped = bool(d.get("primary_stopped", False))
            g.buf_t = {k: np.array(v, dtype=np.float64) for k, v in d["buf_t"].items()}
            g.buf_v = {k: np.array(v, dtype=np.float64).reshape(len(v), -1) if len(v) else np.zeros((0, 0))
                       for k, v in d["buf_v"].items()}
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad grid state ({exc})", source="grid state") from None
        return g


def _sensor(kind: str) -> str:
    """The sensor of a stream kind, as notices name it (:data:`pdr.recording.STREAM_KINDS`)."""
    spec = STREAM_KINDS.get(kind)
    return kind if spec is None else spec.sensor
