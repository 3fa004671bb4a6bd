"""Walking-signal statistics that compare simulated with real phone recordings (same for both).

Per window of steady walking (``WINDOW_S`` long, half overlapping, on a uniform ``RATE_HZ`` grid with
the accelerometer and gyro linearly interpolated), with ``|f|`` the specific-force norm (m/s^2), ``u`` the
window-mean specific-force direction (up) and ``omega`` the angular rate (rad/s, mean removed):

* ``step_hz``: step frequency, twice the inverse of the stride lag (0.7-1.6 s) that maximises the
  autocorrelation of ``|f|``; a window counts as walking when that autocorrelation is at least
  ``MIN_STRIDE_CORRELATION`` and the step frequency lies in 1.3-2.5 Hz;
* ``step_corr``: autocorrelation of ``|f|`` at one step lag (1 = both legs alike);
* ``norm_p2p``, ``norm_max``, ``norm_min``: 1st-99th percentile range, 99th and 1st percentile of ``|f|``;
* ``step_power``: share of the ``|f|`` power (0.3-20 Hz) within 0.2 Hz of the step frequency;
  ``high_power``: share above 4 Hz (heel-strike transients);
* ``vert_std``: standard deviation of the dynamic specific force along ``u``; ``horiz_rms``: RMS of its
  component normal to ``u`` (m/s^2);
* ``gyro_pc1``, ``gyro_pc2``, ``gyro_pc3``: standard deviations of ``omega`` along its principal axes
  (largest first; a pocket phone's first axis is the thigh's pitch axis) and ``gyro_peak``: 99th percentile
  of ``|omega|`` along the first axis (rad/s); NaN without a gyro.

All statistics are orientation-free, so a phone turned any way in the pocket gives the same values.
:func:`recording_summary` reduces a recording to the median over its walking windows; real recordings of
several subjects then give the spread a simulated walk must fall into (``tests/pdr/sim/test_realism.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.recording import Recording

Array = NDArray[np.float64]

RATE_HZ = 100.0
WINDOW_S = 5.12
MIN_STRIDE_CORRELATION = 0.4

#: Statistic names, in the column order of :attr:`WalkingStatistics.values`.
NAMES = ("step_hz", "step_corr", "norm_p2p", "norm_max", "norm_min", "step_power", "high_power",
         "vert_std", "horiz_rms", "gyro_pc1", "gyro_pc2", "gyro_pc3", "gyro_peak")


@dataclass(frozen=True)
class WalkingStatistics:
    """Statistics of the walking windows of one recording.

    Attributes
    ----------
    t_start_s
        (W,) window start times in s on the recording's time axis.
    values
        (W, len(NAMES)) statistics, columns as :data:`NAMES` (units in the module docstring).
    """

    t_start_s: Array
    values: Array

    def column(self, name: str) -> Array:
        """One statistic for every window."""
        return self.values[:, NAMES.index(name)]

    def median(self) -> dict[str, float]:
        """Median of each statistic over the windows (NaN without windows)."""
        out = {}
        for i, n in enumerate(NAMES):
            col = self.values[:, i]
            col = col[np.isfinite(col)]
            out[n] = float(np.median(col)) if col.size else float("nan")
        return out


def _resampled(rec: Recording, kind: str, t: Array) -> Array:
    ts, v = rec.t_s(kind), rec.values(kind)
    return np.column_stack([np.interp(t, ts, v[:, i]) for i in range(v.shape[1])])


def _band(power: Array, freqs: Array, lo: float, hi: float) -> float:
    return float(power[(freqs >= lo) & (freqs < hi)].sum())


def window_statistics(acc: Array, gyro: Array | None, rate_hz: float = RATE_HZ) -> Array | None:
    """Statistics (len(NAMES),) of one window of specific force (N, 3) and angular rate (N, 3) or None.

    Returns None when the window is not steady walking (module docstring).
    """
    norm = np.linalg.norm(acc, axis=1)
    x = norm - norm.mean()
    if x.std() < 0.3:
        return None
    n = x.size
    ac = np.correlate(x, x, "full")[n - 1:] / (x.var() * n)
    lags = np.arange(n) / rate_hz
    stride = int(np.argmax(np.where((lags > 0.7) & (lags < 1.6), ac, -np.inf)))
    step_hz = 2.0 / lags[stride]
    if ac[stride] < MIN_STRIDE_CORRELATION or not 1.3 < step_hz < 2.5:
        return None
    up = acc.mean(axis=0)
    up = up / np.linalg.norm(up)
    dyn = acc - acc.mean(axis=0)
    vert = dyn @ up
    horiz = dyn - np.outer(vert, up)
    power = np.abs(np.fft.rfft(x * np.hanning(n))) ** 2
    freqs = np.asarray(np.fft.rfftfreq(n, 1.0 / rate_hz), dtype=np.float64)
    total = _band(power, freqs, 0.3, 20.0)
    p1, p99 = np.percentile(norm, [1.0, 99.0])
    gyro_stats = [np.nan] * 4
    if gyro is not None:
        w = gyro - gyro.mean(axis=0)
        _, sv, vt = np.linalg.svd(w, full_matrices=False)
        pcs = sv / np.sqrt(w.shape[0])
        gyro_stats = [*pcs, float(np.percentile(np.abs(w @ vt[0]), 99.0))]
    return np.array([step_hz, ac[stride // 2], p99 - p1, p99, p1,
                     _band(power, freqs, step_hz - 0.2, step_hz + 0.2) / total,
                     _band(power, freqs, 4.0, 20.0) / total, vert.std(), np.sqrt((horiz**2).sum(axis=1).mean()),
                     *gyro_stats])


def walking_statistics(rec: Recording, t_start_s: float | None = None, t_end_s: float | None = None,
                       use_gyro: bool = True) -> WalkingStatistics:
    """Statistics of every steady-walking window of ``rec`` between ``t_start_s`` and ``t_end_s`` (s)."""
    if not rec.has("acc"):
        raise InputError("walking statistics need an accelerometer stream", source=rec.source or None,
                         field="acc")
    ta = rec.t_s("acc")
    a = ta[0] if t_start_s is None else max(t_start_s, ta[0])
    b = ta[-1] if t_end_s is None else min(t_end_s, ta[-1])
    t = np.arange(a, b, 1.0 / RATE_HZ)
    acc = _resampled(rec, "acc", t)
    gyro = _resampled(rec, "gyro", t) if use_gyro and rec.has("gyro") else None
    n = int(round(WINDOW_S * RATE_HZ))
    starts, rows = [], []
    for s in range(0, t.size - n + 1, n // 2):
        row = window_statistics(acc[s:s + n], None if gyro is None else gyro[s:s + n])
        if row is not None:
            starts.append(t[s])
            rows.append(row)
    values = np.array(rows, dtype=np.float64).reshape(-1, len(NAMES))
    return WalkingStatistics(np.array(starts, dtype=np.float64), values)


def recording_summary(rec: Recording, t_start_s: float | None = None, t_end_s: float | None = None,
                      min_windows: int = 3) -> dict[str, float] | None:
    """Median statistics over the walking windows, or None with fewer than ``min_windows`` of them."""
    stats = walking_statistics(rec, t_start_s, t_end_s)
    if stats.values.shape[0] < min_windows:
        return None
    return stats.median()
