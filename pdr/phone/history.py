"""The phone pipeline's sample history: the grid samples of the last ``history_s`` seconds and what the stages
derived from them (attitude, specific force in ENU, heights, floors, gyro yaw), indexed by the grid's sample index,
so that a step confirmed later can be processed on its own samples.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

_FIELD_WIDTHS = (("t", 0), ("acc", 3), ("q", 4), ("f_n", 3), ("yaw_y", 0), ("yaw_z", 0), ("y_up", 0), ("an", 0),
                 ("mag_n", 0), ("up", 0), ("floor", 0), ("gyro_yaw", 0), ("up_time", 3))
_FIELDS = tuple(n for n, _ in _FIELD_WIDTHS)


class SampleHistory:
    """Grid samples of the last ``size`` indices: t, acc_b, q_nb, f_n (specific force in ENU), yaw of the
    device y and z axes, up-component of the device y axis, a_n, |m|, up (m), floor, the gyro yaw (rad: the
    angular rate about the vertical integrated since the start, no magnetometer, no bias removed) and the
    device-frame up direction integrated since the start (s).
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.start = 0
        self.t = np.zeros(0)
        self.acc = np.zeros((0, 3))
        self.q = np.zeros((0, 4))
        self.f_n = np.zeros((0, 3))
        self.yaw_y = np.zeros(0)
        self.yaw_z = np.zeros(0)
        self.y_up = np.zeros(0)
        self.an = np.zeros(0)
        self.mag_n = np.zeros(0)
        self.up = np.zeros(0)
        self.floor = np.zeros(0)
        self.gyro_yaw = np.zeros(0)
        self.up_time = np.zeros((0, 3))

    def append(self, start: int, t: FloatArray, acc: FloatArray, an: FloatArray, mag_n: FloatArray,
               up: FloatArray, floor: FloatArray) -> None:
        if self.t.size == 0:
            self.start = start
        n = t.size
        self.t = _extended(self.t, n, t)
        self.acc = _extended(self.acc, n, acc)
        self.q = _extended(self.q, n)
        self.f_n = _extended(self.f_n, n)
        self.yaw_y = _extended(self.yaw_y, n)
        self.yaw_z = _extended(self.yaw_z, n)
        self.y_up = _extended(self.y_up, n)
        self.an = _extended(self.an, n, an)
        self.mag_n = _extended(self.mag_n, n, mag_n)
        self.up = _extended(self.up, n, up)
        self.floor = _extended(self.floor, n, floor)
        self.gyro_yaw = _extended(self.gyro_yaw, n)
        self.up_time = _extended(self.up_time, n)

    def trim(self) -> None:
        extra = self.t.size - self.size
        if extra > 0:
            self.start += extra
            for name in _FIELDS:
                setattr(self, name, getattr(self, name)[extra:])

    def sl(self, a: int, b: int) -> slice:
        return slice(max(a - self.start, 0), max(b - self.start, 0))

    def state(self) -> dict[str, Any]:
        return {"size": self.size, "start": self.start,
                **{n: getattr(self, n).copy() for n in _FIELDS}}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> SampleHistory:
        h = cls(int(d["size"]))
        h.start = int(d["start"])
        for n, w in _FIELD_WIDTHS:
            # The gyro yaw and up time are absent in states saved before the heading smoother.
            a = np.array(d[n] if n in d else np.full((len(d["t"]), w) if w else len(d["t"]), np.nan),
                         dtype=np.float64)
            setattr(h, n, a.reshape(-1, w) if w else a.reshape(-1))
        return h


def _extended(old: FloatArray, n: int, rows: FloatArray | None = None) -> FloatArray:
    """``old`` (float64, rows first) followed by the ``n`` rows ``rows``, or by ``n`` rows of NaN (a value computed
    later): what ``np.concatenate`` of the two gives, made in one new array (not a NaN array first, then the copy).
    """
    if rows is not None and rows.shape != (n, *old.shape[1:]):
        raise ValueError(f"history rows must be {(n, *old.shape[1:])}, got {rows.shape}")
    out = np.empty((old.shape[0] + n, *old.shape[1:]))
    out[:old.shape[0]] = old
    out[old.shape[0]:] = np.nan if rows is None else rows
    return out
