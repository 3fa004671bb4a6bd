"""Online resampling of several sensor streams onto one uniform grid, batch by batch.

The grid is ``t_k = k / rate_hz`` seconds on the log's own clock (``k`` integer, the convention of
:mod:`pdr.preprocess`), so every batch of a session lands on the same grid. A grid point is emitted once
every stream of the session has a sample at or after it; its value is the linear interpolation between
the two samples that bracket it. The result therefore does not depend on how the samples were split into
batches. :meth:`OnlineGrid.flush` ends the session: the remaining grid points up to the last sample of
the fastest-ending stream are emitted, later streams hold their last value.

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

FloatArray = NDArray[np.float64]


class OnlineGrid:
    """Uniform grid over the streams ``kinds`` (fixed at the first batch that has them)."""

    def __init__(self, rate_hz: float, kinds: tuple[str, ...]) -> None:
        if not rate_hz > 0:
            raise InputError(f"grid rate must be positive, got {rate_hz}", field="rate_hz", source="grid")
        self.rate_hz = float(rate_hz)
        self.kinds = kinds
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

    def _emit(self, k_end: int) -> tuple[FloatArray, dict[str, FloatArray]]:
        """Grid points next_k .. k_end (inclusive)."""
        assert self.next_k is not None
        if k_end < self.next_k:
            return np.zeros(0), {k: np.zeros((0, max(self.buf_v[k].shape[1], 1))) for k in self.kinds}
        ks = np.arange(self.next_k, k_end + 1)
        tg = ks / self.rate_hz
        out = {}
        for k in self.kinds:
            bt, bv = self.buf_t[k], self.buf_v[k]
            out[k] = np.column_stack([np.interp(tg, bt, bv[:, j]) for j in range(bv.shape[1])])
            # Keep the last sample at or before the last emitted grid time, and everything after it.
            i = max(int(np.searchsorted(bt, tg[-1], side="right")) - 1, 0)
            self.buf_t[k], self.buf_v[k] = bt[i:], bv[i:]
        self.next_k = k_end + 1
        return tg, out

    def pull(self) -> tuple[FloatArray, dict[str, FloatArray]]:
        """Every grid point that all streams already cover: (times (n,), kind -> (n, k) values)."""
        if any(self.buf_t[k].size == 0 for k in self.kinds):
            return self._empty()
        if self.next_k is None:
            start = max(float(self.buf_t[k][0]) for k in self.kinds)
            self.next_k = self.first_k = int(math.ceil(start * self.rate_hz - 1e-9))
        end = min(float(self.buf_t[k][-1]) for k in self.kinds)
        return self._emit(int(math.floor(end * self.rate_hz + 1e-9)))

    def flush(self) -> tuple[FloatArray, dict[str, FloatArray]]:
        """End of session: emit up to the last sample of the first (primary) stream, holding the others."""
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
