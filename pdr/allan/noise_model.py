"""The IEEE inertial noise model and its weighted non-negative least-squares fit.

``AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2``
(IEEE Std 952-1997 Annex C; seed 004 Sec. 2.1.2 reads N, B and K off the same curve): quantisation Q,
white noise N (angle / velocity random walk), bias instability B (flicker, 1/f noise), rate random
walk K and rate ramp R. For a gyro in rad/s: Q [rad], N [rad/s/sqrt(Hz)] = [rad/sqrt(s)], B [rad/s],
K [rad/s/sqrt(s)], R [rad/s^2]; for an accelerometer replace rad by m/s.

The model is linear in ``theta = (Q^2, N^2, B^2, K^2, R^2) >= 0``. Each point is weighted by the
standard deviation of its estimate, ``model(tau) sqrt(2 / edf(tau))``, with the EDF of the term that
dominates there (iteratively reweighted; :mod:`pdr.allan.confidence`). A term counts as resolved
only if it is positive, significant (``theta / se >= min_significance``) and visibly shapes the curve
(at least ``min_share`` of the model at some tau); otherwise its value is ``None`` and an upper bound
consistent with the measured curve is given instead.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls

from pdr.allan.confidence import ALPHA_OF_TERM, ONE_SIGMA, chi2_interval
from pdr.errors import InputError

FloatArray = NDArray[np.float64]

TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")
#: ADEV of a pure flicker floor relative to B: sqrt(2 ln 2 / pi) = 0.664.
FLICKER_FACTOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))
_SLOPE_NAME = {"Q": "-1", "N": "-1/2", "B": "0", "K": "+1/2", "R": "+1"}


def model_columns(tau_s: ArrayLike) -> FloatArray:
    """(K, 5) design matrix: AVAR contributions per unit of (Q^2, N^2, B^2, K^2, R^2) at each tau."""
    t = np.asarray(tau_s, dtype=np.float64)
    return np.column_stack([3.0 / t**2, 1.0 / t, np.full_like(t, FLICKER_FACTOR**2), t / 3.0, t**2 / 2.0])


def model_avar(tau_s: ArrayLike, terms: Mapping[str, float | None]) -> FloatArray:
    """AVAR of the noise model at ``tau_s`` for term values (SI); ``None`` terms count as zero."""
    theta = np.array([(terms.get(k) or 0.0) ** 2 for k in TERMS])
    return model_columns(tau_s) @ theta


@dataclass(frozen=True)
class NoiseFit:
    """Result of :func:`fit_noise_model` for one axis.

    ``value[k]`` is the term in SI units, ``None`` when not resolved; ``estimate[k]`` the fitted value
    even when unresolved; ``std_error[k]`` its 1-sigma standard error (``None`` for a zero term);
    ``upper_bound[k]`` the largest value the measured curve allows (upper confidence limit);
    ``reason[k]`` why an unresolved term is not reported. ``model`` is the fitted AVAR at the curve's
    taus, ``dominant`` the term that dominates it there, ``edf`` the EDF used for each point, and
    ``chi2_reduced`` the weighted residual sum of squares per degree of freedom (~1 for a good fit,
    treating taus as independent although neighbouring overlapping estimates are correlated).
    """

    value: Mapping[str, float | None]
    estimate: Mapping[str, float]
    std_error: Mapping[str, float | None]
    upper_bound: Mapping[str, float]
    share: Mapping[str, float]
    resolved: Mapping[str, bool]
    reason: Mapping[str, str]
    model: FloatArray
    dominant: tuple[str, ...]
    edf: FloatArray
    chi2_reduced: float
    iterations: int
    notes: tuple[str, ...] = field(default=())


def _solve(a: FloatArray, b: FloatArray, sigma: FloatArray, use: NDArray[np.bool_]) -> FloatArray:
    aw = a / sigma[:, None]
    bw = b / sigma
    theta = np.zeros(a.shape[1])
    cols = np.flatnonzero(use)
    scale = np.linalg.norm(aw[:, cols], axis=0)
    scale[scale == 0] = 1.0
    sol, _ = nnls(aw[:, cols] / scale, bw, maxiter=50 * len(cols) + 100)
    theta[cols] = sol / scale
    return theta


def fit_noise_model(tau_s: ArrayLike, avar: ArrayLike, edf_by_alpha: Mapping[int, ArrayLike], *,
                    terms: tuple[str, ...] = TERMS, min_significance: float = 3.0, min_share: float = 0.25,
                    max_iter: int = 20, confidence: float = ONE_SIGMA, model_error: float = 0.05) -> NoiseFit:
    """Fit the IEEE noise model to one axis' Allan variance by weighted non-negative least squares.

    Parameters
    ----------
    tau_s
        (K,) averaging times in seconds.
    avar
        (K,) measured Allan variance (unit^2).
    edf_by_alpha
        Noise exponent alpha -> (K,) equivalent degrees of freedom of each point
        (:func:`pdr.allan.confidence.edf_table`).
    terms
        Terms allowed in the model (default all five).
    min_significance
        Minimum ``theta / se(theta)`` for a term to count as resolved.
    min_share
        Minimum share of the model AVAR the term must reach at some tau to count as resolved.
    max_iter
        Reweighting iterations.
    confidence
        Confidence level of the measured points' intervals used for the upper bounds.
    model_error
        Relative misfit the model is allowed at every tau on top of the estimate's own scatter
        (``sigma^2 = model^2 (2 / edf + model_error^2)``). Real sensors show structure the five terms do
        not describe (anti-alias filtering and correlation at the shortest taus, vibration, temperature);
        without this floor the points with a million degrees of freedom at short tau would decide
        every term, including those only visible at long tau.
    """
    t = np.asarray(tau_s, dtype=np.float64)
    y = np.asarray(avar, dtype=np.float64)
    if t.ndim != 1 or y.shape != t.shape:
        raise InputError(f"tau_s {t.shape} and avar {y.shape} must be matching 1-D arrays", field="avar")
    if t.size < 3:
        raise InputError(f"the noise model needs at least 3 averaging times, got {t.size}", field="tau_s")
    if not (np.all(np.isfinite(y)) and np.all(y >= 0) and np.all(t > 0)):
        raise InputError("Allan variances must be finite and non-negative at positive taus", field="avar")
    unknown = set(terms) - set(TERMS)
    if unknown:
        raise InputError(f"unknown noise terms {sorted(unknown)}; expected some of {TERMS}", field="terms")
    edf_tab = {a: np.asarray(v, dtype=np.float64) for a, v in edf_by_alpha.items()}
    alphas = np.array([ALPHA_OF_TERM[k] for k in TERMS])
    use = np.array([k in terms for k in TERMS])
    a = model_columns(t)
    floor = max(float(np.max(y)) * 1e-300, np.finfo(float).tiny)
    # Start: every point weighted as white noise around its own value.
    edf = edf_tab[0].copy()
    if not (np.isfinite(model_error) and model_error >= 0):
        raise InputError(f"model_error must be a non-negative fraction, got {model_error}", field="model_error")
    eps2 = model_error**2
    sigma = np.maximum(y, floor) * np.sqrt(2.0 / edf + eps2)
    theta = np.zeros(len(TERMS))
    iterations = 0
    while iterations < max_iter:
        iterations += 1
        new = _solve(a, y, sigma, use)
        model = a @ new
        contrib = a * new
        dom = np.argmax(contrib, axis=1)
        edf = np.choose(dom, [edf_tab[int(al)] for al in alphas])
        sigma = np.maximum(model, floor) * np.sqrt(2.0 / edf + eps2)
        converged = np.allclose(new, theta, rtol=1e-7, atol=0.0)
        theta = new
        if converged:
            break
    model = a @ theta
    contrib = a * theta
    dominant = tuple(TERMS[i] for i in np.argmax(contrib, axis=1))
    share = contrib / np.maximum(model, floor)[:, None]
    resid = (y - model) / sigma
    active = theta > 0
    dof = max(1, t.size - int(active.sum()))
    chi2_red = float(np.sum(resid**2) / dof)
    se = np.full(len(TERMS), np.nan)
    if active.any():
        aw = a[:, active] / sigma[:, None]
        try:
            cov = np.linalg.inv(aw.T @ aw)
            se[active] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        except np.linalg.LinAlgError:
            pass
    # Upper limits: the largest single-term value no measured point's upper confidence limit excludes.
    _, hi = chi2_interval(y, edf, confidence)
    upper = np.min(hi[:, None] / a, axis=0)
    value: dict[str, float | None] = {}
    estimate: dict[str, float] = {}
    std_error: dict[str, float | None] = {}
    resolved: dict[str, bool] = {}
    reason: dict[str, str] = {}
    shares: dict[str, float] = {}
    for i, k in enumerate(TERMS):
        th = float(theta[i])
        estimate[k] = float(np.sqrt(th))
        shares[k] = float(np.max(share[:, i]))
        # se of sqrt(theta) by the delta method
        std_error[k] = float(se[i] / (2.0 * np.sqrt(th))) if th > 0 and np.isfinite(se[i]) else None
        why = ""
        if not use[i]:
            why = "excluded from the model"
        elif th <= 0:
            why = f"fitted as zero: no {_SLOPE_NAME[k]} slope region in the curve"
        elif shares[k] < min_share:
            why = (f"never dominates the curve (at most {100 * shares[k]:.0f} % of the Allan variance "
                   f"between {t[0]:.3g} s and {t[-1]:.3g} s)")
        elif not np.isfinite(se[i]) or th < min_significance * se[i]:
            why = f"not significant (estimate {th:.3g} +- {se[i]:.3g} in variance units)"
        if why and k in ("K", "R") and use[i]:
            why += f"; the record is too short to resolve it (longest tau {t[-1]:.3g} s)"
        if why and k == "Q" and use[i]:
            why += f"; shortest tau {t[0]:.3g} s is too long to resolve it"
        resolved[k] = not why
        reason[k] = why
        value[k] = estimate[k] if not why else None
    return NoiseFit(value=value, estimate=estimate, std_error=std_error,
                    upper_bound={k: float(np.sqrt(upper[i])) for i, k in enumerate(TERMS)}, share=shares,
                    resolved=resolved, reason=reason, model=model, dominant=dominant, edf=edf,
                    chi2_reduced=chi2_red, iterations=iterations)
