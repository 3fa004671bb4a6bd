"""Quantiles of the chi-square distribution, computed with :mod:`math` alone.

The heading smoother's consistency checks need one or two quantiles per walk; importing :mod:`scipy.special` for
them cost a one-shot ``pdr track`` process about 0.1 s. ``chi2_quantile(q, k)`` solves ``P(k/2, x/2) = q`` for
``x``, ``P`` the regularised lower incomplete gamma function (series below ``a + 1``, Lentz's continued fraction
for the upper tail above), by Newton steps kept inside a bracket. It agrees with ``scipy.stats.chi2.ppf`` to
1e-13 relative for 1e-6 <= q <= 0.999 and up to a few thousand degrees of freedom (``tests/pdr/test_chi_square.py``;
further into the upper tail ``1 - q`` itself loses digits).
"""

from __future__ import annotations

import math

_EPS = 1e-16
_TINY = 1e-300


def _gamma_regularised(a: float, x: float) -> tuple[float, float]:
    """``(P(a, x), Q(a, x))``, the regularised lower and upper incomplete gamma functions (a > 0, x >= 0), each
    computed directly where it is the smaller (the other as its complement).
    """
    if x <= 0.0:
        return 0.0, 1.0
    log_front = -x + a * math.log(x) - math.lgamma(a)
    if x < a + 1.0:
        term = total = 1.0 / a
        n = a
        while abs(term) > abs(total) * _EPS:
            n += 1.0
            term *= x / n
            total += term
        p = total * math.exp(log_front)
        return p, 1.0 - p
    # Upper tail by the modified Lentz continued fraction.
    b = x + 1.0 - a
    c = 1.0 / _TINY
    d = 1.0 / b
    h = d
    for i in range(1, 10_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = b + an / c
        c = c if abs(c) > _TINY else _TINY
        step = d * c
        h *= step
        if abs(step - 1.0) < _EPS:
            break
    q = math.exp(log_front) * h
    return 1.0 - q, q


def chi2_quantile(q: float, dof: float) -> float:
    """The ``q`` quantile (0 <= q <= 1; 0 and infinity at the ends, as scipy gives them) of the chi-square
    distribution with ``dof`` (> 0) degrees of freedom.
    """
    if not (0.0 <= q <= 1.0 and dof > 0.0):
        raise ValueError(f"chi2_quantile needs 0 <= q <= 1 and dof > 0, got q={q}, dof={dof}")
    if q in (0.0, 1.0):
        return 0.0 if q == 0.0 else math.inf
    a = 0.5 * dof
    upper = q > 0.5                      # solve on the smaller tail: Q(a, y) = 1 - q there
    target = 1.0 - q if upper else q
    # Start: Wilson-Hilferty, or the small-y limit P(a, y) ~ y^a / Gamma(a + 1).
    z = _normal_quantile(q)
    h = 2.0 / (9.0 * dof)
    y = 0.5 * dof * max(1.0 - h + z * math.sqrt(h), 0.0) ** 3
    if y <= 1e-3 * a:      # Wilson-Hilferty fails in the far lower tail of few degrees of freedom
        y = math.exp((math.log(q) + math.lgamma(a + 1.0)) / a)
    lo, hi = 0.0, math.inf
    for _ in range(400):
        p_lower, p_upper = _gamma_regularised(a, y)
        below = p_lower < q
        lo, hi = (y, hi) if below else (lo, y)
        # Newton on the solved tail: d P / dy = -d Q / dy = y^(a-1) e^-y / Gamma(a).
        density = math.exp(-y + (a - 1.0) * math.log(y) - math.lgamma(a))
        residual = (target - p_upper) if upper else (p_lower - target)
        nxt = y - residual / density if density > 0.0 else math.nan
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * y
        if abs(nxt - y) <= 4e-16 * y:
            return 2.0 * nxt
        y = nxt
    return 2.0 * y


def _normal_quantile(q: float) -> float:
    """The standard normal ``q`` quantile (:class:`statistics.NormalDist`)."""
    from statistics import NormalDist
    return NormalDist().inv_cdf(q)
