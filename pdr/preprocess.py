"""Put a recording's streams on one uniform time grid, with anti-alias filtering, split at gaps.

Each stream has its own clock and rate (a phone may log acc at 50 Hz, gyro at 100 Hz, pressure at
5 Hz, with jitter and dropped batches). :func:`resample` returns the chosen streams sampled on a
common grid ``t_k = k / rate_hz`` (seconds on the recording's time axis, ``k`` integer, so grids of
consecutive batches line up) as a list of :class:`UniformSegment`: the recording is cut where any
chosen stream has a gap longer than ``max_gap_s`` rather than interpolated across it.

Per stream and segment:

1. the samples are linearly interpolated onto a uniform grid at the stream's own median rate
   (this only removes timestamp jitter and bridges short gaps);
2. when the target rate is below the stream's rate, a Butterworth low-pass (cut-off
   ``cutoff_ratio`` times the target Nyquist frequency) is run forwards and backwards
   (``scipy.signal.sosfiltfilt``: zero phase, for offline use) so that content above the new
   Nyquist frequency does not alias;
3. the result is linearly interpolated onto the target grid.

Orientation quaternions are states, not signals: they are interpolated along the geodesic (slerp,
via :func:`pdr.quaternion.boxplus`/:func:`~pdr.quaternion.boxminus`), never per component, and not
low-passed. Units and frames are those of :data:`pdr.recording.STREAM_KINDS`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.recording import STREAM_KINDS, Recording

FloatArray = NDArray[np.float64]

#: Default: an interval longer than this many median sample intervals is a gap.
GAP_FACTOR = 3.0
#: Default: gaps longer than this (s) split a recording into segments instead of being interpolated.
MAX_GAP_S = 0.2
#: Stream kinds interpolated as unit quaternions.
QUATERNION_KINDS: tuple[str, ...] = ("orientation",)


@dataclass(frozen=True)
class Gap:
    """An interval without samples.

    Attributes
    ----------
    start_s
        Time (s) of the last sample before the gap.
    end_s
        Time (s) of the first sample after the gap.
    index
        Index of the first sample after the gap in the stream's arrays.
    """

    start_s: float
    end_s: float
    index: int

    @property
    def duration_s(self) -> float:
        """Length of the interval between the two samples (s)."""
        return self.end_s - self.start_s


def _times(t_s: ArrayLike, what: str = "t_s") -> FloatArray:
    t = np.asarray(t_s, dtype=np.float64)
    if t.ndim != 1:
        raise InputError(f"times must be a 1-D array, got shape {t.shape}", source=what)
    if not np.all(np.isfinite(t)):
        raise InputError("times must be finite", source=what)
    if t.size > 1 and np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise InputError(f"times must be strictly increasing (sample {i})", source=what)
    return t


def nominal_interval_s(t_s: ArrayLike) -> float:
    """Median sample interval (s) of increasing times; NaN with fewer than two samples."""
    t = np.asarray(t_s, dtype=np.float64)
    return float(np.median(np.diff(t))) if t.size > 1 else float("nan")


def find_gaps(t_s: ArrayLike, nominal_dt: float | None = None, factor: float = GAP_FACTOR,
              min_gap_s: float = 0.0) -> list[Gap]:
    """Intervals between consecutive samples longer than ``factor * nominal_dt`` and ``min_gap_s``.

    Parameters
    ----------
    t_s
        (N,) strictly increasing sample times in s.
    nominal_dt
        Expected sample interval in s (default: the median interval).
    factor
        How many nominal intervals make a gap.
    min_gap_s
        Shorter intervals are never gaps (s).
    """
    t = _times(t_s)
    if t.size < 2:
        return []
    dt = np.diff(t)
    nominal = float(np.median(dt)) if nominal_dt is None else float(nominal_dt)
    if not nominal > 0:
        raise InputError(f"nominal interval must be positive, got {nominal}", field="nominal_dt")
    idx = np.flatnonzero((dt > factor * nominal) & (dt > min_gap_s))
    return [Gap(float(t[i]), float(t[i + 1]), int(i + 1)) for i in idx]


def contiguous_segments(t_s: ArrayLike, max_gap_s: float) -> list[tuple[int, int]]:
    """Index ranges ``[start, stop)`` of runs whose sample intervals are all at most ``max_gap_s``."""
    t = _times(t_s)
    if t.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(t) > max_gap_s) + 1
    bounds = np.concatenate([[0], cuts, [t.size]])
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


@dataclass(frozen=True)
class UniformSegment:
    """Several streams sampled on one uniform time grid.

    Attributes
    ----------
    t_s
        (N,) float64 grid times in s on the recording's time axis (``t_k = k / rate_hz``).
    rate_hz
        Grid rate in Hz.
    data
        Stream kind -> (N, k) float64 samples in the kind's SI unit and frame
        (:data:`pdr.recording.STREAM_KINDS`: acc m/s^2, gyro rad/s, mag uT, baro hPa, orientation
        unit ``q_nb`` ...).
    t0_ns
        Origin of the recording's time axis (int ns on the log's clock).
    bridged_gaps
        Gaps (longer than :data:`GAP_FACTOR` intervals but at most the split threshold) inside this
        segment that were interpolated across, per stream kind.
    """

    t_s: FloatArray
    rate_hz: float
    data: Mapping[str, FloatArray]
    t0_ns: int = 0
    bridged_gaps: Mapping[str, tuple[Gap, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = _times(self.t_s, "segment t_s")
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise InputError(f"rate must be positive, got {self.rate_hz}", field="rate_hz")
        data = {}
        for k, v in dict(self.data).items():
            arr = np.array(v, dtype=np.float64)
            if arr.ndim != 2 or arr.shape[0] != t.size:
                raise InputError(f"expected ({t.size}, k) samples, got {arr.shape}", source=f"stream '{k}'")
            arr.setflags(write=False)
            data[k] = arr
        t = t.copy()
        t.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "rate_hz", float(self.rate_hz))
        object.__setattr__(self, "data", MappingProxyType(data))
        object.__setattr__(self, "bridged_gaps", MappingProxyType(
            {k: tuple(v) for k, v in dict(self.bridged_gaps).items()}))

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last grid point (s)."""
        return float(self.t_s[-1] - self.t_s[0]) if self.t_s.size else 0.0

    def __getitem__(self, kind: str) -> FloatArray:
        if kind not in self.data:
            raise InputError(f"segment has no '{kind}' stream (it has {sorted(self.data)})")
        return self.data[kind]


