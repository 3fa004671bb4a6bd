"""Per-stride gait features of a thigh-carried phone: leg pitch (seed 003 eqs. 1-3) and vertical motion.

Stairs and level walking differ in how the thigh swings and how the body rises and falls in each stride:
climbing lifts the knee high and pushes the body up while the stance thigh extends; descending lowers the
body under control and lands it. These features measure that, per window (W, n samples at ``rate_hz``):

* the specific force is carried into the frame of the window's first sample by the gyro-integrated attitude
  (:func:`classifiers.feature_kernels.rotate_to_first`), so the vertical (the mean specific-force direction
  ``u`` in that frame) no longer swings with the thigh; ``a_v = f . u - |g|`` and the horizontal part
  ``a_h`` (m/s^2); ``a_f`` is ``a_h`` along its principal axis (the swing direction, sign arbitrary);
* displacements by double integration with the window's mean acceleration, mean velocity and linear drift
  removed (a stride's net velocity and climb are not observable from acceleration; what is left is the
  phone's excursion about its mean path, m);
* the leg-pitch rate ``r`` is the angular rate about the principal axis of the window's rate covariance
  (the hip's flexion axis, seed 003 eq. 1), signed so that its skewness is non-negative: the faster
  direction -- the swing's flexion -- is positive; its integral, linearly detrended, is the pitch (rad).

Features (:data:`STRIDE_FEATURES`):

``stride_period_s``, ``stride_regularity``
    Lag (s) of the autocorrelation peak of ``r`` between :data:`STRIDE_MIN_S` and :data:`STRIDE_MAX_S` (one
    thigh swing per stride) and the normalised autocorrelation there.
``stride_z_range_m``, ``stride_h_range_m``
    Peak-to-peak vertical and swing-direction displacement within one stride (mean over stride-long
    segments a quarter stride apart, m): the knee lift on stairs.
``stride_vh_log_energy``, ``stride_zh_log_disp``
    log10 of var(a_v) / var(a_h) and of std(z) / std(x_f): how vertical the motion is.
``stride_pitch_range_rad``
    Pitch range within one stride (eq. 1's opening angle per stride, rad).
``stride_vz_skew``
    Skewness of the vertical velocity: climbing pushes up in short strong phases (positive), descending
    lowers the body evenly and drops onto the step (near zero or negative).
``stride_swing_duty``
    Fraction of the window with ``r > 0`` (the thigh turning in its fast direction): swing against stance.
``stride_pitch_asym``
    ``(Pitch_max - |Pitch_min|) / (Pitch_max + |Pitch_min|)`` of the signed pitch (eqs. 2-3): flexion
    against extension.
``stride_vz_rate_corr``
    Correlation of the vertical velocity with ``r``: on stairs up the body rises while the stance thigh
    extends.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from classifiers import feature_kernels as kernels

FloatArray = NDArray[np.float64]

STRIDE_FEATURES: tuple[str, ...] = (
    "stride_period_s", "stride_regularity", "stride_z_range_m", "stride_h_range_m", "stride_vh_log_energy",
    "stride_zh_log_disp", "stride_pitch_range_rad", "stride_vz_skew", "stride_swing_duty", "stride_pitch_asym",
    "stride_vz_rate_corr")

#: Shortest and longest stride (s, two steps): a sprint's ~4.5 steps/s to a slow climb's ~1 step/s.
STRIDE_MIN_S = 0.45
STRIDE_MAX_S = 2.0


def principal_rate(gyro: FloatArray) -> FloatArray:
    """Angular rate (rad/s) about the principal axis of each window's rate covariance; (W, n, 3) -> (W, n).

    The axis's sign is that of the eigenvector (arbitrary); NaN-free input.
    """
    n = gyro.shape[1]
    _, vecs = np.linalg.eigh(gyro.transpose(0, 2, 1) @ gyro / n)
    return _along(gyro, vecs[:, :, -1])


def _along(x: FloatArray, axis: FloatArray) -> FloatArray:
    """Components (W, n) of (W, n, 3) vectors along one (W, 3) axis per window (a batched matrix product)."""
    return np.asarray((x @ axis[:, :, None])[:, :, 0])


def detrend(x: FloatArray) -> FloatArray:
    """Rows of ``x`` (W, n) with their mean and least-squares linear trend removed."""
    tc = np.arange(x.shape[1], dtype=np.float64)
    tc -= tc.mean()
    x = x - x.mean(axis=1, keepdims=True)
    return np.asarray(x - (x @ tc / (tc @ tc))[:, None] * tc[None, :])


def _integrate(a: FloatArray, rate_hz: float) -> tuple[FloatArray, FloatArray]:
    """Displacement and velocity (detrended) of an acceleration (W, n), m/s^2 -> (m, m/s)."""
    v = detrend(np.cumsum(a - a.mean(axis=1, keepdims=True), axis=1) / rate_hz)
    return detrend(np.cumsum(v, axis=1) / rate_hz), v


def _skew(x: FloatArray) -> FloatArray:
    xc = x - x.mean(axis=1, keepdims=True)
    var = np.einsum("wn,wn->w", xc, xc) / x.shape[1]
    return np.asarray(np.einsum("wn,wn,wn->w", xc, xc, xc) / x.shape[1] / np.maximum(var, 1e-24) ** 1.5)


def _corr(a: FloatArray, b: FloatArray) -> FloatArray:
    a = a - a.mean(axis=1, keepdims=True)
    b = b - b.mean(axis=1, keepdims=True)
    den = np.sqrt(np.einsum("wn,wn->w", a, a) * np.einsum("wn,wn->w", b, b))
    return np.asarray(np.einsum("wn,wn->w", a, b) / np.maximum(den, 1e-24))


def stride_period(r: FloatArray, rate_hz: float) -> tuple[FloatArray, FloatArray]:
    """Stride period (s) and regularity of each row of ``r`` (W, n): the autocorrelation peak's lag and value."""
    w, n = r.shape
    xc = r - r.mean(axis=1, keepdims=True)
    n_fft = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.fft.rfft(xc, n_fft, axis=1)
    ac = np.fft.irfft(spec.real ** 2 + spec.imag ** 2, n_fft, axis=1)[:, :n]
    ac = ac / np.maximum(ac[:, :1], 1e-24)
    lo = max(1, int(round(STRIDE_MIN_S * rate_hz)))
    hi = min(n - 1, int(round(STRIDE_MAX_S * rate_hz)))
    lag = lo + np.argmax(ac[:, lo:hi], axis=1)
    return lag / rate_hz, ac[np.arange(w), lag]


