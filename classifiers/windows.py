"""Fixed-length windows of a recording's inertial streams on one uniform time grid.

Every stream used by the classifiers (``acc``, ``gyro``, ``mag``, ``baro``) is brought onto a common
grid ``t_k = t_origin + k / rate_hz`` (seconds on the recording's axis) by box averaging over one grid
interval: the cumulative trapezoid integral of the raw samples is differenced over
``[t_k - 1/(2 rate), t_k + 1/(2 rate)]``. That is an anti-aliasing low-pass when the raw rate is above the
grid rate (gyro at 200 Hz onto 50 Hz) and a linear interpolation when it is below (barometer at 6 Hz).
Grid points farther than ``max_gap_s`` from any raw sample are NaN, so gaps never produce invented data.

Window ``j`` covers ``[t_origin + j * hop_s, t_origin + j * hop_s + length_s)``; the defaults (2.56 s, 50 %
overlap, 50 Hz) follow common activity-recognition practice and give 128 samples per window. Because the
grid is anchored at ``t_origin`` and not at the first sample of a batch, an online caller that keeps the
origin gets exactly the windows of an offline pass (see :mod:`classifiers.streaming`).

Besides the per-window copies, :class:`Windows` keeps the contiguous grid the windows were cut from,
extended by ``margin_s`` on both sides (NaN beyond the data): the context features
(:mod:`classifiers.features`, ``ctx_*`` groups) look at a span longer than one window around it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters.compiled import kernel
from pdr.recording import Recording

FloatArray = NDArray[np.float64]

#: Streams the features use, with the largest raw-sample gap (s) bridged by interpolation (phones drop
#: accelerometer samples for up to ~0.2 s, e.g. the Galaxy S3 of MobiFall).
WINDOW_STREAMS: Mapping[str, float] = {"acc": 0.25, "gyro": 0.25, "mag": 0.5, "baro": 1.0}


@dataclass(frozen=True)
class WindowConfig:
    """Window settings shared by feature extraction, training and inference.

    Parameters
    ----------
    length_s
        Window length in seconds.
    hop_s
        Distance between window starts in seconds (``length_s / 2`` is 50 % overlap).
    rate_hz
        Rate of the common resampling grid in Hz.
    min_valid_fraction
        Minimum fraction of accelerometer grid points with data for a window to be usable.
    """

    length_s: float = 2.56
    hop_s: float = 1.28
    rate_hz: float = 50.0
    min_valid_fraction: float = 0.95

    def __post_init__(self) -> None:
        for name in ("length_s", "hop_s", "rate_hz"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InputError(f"must be a positive number, got {value!r}", field=name)
        if not 0.0 < self.min_valid_fraction <= 1.0:
            raise InputError("must be in (0, 1]", field="min_valid_fraction")
        if self.n_samples < 16:
            raise InputError(f"a window needs at least 16 samples; length_s * rate_hz = {self.n_samples}",
                             field="length_s")
        if abs(self.hop_s * self.rate_hz - self.n_hop) > 1e-6:
            raise InputError("hop_s * rate_hz must be a whole number of samples", field="hop_s")

    @property
    def n_samples(self) -> int:
        """Samples per window."""
        return int(round(self.length_s * self.rate_hz))

    @property
    def n_hop(self) -> int:
        """Samples between window starts."""
        return int(round(self.hop_s * self.rate_hz))

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> WindowConfig:
        try:
            return cls(**{k: float(d[k]) for k in ("length_s", "hop_s", "rate_hz", "min_valid_fraction")})
        except KeyError as exc:
            raise InputError(f"window settings lack {exc}", field="window") from None


@dataclass(frozen=True)
class Windows:
    """A sequence of windows of resampled sensor data.

    Parameters
    ----------
    t_start_s, t_end_s
        (W,) float64 window bounds in seconds on the recording's time axis.
    rate_hz
        Sampling rate of the window contents in Hz.
    streams
        Stream kind -> (W, n, k) float64 resampled values in the stream's SI unit, body frame; NaN where
        the raw stream had no data. Only the streams the recording has.
    valid
        (W,) bool: the window has enough accelerometer data to be classified.
    grid
        Stream kind -> (K, k) the contiguous resampled grid the windows were cut from, including the
        context margin (NaN where the raw stream has no data).
    grid_start
        (W,) index into ``grid`` of each window's first sample.
    """

    t_start_s: FloatArray
    t_end_s: FloatArray
    rate_hz: float
    streams: Mapping[str, FloatArray]
    valid: NDArray[np.bool_]
    grid: Mapping[str, FloatArray] = field(default_factory=dict)
    grid_start: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return int(self.t_start_s.size)

    def get(self, kind: str) -> FloatArray | None:
        """(W, n, k) values of a stream, or None when the recording lacks it."""
        return self.streams.get(kind)

    def select(self, mask: NDArray[np.bool_]) -> Windows:
        """The windows where ``mask`` is true."""
        return Windows(self.t_start_s[mask], self.t_end_s[mask], self.rate_hz,
                       {k: v[mask] for k, v in self.streams.items()}, self.valid[mask], self.grid,
                       self.grid_start[mask] if self.grid_start.size else self.grid_start)


def resample_box(t_s: FloatArray, values: FloatArray, grid_s: FloatArray, max_gap_s: float) -> FloatArray:
    """Box-average raw samples onto a uniform grid.

    Parameters
    ----------
    t_s
        (N,) strictly increasing sample times in s.
    values
        (N, k) samples.
    grid_s
        (M,) uniform grid times in s (spacing ``h``).
    max_gap_s
        Grid points whose averaging interval is farther than this from the nearest raw sample, or outside
        the raw span, are NaN.

    Returns
    -------
    (M, k) float64 mean of the linearly interpolated signal over ``[t - h/2, t + h/2]``.
    """
    out = np.full((grid_s.size, values.shape[1]), np.nan)
    if t_s.size < 2 or grid_s.size == 0:
        return out
    h = float(grid_s[1] - grid_s[0]) if grid_s.size > 1 else 0.0
    # The grid cells share their edges: integrate once at the K + 1 edges.
    edges = np.clip(np.append(grid_s - h / 2, grid_s[-1] + h / 2), t_s[0], t_s[-1])
    i = np.clip(np.searchsorted(t_s, edges, side="right") - 1, 0, t_s.size - 2)
    width = np.diff(edges)
    avg = _cell_means(np.ascontiguousarray(t_s, dtype=np.float64), np.ascontiguousarray(values, dtype=np.float64),
                      edges, i, width)
    wide = width > 1e-12
    if (~wide).any():
        avg[~wide] = np.stack([np.interp(grid_s[~wide], t_s, values[:, c]) for c in range(values.shape[1])],
                              axis=1)
    # Data present: inside the raw span and the raw samples around t no farther apart than max_gap_s.
    j = np.clip(np.searchsorted(t_s, grid_s), 1, t_s.size - 1)
    gap = t_s[j] - t_s[j - 1]
    ok = (grid_s >= t_s[0] - h / 2) & (grid_s <= t_s[-1] + h / 2) & (gap <= max_gap_s)
    out[ok] = avg[ok]
    return out


@kernel
def _cell_means(t_s: FloatArray, values: FloatArray, edges: FloatArray, i: NDArray[np.int64],
                width: FloatArray) -> FloatArray:
    """(K, k) mean over each cell ``[edges[j], edges[j + 1])`` (s) of the linear interpolant of ``values`` (N, k) at
    ``t_s`` (N,), ``i`` (K + 1,) the sample at or before each edge (clipped to ``[0, N - 2]``) and ``width`` (K,) the
    cells' widths (s; a cell of no width gives inf or nan, for the caller to replace).

    The interpolant's integral ``I(t)`` is the cumulative trapezoid sum to the sample before ``t`` plus the part of the
    segment up to ``t``; a cell's mean is ``(I(end) - I(start)) / width``. The arithmetic is that of the numpy
    expressions it replaced, operation by operation, so the results are the same bits.
    """
    n, k = values.shape
    cum = np.zeros((n, k))
    for r in range(n - 1):
        dt = t_s[r + 1] - t_s[r]
        for c in range(k):
            cum[r + 1, c] = cum[r, c] + 0.5 * (values[r + 1, c] + values[r, c]) * dt
    at_edges = np.empty((edges.size, k))
    for e in range(edges.size):
        j = i[e]
        dt = edges[e] - t_s[j]
        span = t_s[j + 1] - t_s[j]
        for c in range(k):
            slope = (values[j + 1, c] - values[j, c]) / span
            at_edges[e, c] = cum[j, c] + values[j, c] * dt + 0.5 * slope * (dt * dt)
    out = np.empty((width.size, k))
    for e in range(width.size):
        for c in range(k):
            out[e, c] = (at_edges[e + 1, c] - at_edges[e, c]) / width[e]
    return out


def grid_for(cfg: WindowConfig, t_origin_s: float, t_first_s: float, t_last_s: float) -> tuple[int, int]:
    """Index range ``[k0, k1)`` of grid points ``t_origin + k / rate`` inside ``[t_first_s, t_last_s]``."""
    k0 = int(math.ceil((t_first_s - t_origin_s) * cfg.rate_hz - 1e-9))
    k1 = int(math.floor((t_last_s - t_origin_s) * cfg.rate_hz + 1e-9)) + 1
    return k0, max(k0, k1)


def make_windows(rec: Recording, cfg: WindowConfig = WindowConfig(), t_origin_s: float | None = None,
                 first_window: int = 0, streams: tuple[str, ...] = tuple(WINDOW_STREAMS),
                 margin_s: float = 0.0) -> Windows:
    """Cut a recording into windows (see module docstring).

    Parameters
    ----------
    rec
        The recording; must have an ``acc`` stream.
    cfg
        Window settings.
    t_origin_s
        Grid origin in seconds on ``rec``'s axis; defaults to the first accelerometer sample.
    first_window
        Index of the first window to emit (windows ``j >= first_window`` that fit inside the data).
    streams
        Which stream kinds to resample when present.
    margin_s
        Extra seconds of grid kept before the first and after the last window (``Windows.grid``) for
        the context features; NaN where there is no data.

    Returns
    -------
    Windows, possibly empty when the recording is shorter than one window.
    """
    if not rec.has("acc"):
        raise InputError("the classifiers need an accelerometer ('acc') stream", source=rec.source or None)
    t_acc = rec.t_s("acc")
    origin = float(t_acc[0]) if t_origin_s is None else float(t_origin_s)
    k_first, k_end = grid_for(cfg, origin, float(t_acc[0]), float(t_acc[-1]))
    n, hop = cfg.n_samples, cfg.n_hop
    # Windows j with start index j*hop >= k_first and end index j*hop + n <= k_end.
    j0 = max(first_window, int(math.ceil(k_first / hop)))
    j1 = (k_end - n) // hop + 1 if k_end - n >= 0 else j0
    n_win = max(0, j1 - j0)
    starts = (j0 + np.arange(n_win)) * hop
    margin = int(math.ceil(max(0.0, margin_s) * cfg.rate_hz - 1e-9))
    k_lo = int(starts[0]) - margin if n_win else 0
    k_hi = int(starts[-1]) + n + margin if n_win else 0
    grid = origin + np.arange(k_lo, k_hi) / cfg.rate_hz
    grid_start = (starts - k_lo).astype(np.int64)
    idx = grid_start[:, None] + np.arange(n)[None, :]
    data: dict[str, FloatArray] = {}
    grids: dict[str, FloatArray] = {}
    for kind in streams:
        if not rec.has(kind) or (len(rec.stream(kind)) < 2 and n_win):
            continue    # (a stream of one sample, e.g. a file cut after its first line: no window either way)
        res = resample_box(rec.t_s(kind), rec.values(kind), grid, WINDOW_STREAMS.get(kind, 0.1))
        grids[kind] = res
        data[kind] = res[idx] if n_win else np.empty((0, n, res.shape[1]))
    acc = data["acc"] if "acc" in data else np.empty((0, n, 3))
    valid = np.isfinite(acc).all(axis=2).mean(axis=1) >= cfg.min_valid_fraction if n_win else np.zeros(0, bool)
    t0 = origin + starts / cfg.rate_hz
    return Windows(t0.astype(np.float64), t0 + cfg.length_s, cfg.rate_hz, data, valid, grids, grid_start)
