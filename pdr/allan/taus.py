"""Averaging times: integer averaging factors ``m`` with ``tau = m / rate_hz``."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

IntArray = NDArray[np.int64]

#: Largest m each estimator can evaluate for n samples (needs >= 1 difference term).
ESTIMATOR_KINDS = ("nonoverlapping", "overlapping", "modified")


def max_factor(n_samples: int, kind: str) -> int:
    """Largest averaging factor ``m`` the estimator ``kind`` can evaluate on ``n_samples`` rate samples.

    Non-overlapping (seed 004 eq. 1) needs two bins (``2m <= n``); overlapping needs one second
    difference of the ``n + 1`` phase points (``2m <= n``); modified needs ``3m <= n + 1``.
    """
    if kind == "modified":
        return (n_samples + 1) // 3
    if kind in ("overlapping", "nonoverlapping"):
        return n_samples // 2
    raise InputError(f"unknown estimator '{kind}'; expected one of {ESTIMATOR_KINDS}", field="kind")


def averaging_factors(n_samples: int, rate_hz: float, *, per_decade: float = 6.0, tau_min_s: float | None = None,
                      tau_max_s: float | None = None, all_taus: bool = False, kind: str = "overlapping",
                      max_fraction: float = 0.25) -> IntArray:
    """Averaging factors ``m`` (sorted, unique, >= 1) for a record of ``n_samples`` at ``rate_hz``.

    Parameters
    ----------
    n_samples, rate_hz
        Record length (samples) and sampling rate (Hz).
    per_decade
        Density of the log-spaced grid: points per decade of tau (duplicates after rounding to
        integer m are removed, so short taus have fewer).
    tau_min_s, tau_max_s
        Requested range in seconds. Default: one sample period to ``max_fraction`` of the record.
        An explicit ``tau_max_s`` the record cannot support raises :class:`InputError`.
    all_taus
        Every integer m in the range (cost grows as n * m_max; use for short records).
    kind
        Estimator the factors are for (sets the largest possible m).
    max_fraction
        Default largest tau as a fraction of the record length.

    Returns
    -------
    (K,) int64 averaging factors.
    """
    if n_samples < 4:
        raise InputError(f"record has {n_samples} samples; at least 4 are needed for an Allan variance",
                         field="samples")
    if not np.isfinite(rate_hz) or rate_hz <= 0:
        raise InputError(f"sampling rate must be positive and finite, got {rate_hz}", field="rate_hz")
    if not np.isfinite(per_decade) or per_decade <= 0:
        raise InputError(f"taus per decade must be positive, got {per_decade}", field="per_decade")
    m_cap = max_factor(n_samples, kind)
    duration_s = n_samples / rate_hz
    if tau_max_s is None:
        m_hi = max(1, min(m_cap, int(np.floor(max_fraction * n_samples))))
    else:
        m_hi = int(np.floor(tau_max_s * rate_hz + 1e-9))
        if m_hi > m_cap:
            raise InputError(
                f"record of {duration_s:.6g} s ({n_samples} samples at {rate_hz:g} Hz) is too short for "
                f"tau = {tau_max_s:g} s with the {kind} estimator (longest possible: {m_cap / rate_hz:.6g} s)",
                field="tau_max_s")
    m_lo = 1 if tau_min_s is None else max(1, int(np.ceil(tau_min_s * rate_hz - 1e-9)))
    if m_lo > m_hi:
        raise InputError(f"no averaging time between {m_lo / rate_hz:g} s and {m_hi / rate_hz:g} s "
                         f"for this record", field="tau_min_s")
    if all_taus:
        return np.arange(m_lo, m_hi + 1, dtype=np.int64)
    n_pts = max(2, int(np.ceil(np.log10(m_hi / m_lo) * per_decade)) + 1)
    m = np.unique(np.round(np.logspace(np.log10(m_lo), np.log10(m_hi), n_pts)).astype(np.int64))
    return m[(m >= m_lo) & (m <= m_hi)]