def per_stride_range(x: FloatArray, stride_samples: NDArray[np.int64]) -> FloatArray:
    """Mean peak-to-peak of each row of ``x`` (W, n) over segments one stride long, a quarter stride apart."""
    w, n = x.shape
    out = np.empty(w)
    lengths = np.clip(stride_samples, 2, n)
    for length in np.unique(lengths):
        rows = np.flatnonzero(lengths == length)
        seg = np.lib.stride_tricks.sliding_window_view(x[rows], int(length), axis=1)[:, ::max(1, int(length) // 4)]
        out[rows] = (seg.max(axis=2) - seg.min(axis=2)).mean(axis=1)
    return out


def stride_features(f_b: FloatArray, gyro: FloatArray, rate_hz: float) -> FloatArray:
    """The :data:`STRIDE_FEATURES` of each window; (W, n, 3) specific force (m/s^2) and rate (rad/s), body
    frame, NaN-free -> (W, 11).
    """
    w, n, _ = f_b.shape
    f0 = kernels.rotate_to_first(np.ascontiguousarray(f_b), np.ascontiguousarray(gyro), 1.0 / rate_hz)
    g_vec = f0.mean(axis=1)
    g_mag = np.sqrt(np.einsum("wi,wi->w", g_vec, g_vec))
    u = g_vec / np.where(g_mag > 0, g_mag, 1.0)[:, None]
    along = _along(f0, u)
    a_v = along - g_mag[:, None]
    a_h = f0 - along[:, :, None] * u[:, None, :]
    a_h -= a_h.mean(axis=1, keepdims=True)
    _, h_vecs = np.linalg.eigh(a_h.transpose(0, 2, 1) @ a_h / n)
    a_f = _along(a_h, h_vecs[:, :, -1])
    z, v_z = _integrate(a_v, rate_hz)
    x_f, _ = _integrate(a_f, rate_hz)
    r = principal_rate(gyro)
    r *= np.where(_skew(r) < 0, -1.0, 1.0)[:, None]
    pitch = detrend(np.cumsum(r, axis=1) / rate_hz)
    period, regularity = stride_period(r, rate_hz)
    stride_n = np.round(period * rate_hz).astype(np.int64)
    p_max, p_min = pitch.max(axis=1), -pitch.min(axis=1)
    e_h = np.square(a_h).sum(axis=(1, 2)) / n
    return np.column_stack([
        period, regularity, per_stride_range(z, stride_n), per_stride_range(x_f, stride_n),
        np.log10((a_v.var(axis=1) + 1e-6) / (e_h + 1e-6)),
        np.log10((z.std(axis=1) + 1e-6) / (x_f.std(axis=1) + 1e-6)),
        per_stride_range(pitch, stride_n), _skew(v_z), (r > 0).mean(axis=1),
        (p_max - p_min) / np.maximum(p_max + p_min, 1e-12), _corr(v_z, r)])