def slerp(t_s: ArrayLike, q: ArrayLike, t_new_s: ArrayLike) -> FloatArray:
    """Interpolate unit quaternions along the shortest geodesic between neighbouring samples.

    Parameters
    ----------
    t_s
        (N,) increasing sample times in s, N >= 1.
    q
        (N, 4) quaternions (Hamilton, scalar first); normalised before use.
    t_new_s
        (M,) query times in s; outside ``[t_s[0], t_s[-1]]`` the end samples are held.

    Returns
    -------
    (M, 4) unit quaternions with non-negative scalar part.
    """
    t = np.asarray(t_s, dtype=np.float64)
    qq = quat.normalize(np.asarray(q, dtype=np.float64))
    tn = np.asarray(t_new_s, dtype=np.float64)
    if t.size == 1:
        return np.repeat(qq, tn.size, axis=0)
    i = np.clip(np.searchsorted(t, tn, side="right") - 1, 0, t.size - 2)
    u = np.clip((tn - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)
    q0, q1 = qq[i], qq[i + 1]
    # q(u) = exp(u log(q1 q0^-1)) q0; to_rotvec picks the shorter of the two arcs (q and -q are equal).
    return quat.normalize(quat.boxplus(q0, u[:, None] * quat.boxminus(q1, q0)))


def lowpass_sos(rate_hz: float, cutoff_hz: float, order: int = 6) -> FloatArray:
    """Butterworth low-pass in second-order sections for data sampled at ``rate_hz`` (Hz)."""
    from scipy import signal  # 2 s of imports: only where a signal is filtered (`pdr inspect` never does)

    return np.asarray(signal.butter(order, cutoff_hz, btype="low", fs=rate_hz, output="sos"))


def _resample_signal(t: FloatArray, v: FloatArray, fs: float, grid: FloatArray, rate_hz: float,
                     cutoff_ratio: float, order: int) -> FloatArray:
    """Linear onto a jitter-free grid at ``fs``, zero-phase low-pass if decimating, linear onto ``grid``."""
    if t.size == 1:
        return np.repeat(v, grid.size, axis=0)
    cutoff = cutoff_ratio * 0.5 * rate_hz
    if rate_hz >= fs or cutoff >= 0.5 * fs:
        return np.column_stack([np.interp(grid, t, v[:, c]) for c in range(v.shape[1])])
    n = int(round((t[-1] - t[0]) * fs)) + 1
    native = np.linspace(t[0], t[-1], n)
    fs = (n - 1) / (t[-1] - t[0]) if n > 1 else fs
    x = np.column_stack([np.interp(native, t, v[:, c]) for c in range(v.shape[1])])
    if n > 1 and cutoff < 0.5 * fs:
        sos = lowpass_sos(fs, cutoff, order)
        # Default pad length is 3 * (2 * sections + 1); shorter runs pad with what they have.
        padlen = min(3 * (2 * sos.shape[0] + 1), n - 1)
        from scipy import signal

        x = signal.sosfiltfilt(sos, x, axis=0, padtype="odd" if padlen else None, padlen=padlen)
    return np.column_stack([np.interp(grid, native, x[:, c]) for c in range(v.shape[1])])


def _intervals_without_long_gaps(times: Mapping[str, FloatArray], max_gap_s: float,
                                 gap_factor: float) -> list[tuple[float, float]]:
    """Time intervals covered by every stream, cut at each stream's long gaps."""
    lo = max(float(t[0]) for t in times.values())
    hi = min(float(t[-1]) for t in times.values())
    if hi < lo:
        return []
    holes: list[tuple[float, float]] = []
    for t in times.values():
        threshold = max(max_gap_s, gap_factor * nominal_interval_s(t)) if t.size > 1 else max_gap_s
        idx = np.flatnonzero(np.diff(t) > threshold)
        holes += [(float(t[i]), float(t[i + 1])) for i in idx]
    out: list[tuple[float, float]] = []
    start = lo
    for a, b in sorted(holes):
        if a >= hi:
            break
        if a > start:
            out.append((start, a))
        start = max(start, b)
    if start <= hi:
        out.append((start, hi))
    return out


def resample(recording: Recording, rate_hz: float, kinds: Iterable[str] | None = None, *,
             max_gap_s: float = MAX_GAP_S, gap_factor: float = GAP_FACTOR, cutoff_ratio: float = 0.8,
             filter_order: int = 6, min_samples: int = 2) -> list[UniformSegment]:
    """Chosen streams of a recording on one uniform grid at ``rate_hz``, one segment per gap-free span.

    Parameters
    ----------
    recording
        The input; streams in SI units (:mod:`pdr.recording`).
    rate_hz
        Output rate in Hz; the grid is ``t_k = k / rate_hz`` s on the recording's time axis.
    kinds
        Stream kinds to include (default: every stream of the recording).
    max_gap_s
        A stream interval longer than ``max(max_gap_s, gap_factor * its median interval)`` (s) cuts
        the recording; shorter ones are interpolated across and listed in ``bridged_gaps``.
    gap_factor
        Intervals longer than this many median intervals count as gaps.
    cutoff_ratio
        Low-pass cut-off as a fraction of the output Nyquist frequency ``rate_hz / 2`` (used only
        for streams faster than ``rate_hz``).
    filter_order
        Butterworth order (doubled in effect by the forward-backward pass).
    min_samples
        Segments with fewer grid points are dropped.

    Returns
    -------
    list of UniformSegment
        In time order; empty when the chosen streams never overlap.
    """
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"rate must be a positive number of Hz, got {rate_hz}", field="rate_hz")
    if not 0 < cutoff_ratio <= 1:
        raise InputError(f"cutoff_ratio must be in (0, 1], got {cutoff_ratio}", field="cutoff_ratio")
    chosen = list(recording.streams) if kinds is None else list(dict.fromkeys(kinds))
    if not chosen:
        raise InputError("no stream kinds chosen", field="kinds")
    for k in chosen:
        if k not in STREAM_KINDS:
            raise InputError(f"unknown stream kind (known: {', '.join(STREAM_KINDS)})", source=f"stream '{k}'")
        recording.stream(k)  # raises naming the available streams
    times = {k: recording.t_s(k) for k in chosen}
    empty = [k for k, t in times.items() if t.size == 0]
    if empty:
        raise InputError("stream has no samples", source=f"stream '{empty[0]}'")
    rates = {k: (1.0 / nominal_interval_s(t) if t.size > 1 else rate_hz) for k, t in times.items()}
    segments = []
    for a, b in _intervals_without_long_gaps(times, max_gap_s, gap_factor):
        k_lo, k_hi = int(np.ceil(a * rate_hz - 1e-9)), int(np.floor(b * rate_hz + 1e-9))
        if k_hi - k_lo + 1 < min_samples:
            continue
        grid = np.arange(k_lo, k_hi + 1) / rate_hz
        data: dict[str, FloatArray] = {}
        bridged: dict[str, tuple[Gap, ...]] = {}
        for kind in chosen:
            t = times[kind]
            # one sample either side of the span so interpolation reaches its ends
            i0 = max(int(np.searchsorted(t, a, side="right")) - 1, 0)
            i1 = min(int(np.searchsorted(t, b, side="left")) + 1, t.size)
            ts, vs = t[i0:i1], recording.values(kind)[i0:i1]
            if kind in QUATERNION_KINDS:
                data[kind] = slerp(ts, vs, grid)
            else:
                data[kind] = _resample_signal(ts, vs, rates[kind], grid, rate_hz, cutoff_ratio, filter_order)
            if ts.size > 1:
                inner = [g for g in find_gaps(ts, nominal_dt=1.0 / rates[kind], factor=gap_factor)
                         if g.end_s > a and g.start_s < b]
                if inner:
                    bridged[kind] = tuple(inner)
        segments.append(UniformSegment(grid, rate_hz, data, recording.origin_ns, bridged))
    return segments
