"""Window features for the motion-mode, placement and landmark classifiers (seed 004 Sec. 4.2, seed 003 Sec. 3).

Every feature is computed for all windows at once (arrays ``(W, n)``). The feature vector has a fixed
layout (:func:`feature_names`); features of a sensor the recording lacks are NaN, so the same extractor
serves recordings with and without gyro, magnetometer or barometer ("degrade gracefully").

Orientation-invariant signals (accelerometer and gyro in the Android body frame, SI units):

* ``anorm``: specific-force norm ``|f|`` (m/s^2), seed 004 eq. 12;
* ``avert``: vertical dynamic acceleration ``f . u - |g|`` with ``u`` the window-mean specific-force
  direction (the gravity estimate, pointing up) and ``|g|`` its magnitude (m/s^2);
* ``ahor``: horizontal acceleration magnitude ``|f - (f . u) u|`` (m/s^2);
* ``gnorm``: angular-rate norm ``|omega|`` (rad/s); ``gvert``: angular rate about the vertical ``omega . u``;
  ``ghor``: magnitude of the horizontal angular rate (leg swing for a pocket phone).

Per signal (seed 004 Sec. 4.2): mean, variance and standard deviation, skewness, mean absolute deviation,
zero-crossing rate of the mean-removed signal (1/s), peak frequency (Hz), spectral entropy (normalised to
[0, 1]), log10 sub-band energies and their ratios to the total, and the change of the peak frequency over
4 sub-frames (max minus min, Hz; at the sub-frame's own resolution, 1.56 Hz for 0.64 s sub-frames).

Further groups:

* ``coning``: the coning feature of seed 004 eqs. 26-27 -- the largest angle (rad) between the attitude
  integrated at the full grid rate (eq. 9 with eq. 7, ``p = omega dt`` per sample) and the attitude
  obtained from the gyro averaged over blocks of ``CONING_BLOCKS`` sub-frames (eq. 27,
  ``p <- T_block * mean(omega)``), evaluated at the block ends; plus the total rotation angle (rad).
* ``mag``: magnitude mean (uT), magnitude variance (uT^2) and summed component variance (uT^2).
* ``baro``: least-squares pressure slope (hPa/s) and range (hPa) over the window.
* ``pitch``: leg-pitch pattern of seed 003 eqs. 1-3 from the tilt of the low-passed specific force about
  its principal tilt axis: opening angle ``dPitch = Pitch_max - Pitch_min`` (eq. 1), and ``Pitch_max``,
  ``-Pitch_min`` about the window mean (rad), the sign fixed so that the pitch skewness is non-negative.
* ``gyro_pitch``: the same leg-pitch pattern from the gyro: the angular rate about its principal axis
  integrated over the window and linearly detrended (rad), and the fraction of the rate variance about that
  axis.
* ``gait``: percentiles of ``avert`` (m/s^2), the gait period (s, lag of the autocorrelation peak of
  ``avert`` between 0.4 and 2 s) and its regularity (normalised autocorrelation at that lag).
* ``stride``: per-stride leg pitch and vertical motion of a thigh-carried phone in the frame of the window's
  first sample (:mod:`classifiers.stride_features`): stride period and regularity, knee-lift excursions,
  vertical against horizontal motion, the vertical velocity's skewness, swing/stance asymmetry.
* ``elevator``: extremes (m/s^2) of the 1 s moving average of ``avert`` (seed 003 level 1: the
  hyper-/hypo-gravity impulse pair of an elevator).
* ``orientation``: mean gravity direction in the body frame (unit vector components; placement only: it
  depends on how the phone is carried, not on how the person moves).
* ``ctx_acc``, ``ctx_mag``, ``ctx_baro``: context over a span longer than the window, centred on it
  (:mod:`classifiers.context`): the elevator impulse pair, the magnetic change of a cabin, the pressure
  slope over a flight of stairs. Windows need ``context_margin_s`` of grid beyond them.

Speed: all windows of a recording are processed at once; the per-row moments and the coning integration
run in compiled kernels (:mod:`classifiers.feature_kernels`), the spectra as one batched real FFT. Version 2
of the feature set (``FEATURE_SET_VERSION``) changed the sub-frame spectra and added the context groups.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from classifiers import feature_kernels as kernels
from classifiers.context import context_features
from classifiers.stride_features import STRIDE_FEATURES, stride_features
from classifiers.windows import Windows
from pdr.frames import GRAVITY_MPS2

FloatArray = NDArray[np.float64]

#: Bump when the layout or meaning of any feature changes; models record it and refuse a mismatch.
FEATURE_SET_VERSION = 2

#: Sub-band edges in Hz for the band energies (the last band is cut at the Nyquist frequency).
BAND_EDGES_HZ: tuple[float, ...] = (0.25, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 25.0)
#: Sub-frames for the peak-frequency change and the coning blocks.
SUB_FRAMES = 4
CONING_BLOCKS = 4

_SIGNAL_FEATURES: tuple[str, ...] = (
    ("mean", "var", "std", "skew", "mad", "zcr", "peak_hz", "entropy", "peak_hz_change")
    + tuple(f"band{i}_log_energy" for i in range(len(BAND_EDGES_HZ) - 1))
    + tuple(f"band{i}_ratio" for i in range(len(BAND_EDGES_HZ) - 1))
)

#: Feature groups: group name -> (stream the group needs, feature names).
FEATURE_GROUPS: Mapping[str, tuple[str, tuple[str, ...]]] = {
    "acc": ("acc", tuple(f"{s}_{f}" for s in ("anorm", "avert", "ahor") for f in _SIGNAL_FEATURES)),
    "gyro": ("gyro", tuple(f"{s}_{f}" for s in ("gnorm", "gvert", "ghor") for f in _SIGNAL_FEATURES)),
    "gait": ("acc", ("avert_p05", "avert_p25", "avert_p50", "avert_p75", "avert_p95", "gait_period_s",
                     "gait_regularity")),
    "gyro_pitch": ("gyro", ("gpitch_opening_rad", "gpitch_max_rad", "gpitch_min_neg_rad", "gyro_axis_fraction")),
    "coning": ("gyro", ("coning_rad", "rotation_rad")),
    "stride": ("gyro", STRIDE_FEATURES),
    "mag": ("mag", ("mag_mean", "mag_var", "mag_comp_var")),
    "baro": ("baro", ("baro_slope_hpa_s", "baro_range_hpa")),
    "pitch": ("acc", ("pitch_opening_rad", "pitch_max_rad", "pitch_min_neg_rad")),
    "elevator": ("acc", ("avert_lp_max", "avert_lp_min")),
    "orientation": ("acc", ("grav_dir_x", "grav_dir_y", "grav_dir_z")),
    "ctx_acc": ("acc", ("ctx_avert_lp_max", "ctx_avert_lp_min", "ctx_anorm_std")),
    "ctx_mag": ("mag", ("ctx_mag_log_ratio_max", "ctx_mag_log_ratio_min")),
    "ctx_baro": ("baro", ("ctx_baro_slope_hpa_s", "ctx_baro_slope_long_hpa_s")),
}

#: Span (s) of the context groups, centred on each window: long enough to reach outside an elevator cabin
#: from any in-cabin window of a ride of a few floors (seed 003 level 1: the impulse pair seconds apart,
#: the magnetic magnitude change at the doors).
CONTEXT_SPAN_S = 20.48
#: Span (s) of the short context pressure slope (a flight of stairs lasts ~5-15 s).
BARO_CONTEXT_SPAN_S = 7.68
#: Span (s) of the moving average that estimates gravity for the context vertical acceleration: longer
#: than an elevator's acceleration phase (~1-3 s), which it must not absorb.
GRAVITY_SPAN_S = 10.24


def context_margin_s(groups: tuple[str, ...], length_s: float) -> float:
    """Seconds of grid the ``groups`` need beyond a window of ``length_s`` on each side (0 without ctx_*).

    Half the context span beyond the window plus the support of the moving averages inside it (half the
    gravity span and 1 s), so a span never reaches the edge of a grid that has data beyond it: the
    streaming classifier, cutting its grid at batch edges, then computes the same values as an offline pass.
    """
    if not any(g.startswith("ctx_") for g in groups):
        return 0.0
    return max(0.0, 0.5 * (CONTEXT_SPAN_S - length_s)) + 0.5 * max(GRAVITY_SPAN_S, length_s) + 1.0


def feature_names(groups: tuple[str, ...] = tuple(FEATURE_GROUPS)) -> list[str]:
    """Names of the features of ``groups`` in extraction order."""
    return [name for g in groups for name in FEATURE_GROUPS[g][1]]


def _fill_nan(x: FloatArray) -> FloatArray:
    """Replace NaN samples by the window mean (windows that are all NaN stay NaN)."""
    if not np.isnan(x).any():
        return x
    with np.errstate(invalid="ignore"):
        counts = np.sum(np.isfinite(x), axis=1, keepdims=True)
        mean = np.where(counts > 0, np.nansum(x, axis=1, keepdims=True) / np.maximum(counts, 1), np.nan)
    return np.where(np.isnan(x), mean, x)


def _sample_mean(x: FloatArray) -> FloatArray:
    """Mean over the samples of (W, n, k) windows, (W, k) (a matrix product: much faster than ``mean(axis=1)``)."""
    return np.asarray(x.transpose(0, 2, 1) @ np.full(x.shape[1], 1.0 / max(1, x.shape[1])))


def _present_fraction(x: FloatArray) -> FloatArray:
    """Fraction of the samples of (W, n, k) windows with every component finite, (W,)."""
    return np.asarray(np.isfinite(x @ np.ones(x.shape[2])).mean(axis=1))


#: Specific force of a phone at rest, screen up (m/s^2, body frame): the stand-in samples of an invalid window.
_AT_REST = np.array([0.0, 0.0, GRAVITY_MPS2])


def _fill_nan3(x: FloatArray) -> FloatArray:
    """:func:`_fill_nan` for (W, n, k) arrays, per component."""
    if not np.isnan(x).any():
        return x
    return np.stack([_fill_nan(x[:, :, i]) for i in range(x.shape[2])], axis=2)


def _stacked_signal_features(signals: tuple[FloatArray, ...], rate_hz: float) -> FloatArray:
    """:func:`signal_features` of several (W, n) signals in one batch; (W, F * len(signals)), signal-major."""
    w = signals[0].shape[0]
    if w == 0:
        return np.zeros((0, len(_SIGNAL_FEATURES) * len(signals)))
    f = signal_features(np.concatenate(signals, axis=0), rate_hz)
    return np.asarray(f.reshape(len(signals), w, -1).transpose(1, 0, 2).reshape(w, -1))


def _next_pow2(n: int) -> int:
    return 1 << max(0, int(np.ceil(np.log2(max(n, 1)))))


def _power(tapered: FloatArray, n_fft: int) -> FloatArray:
    """One-sided power spectrum ``|FFT|^2`` of rows already mean-removed and tapered."""
    spec = np.fft.rfft(tapered, n=n_fft, axis=1)
    pairs = spec.view(np.float64).reshape(*spec.shape, 2)
    return np.asarray(np.einsum("wki,wki->wk", pairs, pairs))


def _peak_hz(power: FloatArray, df_hz: float) -> FloatArray:
    """Frequency (Hz) of the largest non-DC bin; 0 for a flat (all-zero) spectrum."""
    p = power[:, 1:]
    i = np.argmax(p, axis=1)
    return np.where(p[np.arange(p.shape[0]), i] > 0, (i + 1) * df_hz, 0.0)


def _band_matrix(n_freq: int, df_hz: float) -> FloatArray:
    """(n_freq, n_bands) 0/1 matrix summing power bins into the ``BAND_EDGES_HZ`` sub-bands."""
    edges = np.asarray(BAND_EDGES_HZ)
    band = np.searchsorted(edges, np.arange(n_freq) * df_hz, side="right") - 1
    return np.asarray((band[:, None] == np.arange(edges.size - 1)[None, :]), dtype=np.float64)


def signal_features(x: FloatArray, rate_hz: float) -> FloatArray:
    """The per-signal features of ``_SIGNAL_FEATURES`` for each row of ``x`` (W, n); returns (W, F).

    The moments, zero crossings and tapered copies come from one compiled pass per row
    (:func:`classifiers.feature_kernels.row_moments`); the spectra are one batched real FFT (zero-padded to
    a power of two), the sub-band energies one matrix product with the band mask. The sub-frame spectra
    (peak-frequency change) have the sub-frame's own resolution (1.56 Hz for 0.64 s sub-frames).
    """
    w, n = x.shape
    m = n // SUB_FRAMES
    stats, tapered, sub_tapered = kernels.row_moments(np.ascontiguousarray(_fill_nan(x), dtype=np.float64),
                                                      np.hanning(n), SUB_FRAMES, np.hanning(m))
    mean, var, skew, mad = stats[:, 0], stats[:, 1], stats[:, 2], stats[:, 3]
    std = np.sqrt(var)
    zcr = stats[:, 4] * rate_hz / (n - 1)
    n_fft = _next_pow2(n)
    df = rate_hz / n_fft
    power = _power(tapered, n_fft)
    peak = _peak_hz(power, df)
    p = power[:, 1:]
    total = p.sum(axis=1)
    tot_safe = np.where(total > 0, total, 1.0)
    # Spectral entropy -sum(q log q) with q = p / total, as log(total) - sum(p log p) / total.
    plogp = np.einsum("wk,wk->w", p, np.log(np.maximum(p, 1e-300)))
    ent = np.where(total > 0, (np.log(tot_safe) - plogp / tot_safe) / np.log(p.shape[1]), 0.0)
    # Energies per unit time of the tapered signal (the scale is arbitrary but fixed).
    band_e = power @ _band_matrix(power.shape[1], df) / (n * n_fft)
    log_e = np.log10(band_e + 1e-12)
    band_sum = band_e.sum(axis=1)
    ratio = band_e / np.where(band_sum > 0, band_sum, 1.0)[:, None]
    n_sub = _next_pow2(m)
    sub_peak = _peak_hz(_power(sub_tapered, n_sub), rate_hz / n_sub).reshape(w, SUB_FRAMES)
    change = sub_peak.max(axis=1) - sub_peak.min(axis=1)
    return np.column_stack([mean, var, std, skew, mad, zcr, peak, ent, change, log_e, ratio])


def coning_features(gyro: FloatArray, rate_hz: float) -> FloatArray:
    """Coning feature of seed 004 eqs. 26-27 and total rotation angle; (W, n, 3) rad/s -> (W, 2) rad.

    See :func:`classifiers.feature_kernels.coning`; a few missing gyro samples are bridged by zero rate,
    windows under 90 % present get NaN.
    """
    g = np.ascontiguousarray(np.where(np.isfinite(gyro), gyro, 0.0), dtype=np.float64)
    out = np.asarray(kernels.coning(g, 1.0 / rate_hz, CONING_BLOCKS))
    out[_present_fraction(gyro) < 0.9] = np.nan
    return out


def gyro_pitch_features(gyro: FloatArray, rate_hz: float, filled: FloatArray | None = None) -> FloatArray:
    """Leg-pitch pattern (seed 003 eqs. 1-3) from the gyro; (W, n, 3) rad/s -> (W, 4).

    The rate about the principal axis of the window's angular-rate covariance is integrated and linearly
    detrended (removing a constant bias); returns the opening angle, ``Pitch_max`` and ``-Pitch_min`` about
    the mean (rad; sign fixed by non-negative skewness) and the share of the rate variance about that axis.
    ``filled`` is ``gyro`` with gaps already filled (:func:`_fill_nan3`), when the caller has it.
    """
    g = _fill_nan3(gyro) if filled is None else filled
    g = np.where(np.isfinite(g), g, 0.0)
    w, n, _ = g.shape
    cov = np.einsum("wni,wnj->wij", g, g) / n
    vals, vecs = np.linalg.eigh(cov)
    rate = np.einsum("wni,wi->wn", g, vecs[:, :, -1])
    angle = np.cumsum(rate, axis=1) / rate_hz
    t = np.arange(n, dtype=np.float64)
    tc = t - t.mean()
    angle -= angle.mean(axis=1, keepdims=True)
    slope = angle @ tc / (tc @ tc)
    angle -= slope[:, None] * tc[None, :]
    angle[np.einsum("wn,wn,wn->w", angle, angle, angle) < 0] *= -1.0
    amax, amin = angle.max(axis=1), angle.min(axis=1)
    total = vals.sum(axis=1)
    frac = np.where(total > 0, vals[:, -1] / np.where(total > 0, total, 1.0), 0.0)
    out = np.column_stack([amax - amin, amax, -amin, frac])
    out[_present_fraction(gyro) < 0.9] = np.nan
    return out


def gait_features(avert: FloatArray, rate_hz: float) -> FloatArray:
    """Percentiles of the vertical acceleration and the gait period and regularity; (W, n) -> (W, 7)."""
    w, n = avert.shape
    # Percentiles by linear interpolation between order statistics (numpy's default 'linear' method).
    srt = np.sort(avert, axis=1)
    pos = np.array([0.05, 0.25, 0.5, 0.75, 0.95]) * (n - 1)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    pct = srt[:, lo] + (pos - lo) * (srt[:, hi] - srt[:, lo])
    xc = avert - avert.mean(axis=1, keepdims=True)
    n_fft = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.fft.rfft(xc, n_fft, axis=1)
    pairs = spec.view(np.float64).reshape(*spec.shape, 2)
    ac = np.fft.irfft(np.einsum("wki,wki->wk", pairs, pairs), n_fft, axis=1)[:, :n]
    ac = ac / np.maximum(ac[:, :1], 1e-12)
    lo, hi = int(round(0.4 * rate_hz)), min(n - 1, int(round(2.0 * rate_hz)))
    lag = lo + np.argmax(ac[:, lo:hi], axis=1)
    reg = ac[np.arange(w), lag]
    return np.column_stack([pct, lag / rate_hz, reg])


def _moving_average(x: FloatArray, k: int) -> FloatArray:
    """Moving average of rows over ``k`` samples, 'valid' part only: (W, n) -> (W, n - k + 1)."""
    c = np.cumsum(np.pad(x, ((0, 0), (1, 0))), axis=1)
    return (c[:, k:] - c[:, :-k]) / k


def pitch_features(f_b: FloatArray, u: FloatArray, rate_hz: float) -> FloatArray:
    """Leg-pitch pattern (seed 003 eqs. 1-3) from the tilt of the low-passed specific force.

    Parameters
    ----------
    f_b
        (W, n, 3) specific force, body frame, m/s^2 (NaN-free).
    u
        (W, 3) window-mean specific-force direction (unit).
    rate_hz
        Sampling rate in Hz.

    Returns
    -------
    (W, 3): opening angle ``Pitch_max - Pitch_min`` (eq. 1), ``Pitch_max`` and ``-Pitch_min`` relative to
    the window mean, in rad.
    """
    k = max(1, int(round(0.25 * rate_hz)))  # 0.25 s moving average: keeps the ~1-2 Hz leg swing
    c = np.cumsum(np.pad(f_b, ((0, 0), (1, 0), (0, 0))), axis=1)
    lp = (c[:, k:] - c[:, :-k]) / k
    d = lp / np.sqrt(np.einsum("wni,wni->wn", lp, lp))[:, :, None]
    # tilt = u x d: sin(angle) times the rotation axis (components written out: np.cross is slow).
    ux, uy, uz = (u[:, i, None] for i in range(3))
    dx, dy, dz = d[:, :, 0], d[:, :, 1], d[:, :, 2]
    tilt = np.stack([uy * dz - uz * dy, uz * dx - ux * dz, ux * dy - uy * dx], axis=2)
    cov = np.einsum("wni,wnj->wij", tilt, tilt) / tilt.shape[1]
    _, vecs = np.linalg.eigh(cov)
    axis = vecs[:, :, -1]
    pitch = np.arcsin(np.clip(np.einsum("wni,wi->wn", tilt, axis), -1.0, 1.0))
    pitch -= pitch.mean(axis=1, keepdims=True)
    flip = np.einsum("wn,wn,wn->w", pitch, pitch, pitch) < 0
    pitch[flip] *= -1.0
    pmax, pmin = pitch.max(axis=1), pitch.min(axis=1)
    return np.column_stack([pmax - pmin, pmax, -pmin])


def extract_features(win: Windows, groups: tuple[str, ...] = tuple(FEATURE_GROUPS)) -> FloatArray:
    """Feature matrix (W, F) of ``groups`` in the order of :func:`feature_names`; NaN for missing sensors.

    Parameters
    ----------
    win
        Windows of resampled data (:func:`classifiers.windows.make_windows`).
    groups
        Feature groups to compute (keys of :data:`FEATURE_GROUPS`).
    """
    n_win = len(win)
    rate = win.rate_hz
    out: dict[str, FloatArray] = {}
    acc = win.get("acc")
    if acc is None:
        acc = np.full((n_win, 1, 3), np.nan)
    # A window without one accelerometer sample (a gap longer than a window) stays NaN after filling, which the
    # per-window eigendecompositions (pitch, stride) refuse; it is invalid, so its features are NaN below whatever
    # it holds: a phone at rest stands in for it.
    f_b = _fill_nan3(acc)
    if not win.valid.all():
        f_b = np.where(np.isfinite(f_b) | win.valid[:, None, None], f_b, _AT_REST)
    g_vec = _sample_mean(f_b)
    g_mag = np.sqrt(np.einsum("wi,wi->w", g_vec, g_vec))
    u = g_vec / np.where(g_mag > 0, g_mag, 1.0)[:, None]
    along = np.einsum("wni,wi->wn", f_b, u)
    if "acc" in groups:
        # |f - (f.u) u|^2 = |f|^2 - (f.u)^2 for the unit vertical u.
        anorm2 = np.einsum("wni,wni->wn", f_b, f_b)
        ahor = np.sqrt(np.maximum(anorm2 - along * along, 0.0))
        out["acc"] = _stacked_signal_features((np.sqrt(anorm2), along - g_mag[:, None], ahor), rate)
    gyro = win.get("gyro")
    gy = None if gyro is None else _fill_nan3(gyro)
    if "gyro" in groups:
        if gy is None:
            out["gyro"] = np.full((n_win, len(FEATURE_GROUPS["gyro"][1])), np.nan)
        else:
            gnorm2 = np.einsum("wni,wni->wn", gy, gy)
            gv = np.einsum("wni,wi->wn", gy, u)
            gh = np.sqrt(np.maximum(gnorm2 - gv * gv, 0.0))
            out["gyro"] = _stacked_signal_features((np.sqrt(gnorm2), gv, gh), rate)
    if "gyro_pitch" in groups:
        out["gyro_pitch"] = (np.full((n_win, 4), np.nan) if gyro is None or gy is None
                             else gyro_pitch_features(gyro, rate, filled=gy))
    if "gait" in groups:
        out["gait"] = gait_features(along - g_mag[:, None], rate)
    if "coning" in groups:
        out["coning"] = (np.full((n_win, 2), np.nan) if gyro is None else coning_features(gyro, rate))
    if "stride" in groups:
        if gyro is None or gy is None:
            out["stride"] = np.full((n_win, len(STRIDE_FEATURES)), np.nan)
        else:
            out["stride"] = stride_features(f_b, np.where(np.isfinite(gy), gy, 0.0), rate)
            out["stride"][_present_fraction(gyro) < 0.9] = np.nan
    if "mag" in groups:
        mag = win.get("mag")
        if mag is None:
            out["mag"] = np.full((n_win, 3), np.nan)
        else:
            m3 = _fill_nan3(mag)
            mnorm = np.sqrt(np.einsum("wni,wni->wn", m3, m3))
            mc = m3 - _sample_mean(m3)[:, None, :]
            out["mag"] = np.column_stack([mnorm.mean(axis=1), mnorm.var(axis=1),
                                          np.einsum("wni,wni->w", mc, mc) / m3.shape[1]])
    if "baro" in groups:
        baro = win.get("baro")
        out["baro"] = np.full((n_win, 2), np.nan) if baro is None else _baro_features(baro[:, :, 0], rate)
    if "pitch" in groups:
        out["pitch"] = pitch_features(f_b, u, rate)
    if "elevator" in groups:
        lp = _moving_average(along - g_mag[:, None], max(1, int(round(rate))))
        out["elevator"] = np.column_stack([lp.max(axis=1), lp.min(axis=1)])
    if "orientation" in groups:
        out["orientation"] = u
    ctx = tuple(g for g in groups if g.startswith("ctx_"))
    if ctx:
        if win.grid_start.size == n_win and win.grid:
            out.update(context_features(dict(win.grid), win.grid_start, acc.shape[1], rate, ctx, CONTEXT_SPAN_S,
                                        BARO_CONTEXT_SPAN_S, GRAVITY_SPAN_S))
        else:
            out.update({g: np.full((n_win, len(FEATURE_GROUPS[g][1])), np.nan) for g in ctx})
    x = np.hstack([out[g] for g in groups]) if groups else np.zeros((n_win, 0))
    # Windows without enough accelerometer data have no features at all.
    x[~win.valid] = np.nan
    return np.asarray(x, dtype=np.float64)


def _baro_features(p: FloatArray, rate_hz: float) -> FloatArray:
    """Least-squares slope (hPa/s) and range (hPa) of each window's pressure; NaN if under half present."""
    n = p.shape[1]
    t = np.arange(n) / rate_hz
    ok = np.isfinite(p)
    cnt = ok.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        tm = np.where(ok, t, 0.0).sum(axis=1) / cnt
        pm = np.where(ok, p, 0.0).sum(axis=1) / cnt
        dt = np.where(ok, t - tm[:, None], 0.0)
        dp = np.where(ok, p - pm[:, None], 0.0)
        slope = (dt * dp).sum(axis=1) / (dt**2).sum(axis=1)
        rng = np.where(ok, p, -np.inf).max(axis=1) - np.where(ok, p, np.inf).min(axis=1)
    res = np.column_stack([slope, rng])
    res[cnt < n / 2] = np.nan
    return res
