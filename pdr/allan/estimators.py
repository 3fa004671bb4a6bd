"""Allan-variance estimators on uniformly sampled rate data, vectorised with cumulative sums.

Input ``samples`` is a sensor output ``y`` (angular rate in rad/s, specific force in m/s^2, or any
unit ``u``) sampled at ``rate_hz``; results are variances in ``u^2`` at averaging times
``tau = m / rate_hz``. All three estimators are written on the "phase" ``x_j = sum_{i<j} y_i``
(``n + 1`` points, ``x_0 = 0``; the mean of ``y`` is removed first, which changes no estimate since
each is a second difference of ``x`` but keeps the sums small):

- non-overlapping, seed 004 eq. 1: ``sigma_A^2(tau) = 1 / (2 (K - 1)) sum_i (ybar_{i+1} - ybar_i)^2``
  over the ``K = floor(n / m)`` disjoint bins, ``ybar_i = (x_{(i+1)m} - x_{im}) / m``;
- overlapping (the default): the same squared difference of adjacent ``m``-bin means averaged over
  every start sample, ``sum_j (x_{j+2m} - 2 x_{j+m} + x_j)^2 / (2 m^2 (n + 1 - 2m))``;
- modified: the overlapping second differences first averaged over ``m`` starts,
  ``sum_j (sum_{i=j}^{j+m-1} (x_{i+2m} - 2 x_{i+m} + x_i))^2 / (2 m^4 (n + 2 - 3m))``.

These are the definitions of IEEE Std 952 / NIST SP 1065 and agree with allantools' ``adev``,
``oadev`` and ``mdev`` on frequency data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.allan.taus import ESTIMATOR_KINDS, averaging_factors, max_factor
from pdr.errors import InputError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Start samples per block of the overlapping estimator (32 KiB of float64: fits the L1/L2 cache; much
#: larger blocks measured 3x slower).
_BLOCK = 4096


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class AllanCurve:
    """Allan variance of one or more axes at a set of averaging times.

    Parameters
    ----------
    kind
        ``nonoverlapping`` (seed 004 eq. 1), ``overlapping`` or ``modified``.
    rate_hz
        Sampling rate of the input (Hz).
    n_samples
        Number of input samples per axis.
    m
        (K,) int64 averaging factors; ``tau_s = m / rate_hz``.
    avar
        (K, A) float64 Allan variance per averaging time and axis, in the input unit squared.
    n_terms
        (K,) int64 number of squared differences averaged at each tau.
    """

    kind: str
    rate_hz: float
    n_samples: int
    m: IntArray
    avar: FloatArray
    n_terms: IntArray

    def __post_init__(self) -> None:
        m = np.asarray(self.m, dtype=np.int64)
        avar = np.asarray(self.avar, dtype=np.float64)
        if avar.ndim == 1:
            avar = avar[:, None]
        if avar.shape[0] != m.size or np.asarray(self.n_terms).shape != m.shape:
            raise InputError(f"m {m.shape}, avar {avar.shape} and n_terms disagree in length", source="AllanCurve")
        object.__setattr__(self, "m", _readonly(m))
        object.__setattr__(self, "avar", _readonly(avar))
        object.__setattr__(self, "n_terms", _readonly(np.asarray(self.n_terms, dtype=np.int64)))

    @property
    def tau_s(self) -> FloatArray:
        """(K,) averaging times in seconds."""
        return self.m / self.rate_hz

    @property
    def adev(self) -> FloatArray:
        """(K, A) Allan deviation in the input unit."""
        return np.sqrt(self.avar)

    @property
    def n_axes(self) -> int:
        return int(self.avar.shape[1])


def as_samples(samples: ArrayLike, name: str = "samples") -> FloatArray:
    """(n, A) float64 copy of ``samples`` ((n,) or (n, A)); :class:`InputError` on NaN/inf or bad shape."""
    try:
        y = np.array(samples, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"samples are not numeric ({exc})", source=name) from None
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] == 0 or y.shape[1] == 0:
        raise InputError(f"samples must be a non-empty (n,) or (n, axes) array, got shape {y.shape}", source=name)
    bad = ~np.isfinite(y)
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        raise InputError(f"sample {row} of axis {col} is {y[row, col]}; the record must be finite "
                         f"(NaN/inf found in {int(bad.sum())} samples)", source=name)
    return y


def _phase(y: FloatArray) -> FloatArray:
    """(A, n + 1) cumulative sums of the mean-removed samples, one contiguous row per axis."""
    yc = (y - y.mean(axis=0)).T
    x = np.zeros((yc.shape[0], yc.shape[1] + 1))
    np.cumsum(yc, axis=1, out=x[:, 1:])
    return x


def _check_factors(m: ArrayLike, n: int, kind: str) -> IntArray:
    mm = np.asarray(m)
    if mm.ndim != 1 or mm.size == 0:
        raise InputError("averaging factors must be a non-empty 1-D array", field="m")
    if mm.dtype.kind == "f":
        if not np.all(np.isfinite(mm)) or np.any(mm != np.round(mm)):
            raise InputError("averaging factors must be whole numbers of samples", field="m")
    mi = mm.astype(np.int64)
    if np.any(mi < 1):
        raise InputError("averaging factors must be >= 1", field="m")
    cap = max_factor(n, kind)
    if np.any(mi > cap):
        raise InputError(f"averaging factor {int(mi.max())} needs more than the {n} samples of the record "
                         f"(largest possible for the {kind} estimator: {cap})", field="m")
    return mi


def avar_nonoverlapping(samples: ArrayLike, m: ArrayLike) -> tuple[FloatArray, IntArray]:
    """Non-overlapping Allan variance, seed 004 eq. 1.

    Parameters
    ----------
    samples
        (n,) or (n, A) uniformly sampled sensor output, unit ``u``.
    m
        (K,) averaging factors (samples per bin, ``tau = m / rate``).

    Returns
    -------
    avar
        (K, A) variance in ``u^2``.
    n_terms
        (K,) number of differences ``K_bins - 1``.
    """
    y = as_samples(samples)
    mi = _check_factors(m, y.shape[0], "nonoverlapping")
    x = _phase(y)
    n = y.shape[0]
    out = np.empty((mi.size, y.shape[1]))
    terms = np.empty(mi.size, dtype=np.int64)
    for k, mk in enumerate(mi):
        bins = n // mk
        ybar = np.diff(x[:, : bins * mk + 1 : mk], axis=1) / mk  # bin means, eq. 1's ybar_tau(i)
        d = np.diff(ybar, axis=1)
        out[k] = np.einsum("ij,ij->i", d, d) / (2.0 * (bins - 1))  # eq. 1
        terms[k] = bins - 1
    return out, terms


def avar_overlapping(samples: ArrayLike, m: ArrayLike) -> tuple[FloatArray, IntArray]:
    """Overlapping Allan variance (all ``n + 1 - 2m`` start samples); same arguments as eq. 1's.

    The sums run over blocks of :data:`_BLOCK` start samples, every averaging factor per block, so that
    the three phase slices and the difference buffer stay in the processor cache: the work is one pass
    of O(n) per tau either way, but from cache it runs about twice as fast as on whole arrays.
    """
    y = as_samples(samples)
    mi = _check_factors(m, y.shape[0], "overlapping")
    x = _phase(y)
    n_phase = x.shape[1]
    n_terms = n_phase - 2 * mi
    sums = np.zeros((mi.size, y.shape[1]))
    buf = np.empty(_BLOCK)
    for a in range(x.shape[0]):
        xa = x[a]
        for start in range(0, int(n_terms.max()), _BLOCK):
            for k in np.flatnonzero(n_terms > start):
                mk = int(mi[k])
                stop = min(start + _BLOCK, int(n_terms[k]))
                d = buf[: stop - start]
                np.subtract(xa[start + 2 * mk:stop + 2 * mk], xa[start + mk:stop + mk], out=d)
                d -= xa[start + mk:stop + mk]
                d += xa[start:stop]
                sums[k, a] += np.dot(d, d)
    return sums / (2.0 * mi.astype(np.float64)[:, None] ** 2 * n_terms[:, None]), n_terms.astype(np.int64)


def avar_modified(samples: ArrayLike, m: ArrayLike) -> tuple[FloatArray, IntArray]:
    """Modified Allan variance (second differences averaged over ``m`` starts); same arguments."""
    y = as_samples(samples)
    mi = _check_factors(m, y.shape[0], "modified")
    x = _phase(y)
    n_phase = x.shape[1]
    out = np.empty((mi.size, y.shape[1]))
    for a in range(x.shape[0]):
        xa = x[a]
        for k, mk in enumerate(mi):
            d2 = xa[2 * mk:] - 2.0 * xa[mk:n_phase - mk] + xa[: n_phase - 2 * mk]
            c = np.zeros(d2.size + 1)
            np.cumsum(d2, out=c[1:])
            s = c[mk:] - c[:-mk]  # sums of m consecutive second differences
            out[k, a] = np.dot(s, s) / (2.0 * float(mk) ** 4 * s.size)
    return out, (n_phase - 3 * mi + 1).astype(np.int64)


_ESTIMATORS = {"nonoverlapping": avar_nonoverlapping, "overlapping": avar_overlapping, "modified": avar_modified}


def allan_curve(samples: ArrayLike, rate_hz: float, *, kind: str = "overlapping", m: ArrayLike | None = None,
                per_decade: float = 6.0, tau_min_s: float | None = None, tau_max_s: float | None = None,
                all_taus: bool = False) -> AllanCurve:
    """Allan variance of ``samples`` at log-spaced (or given) averaging times.

    Parameters
    ----------
    samples
        (n,) or (n, A) uniformly sampled sensor output (rad/s, m/s^2, ...); must be finite.
    rate_hz
        Sampling rate in Hz.
    kind
        ``overlapping`` (default), ``nonoverlapping`` (seed 004 eq. 1) or ``modified``.
    m
        Explicit averaging factors; otherwise chosen by :func:`pdr.allan.taus.averaging_factors` from
        ``per_decade``, ``tau_min_s``, ``tau_max_s`` and ``all_taus``.
    """
    if kind not in ESTIMATOR_KINDS:
        raise InputError(f"unknown estimator '{kind}'; expected one of {ESTIMATOR_KINDS}", field="kind")
    y = as_samples(samples)
    if not np.isfinite(rate_hz) or rate_hz <= 0:
        raise InputError(f"sampling rate must be positive and finite, got {rate_hz}", field="rate_hz")
    if m is None:
        mi = averaging_factors(y.shape[0], rate_hz, per_decade=per_decade, tau_min_s=tau_min_s,
                               tau_max_s=tau_max_s, all_taus=all_taus, kind=kind)
    else:
        mi = _check_factors(m, y.shape[0], kind)
    avar, terms = _ESTIMATORS[kind](y, mi)
    return AllanCurve(kind=kind, rate_hz=float(rate_hz), n_samples=int(y.shape[0]), m=mi, avar=avar,
                      n_terms=terms)
