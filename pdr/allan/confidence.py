"""Confidence intervals of Allan variances from equivalent degrees of freedom (EDF).

An Allan-variance estimate ``s^2`` is treated as ``sigma^2 chi^2_nu / nu`` with ``nu`` the EDF, so the
interval at confidence ``c`` is ``[nu s^2 / chi^2_{(1+c)/2}(nu), nu s^2 / chi^2_{(1-c)/2}(nu)]``.
The EDF follows C. Greenhall and W. Riley, "Uncertainty of stability variances based on finite
differences" (35th PTTI, 2003), eqs. 7-10: ``edf = M sz(0)^2 / sum_{|j|<M} (1 - |j|/M) sz(j/S)^2``, the
variance of a sum of ``M`` correlated squared differences, with ``sz`` the normalised autocovariance
of the differences for power-law noise ``S_y(f) ~ f^alpha``. The sum is evaluated directly (vectorised)
and, for long lags, by trapezoidal quadrature of the smooth ``sz`` instead of Greenhall's tables.

Power-law exponents of the IEEE inertial noise terms (AVAR slope ``mu = -alpha - 1``):
quantisation Q -> alpha = +2 (white phase), white rate N -> 0, bias instability B -> -1 (flicker),
rate random walk K -> -2; rate ramp R (mu = +2) is outside the AVAR's range and uses -2.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special, stats

from pdr.errors import InputError

FloatArray = NDArray[np.float64]

#: Noise exponent alpha (S_y ~ f^alpha) used for the EDF of each IEEE term.
ALPHA_OF_TERM = {"Q": 2, "N": 0, "B": -1, "K": -2, "R": -2}
ONE_SIGMA = float(special.erf(1.0 / np.sqrt(2.0)))  # 0.6827
_D = 2  # Allan variance = second difference of phase
_J_EXACT = 4000  # lags summed term by term; longer sums by quadrature


def _sw(t: FloatArray, alpha: int) -> FloatArray:
    """Greenhall eq. 7: generalised autocovariance kernel of the phase for S_y ~ f^alpha."""
    at = np.abs(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_t = np.where(at > 0, np.log(np.where(at > 0, at, 1.0)), 0.0)
    if alpha == 2:
        return -at
    if alpha == 1:
        return t**2 * log_t
    if alpha == 0:
        return at**3
    if alpha == -1:
        return -(t**4) * log_t
    if alpha == -2:
        return -(at**5)
    raise InputError(f"noise exponent alpha={alpha} not supported (expected 2, 1, 0, -1 or -2)", field="alpha")


def _sx(t: FloatArray, f: float, alpha: int) -> FloatArray:
    """Greenhall eq. 8: kernel after the averaging filter of factor F (F = inf: continuous limit)."""
    if np.isinf(f):
        return _sw(t, alpha + 2)
    return f**2 * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: FloatArray, f: float, alpha: int) -> FloatArray:
    """Greenhall eq. 9 for d = 2: autocovariance of the second differences at lag t (units of tau)."""
    return (6.0 * _sx(t, f, alpha) - 4.0 * (_sx(t - 1.0, f, alpha) + _sx(t + 1.0, f, alpha))
            + _sx(t - 2.0, f, alpha) + _sx(t + 2.0, f, alpha))


def _basic_sum(j_max: int, m_terms: float, s: float, f: float, alpha: int) -> float:
    """Greenhall eq. 10: ``sz(0)^2 + (1 - J/M) sz(J/S)^2 + 2 sum_{j=1}^{J-1} (1 - j/M) sz(j/S)^2``."""
    z0 = float(_sz(np.zeros(1), f, alpha)[0])
    zj = float(_sz(np.array([j_max / s]), f, alpha)[0])
    total = z0**2 + (1.0 - j_max / m_terms) * zj**2
    if j_max > 1:
        if j_max - 1 <= _J_EXACT:
            j = np.arange(1, j_max, dtype=np.float64)
            total += 2.0 * float(np.sum((1.0 - j / m_terms) * _sz(j / s, f, alpha) ** 2))
        else:  # smooth in j: trapezoid + end corrections (Euler-Maclaurin, first order)
            j = np.linspace(1.0, j_max - 1.0, _J_EXACT)
            g = (1.0 - j / m_terms) * _sz(j / s, f, alpha) ** 2
            total += 2.0 * (float(np.trapezoid(g, j)) + 0.5 * float(g[0] + g[-1]))
    return total


def edf_allan(alpha: int, m: int, n_phase: int, *, overlapping: bool = True, modified: bool = False) -> float:
    """Equivalent degrees of freedom of an Allan-variance estimate (Greenhall-Riley).

    Parameters
    ----------
    alpha
        Power-law exponent of the dominant noise (2, 1, 0, -1, -2; see :data:`ALPHA_OF_TERM`).
    m
        Averaging factor (tau = m / rate).
    n_phase
        Number of phase points, i.e. rate samples + 1.
    overlapping
        All start samples (overlapping / modified estimators) or disjoint bins (seed 004 eq. 1).
    modified
        Modified Allan variance.
    """
    if alpha not in (2, 1, 0, -1, -2):
        raise InputError(f"noise exponent alpha={alpha} not supported (expected 2, 1, 0, -1 or -2)", field="alpha")
    m = int(m)
    if m < 1 or n_phase < 3:
        raise InputError(f"EDF needs m >= 1 and at least 3 phase points (m={m}, n={n_phase})", field="m")
    f = 1.0 if modified else float(m)
    s = float(m) if (overlapping or modified) else 1.0
    length = m / f + m * _D
    m_terms = 1.0 + np.floor(s * (n_phase - length) / m)
    if m_terms < 1:
        raise InputError(f"record too short for m={m}", field="m")
    j_max = int(min(m_terms, (_D + 1) * s))
    r = m_terms / s
    if alpha == 2 and not modified and np.ceil(r) > _D:
        a0 = special.binom(4 * _D, 2 * _D) / special.binom(2 * _D, _D) ** 2
        return float(m_terms / (a0 - (_D / 2.0) / r))
    if not modified and alpha <= 0:
        # Our phase x_j is the exact running sum of the rate samples, i.e. the phase sampled at points,
        # not averaged over a sample interval: Greenhall's F = infinity kernel is exact here at every m
        # (his F = m, used for m(d+1) <= 100, models a phase meter that averages over one sample).
        f = np.inf
    z0 = float(_sz(np.zeros(1), f, alpha)[0])
    return float(z0**2 * m_terms / _basic_sum(j_max, m_terms, s, f, alpha))


def chi2_interval(avar: ArrayLike, edf: ArrayLike, confidence: float = ONE_SIGMA) -> tuple[FloatArray, FloatArray]:
    """Lower and upper bounds of the true variance given estimates ``avar`` with ``edf`` degrees of freedom."""
    if not 0.0 < confidence < 1.0:
        raise InputError(f"confidence must be in (0, 1), got {confidence}", field="confidence")
    v = np.asarray(avar, dtype=np.float64)
    nu = np.asarray(edf, dtype=np.float64)
    lo = v * nu / stats.chi2.ppf(0.5 + confidence / 2.0, nu)
    hi = v * nu / stats.chi2.ppf(0.5 - confidence / 2.0, nu)
    return lo, hi


def edf_table(m: ArrayLike, n_samples: int, kind: str) -> dict[int, FloatArray]:
    """EDF of every averaging factor for each alpha in :data:`ALPHA_OF_TERM` (alpha -> (K,) array)."""
    overlapping = kind != "nonoverlapping"
    modified = kind == "modified"
    out: dict[int, FloatArray] = {}
    for alpha in sorted(set(ALPHA_OF_TERM.values())):
        out[alpha] = np.array([edf_allan(alpha, int(mk), n_samples + 1, overlapping=overlapping, modified=modified)
                               for mk in np.asarray(m)])
    return out
