"""Context features: statistics over a span longer than one window, centred on it (seed 003 Sec. 3).

A 2.56 s window in the middle of an elevator ride -- standing in the cabin before the cabin moves, or at
constant speed between the two acceleration impulses -- looks like standing, and the barometric slope of
one window is too noisy to tell a flight of stairs from level walking. The seed decides per landmark event
with its context: the impulse pair seconds apart, the magnetic magnitude change at the cabin doors. These
features give each window that context, computed on the contiguous resampled grid the windows were cut
from (``Windows.grid``, which :func:`classifiers.windows.make_windows` extends by
:func:`classifiers.features.context_margin_s` on both sides):

``ctx_acc`` (span ``CONTEXT_SPAN_S``)
    maximum and minimum of the 1 s moving average of the vertical dynamic acceleration (m/s^2; gravity
    from a moving average over ``GRAVITY_SPAN_S``) -- the hyper-/hypo-gravity impulse
    pair of an elevator anywhere in the span; standard deviation of the specific-force norm (m/s^2).
``ctx_mag`` (span ``CONTEXT_SPAN_S``)
    ``log(|m|_window / max |m|_span)`` and ``log(|m|_window / min |m|_span)`` with ``|m|_window`` the
    window's mean field magnitude and ``|m|_span`` the one-window moving average over the span: a steel
    cabin changes the magnitude against the corridor outside it.
``ctx_baro``
    least-squares pressure slope (hPa/s) over ``BARO_CONTEXT_SPAN_S`` and over ``CONTEXT_SPAN_S``.

Every statistic uses only the samples with data; a span with under half its samples present gives NaN.
All windows are computed at once: sums and slopes from cumulative sums over the grid (O(grid)), extrema by one
reduction over each window's span (O(windows x span)).
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _cumsum0(x: FloatArray) -> FloatArray:
    """Cumulative sum with a leading zero along axis 0."""
    return np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)])


def span_sums(x: FloatArray, lo: IntArray, hi: IntArray) -> tuple[FloatArray, FloatArray]:
    """Sum of the finite values of ``x`` (K,) over ``[lo, hi)`` (clipped to the grid) and their count."""
    ok = np.isfinite(x)
    k = x.shape[0]
    lo_c, hi_c = np.clip(lo, 0, k), np.clip(hi, 0, k)
    if ok.all():
        cs = _cumsum0(x)
        return cs[hi_c] - cs[lo_c], (hi_c - lo_c).astype(np.float64)
    cs = _cumsum0(np.where(ok, x, 0.0))
    cn = _cumsum0(ok.astype(np.float64))
    return cs[hi_c] - cs[lo_c], cn[hi_c] - cn[lo_c]


def moving_average(x: FloatArray, width: int, min_fraction: float = 0.5) -> FloatArray:
    """Centred moving average of (K,) ``x`` over ``width`` samples ignoring NaN (NaN if too few present)."""
    k = x.shape[0]
    lo = np.arange(k) - width // 2
    s, c = span_sums(x, lo, lo + width)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c >= min_fraction * width, s / np.maximum(c, 1.0), np.nan)


def span_extrema(x: FloatArray, lo: IntArray, span: int) -> tuple[FloatArray, FloatArray]:
    """Maximum and minimum of the finite values of (K,) ``x`` over ``[lo, lo + span)``; NaN if none."""
    ok = np.isfinite(x)
    half = span // 2
    # The span of a window is centred on it as a filter of ``span`` taps is (``lo`` clipped to the grid):
    # x[c - half : c - half + span] with c = lo + half, which is padded[c : c + span] once ``half`` samples lead.
    centre = np.clip(lo + half, 0, x.shape[0] - 1)

    def extreme(fill: float, reduce: np.ufunc) -> FloatArray:
        padded = np.concatenate([np.full(half, fill), np.where(ok, x, fill), np.full(span, fill)])
        return np.asarray(reduce.reduce(sliding_window_view(padded, span)[centre], axis=1))

    mx, mn = extreme(-np.inf, np.maximum), extreme(np.inf, np.minimum)
    return np.where(np.isfinite(mx), mx, np.nan), np.where(np.isfinite(mn), mn, np.nan)


def span_slope(x: FloatArray, lo: IntArray, span: int, rate_hz: float) -> FloatArray:
    """Least-squares slope (unit of ``x`` per s) of (K,) ``x`` over ``[lo, lo + span)``; NaN if under half present."""
    ok = np.isfinite(x)
    ref = float(np.mean(x[ok])) if ok.any() else 0.0
    t = np.arange(x.shape[0], dtype=np.float64)
    t0 = float(lo[0]) if lo.size else 0.0
    tt = np.where(ok, t - t0, np.nan)
    xv = x - ref
    hi = lo + span
    sx, n = span_sums(xv, lo, hi)
    st = span_sums(tt, lo, hi)[0]
    stt = span_sums(tt * tt, lo, hi)[0]
    stx = span_sums(tt * xv, lo, hi)[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        den = n * stt - st * st
        slope = (n * stx - st * sx) / den * rate_hz
    return np.where((n >= 0.5 * span) & (den > 0), slope, np.nan)


def context_features(grid: dict[str, FloatArray], grid_start: IntArray, n: int, rate_hz: float,
                     groups: tuple[str, ...], span_s: float, baro_span_s: float,
                     gravity_span_s: float) -> dict[str, FloatArray]:
    """The ``ctx_*`` groups (module docstring) for windows of ``n`` samples starting at ``grid_start``.

    Parameters
    ----------
    grid
        Stream kind -> (K, k) resampled samples (``Windows.grid``).
    grid_start
        (W,) first grid index of each window.
    n
        Samples per window.
    rate_hz
        Grid rate in Hz.
    groups
        Which of ``ctx_acc``, ``ctx_mag``, ``ctx_baro`` to compute.
    span_s, baro_span_s
        Context spans in s.
    gravity_span_s
        Span in s of the moving average that estimates gravity for the vertical acceleration.

    Returns
    -------
    Group -> (W, q) features; all NaN when the group's stream is missing.
    """
    w = grid_start.size
    span = max(n, int(round(span_s * rate_hz)))
    lo = grid_start + (n - span) // 2
    out: dict[str, FloatArray] = {}
    if "ctx_acc" in groups:
        acc = grid.get("acc")
        if acc is None or acc.shape[0] == 0:
            out["ctx_acc"] = np.full((w, 3), np.nan)
        else:
            k_g = max(n, int(round(gravity_span_s * rate_hz)))
            g = np.column_stack([moving_average(acc[:, i], k_g) for i in range(3)])
            g_mag = np.linalg.norm(g, axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                avert = np.einsum("ki,ki->k", acc, g) / g_mag - g_mag
            lp = moving_average(avert, max(1, int(round(rate_hz))))
            mx, mn = span_extrema(lp, lo, span)
            anorm = np.linalg.norm(acc, axis=1)
            s1, c = span_sums(anorm, lo, lo + span)
            s2, _ = span_sums(anorm * anorm, lo, lo + span)
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = s1 / c
                std = np.sqrt(np.maximum(s2 / c - mean * mean, 0.0))
            std = np.where(c >= 0.5 * span, std, np.nan)
            out["ctx_acc"] = np.column_stack([mx, mn, std])
    if "ctx_mag" in groups:
        mag = grid.get("mag")
        if mag is None or mag.shape[0] == 0:
            out["ctx_mag"] = np.full((w, 2), np.nan)
        else:
            mnorm = moving_average(np.linalg.norm(mag, axis=1), n)
            win = mnorm[np.clip(grid_start + n // 2, 0, mnorm.size - 1)]
            mx, mn = span_extrema(mnorm, lo, span)
            with np.errstate(invalid="ignore", divide="ignore"):
                out["ctx_mag"] = np.column_stack([np.log(win / mx), np.log(win / mn)])
    if "ctx_baro" in groups:
        baro = grid.get("baro")
        if baro is None or baro.shape[0] == 0:
            out["ctx_baro"] = np.full((w, 2), np.nan)
        else:
            short = max(n, int(round(baro_span_s * rate_hz)))
            lo_s = grid_start + (n - short) // 2
            out["ctx_baro"] = np.column_stack([span_slope(baro[:, 0], lo_s, short, rate_hz),
                                               span_slope(baro[:, 0], lo, span, rate_hz)])
    return out
