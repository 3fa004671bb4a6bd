"""Classic slope readings of an Allan-deviation curve (seed 004 Sec. 2.1.2; IEEE Std 952 Annex C).

- white noise N: the -1/2 line ``ADEV = N / sqrt(tau)`` through the point whose local log-log slope is
  closest to -1/2 (left of the minimum), read at tau = 1 s;
- bias instability B: the minimum of the curve divided by ``sqrt(2 ln 2 / pi) = 0.664``, at tau_min;
- rate random walk K: the +1/2 line ``ADEV = K sqrt(tau / 3)`` through the point whose slope is closest
  to +1/2 (right of the minimum), read at tau = 3 s.

A reading is ``None`` when the curve has no region with that slope (within ``slope_tolerance``) or,
for B, when the minimum lies at an end of the curve (the record does not show the floor).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from pdr.allan.noise_model import FLICKER_FACTOR
from pdr.errors import InputError


@dataclass(frozen=True)
class SlopeReadings:
    """Slope readings of one axis (SI units); ``tau_*_s`` locate the point each was read from."""

    N: float | None
    B: float | None
    K: float | None
    tau_n_s: float | None
    tau_min_s: float
    adev_min: float
    tau_k_s: float | None
    notes: tuple[str, ...]


def local_slopes(tau_s: ArrayLike, adev: ArrayLike) -> np.ndarray:
    """(K,) log-log slope d log(adev) / d log(tau) by central differences."""
    t = np.log(np.asarray(tau_s, dtype=np.float64))
    d = np.log(np.asarray(adev, dtype=np.float64))
    return np.gradient(d, t)


def read_slopes(tau_s: ArrayLike, adev: ArrayLike, slope_tolerance: float = 0.15, edf: ArrayLike | None = None,
                min_edf: float = 10.0) -> SlopeReadings:
    """Read N, B and K from the curve the classic way (see module docstring).

    With ``edf`` given, the minimum is searched only among points with at least ``min_edf`` degrees of
    freedom, so that a noisy dip at the longest taus is not taken for the flicker floor.
    """
    t = np.asarray(tau_s, dtype=np.float64)
    s = np.asarray(adev, dtype=np.float64)
    if t.ndim != 1 or t.shape != s.shape or t.size < 3:
        raise InputError("slope readings need matching 1-D tau and adev arrays of at least 3 points", field="adev")
    if np.any(s <= 0) or not np.all(np.isfinite(s)):
        raise InputError("Allan deviations must be positive and finite for slope readings", field="adev")
    slope = local_slopes(t, s)
    reliable = np.ones(t.size, dtype=bool) if edf is None else np.asarray(edf, dtype=np.float64) >= min_edf
    if not reliable.any():
        reliable[:] = True
    i_min = int(np.flatnonzero(reliable)[np.argmin(s[reliable])])
    notes = []
    n_val = tau_n = None
    left = np.arange(0, i_min + 1)
    i = int(left[np.argmin(np.abs(slope[left] + 0.5))])
    if abs(slope[i] + 0.5) <= slope_tolerance:
        n_val, tau_n = float(s[i] * np.sqrt(t[i])), float(t[i])
    else:
        notes.append(f"no -1/2 slope region (closest slope {slope[i]:+.2f} at tau {t[i]:.3g} s)")
    b_val: float | None = float(s[i_min] / FLICKER_FACTOR)
    if i_min == int(np.flatnonzero(reliable)[-1]):
        notes.append("the curve is still falling at the longest tau: B reading is only an upper bound")
        b_val = None
    elif i_min == 0:
        notes.append("the curve rises from the shortest tau: no flicker floor visible")
        b_val = None
    k_val = tau_k = None
    right = np.arange(i_min, t.size)
    j = int(right[np.argmin(np.abs(slope[right] - 0.5))])
    if abs(slope[j] - 0.5) <= slope_tolerance:
        k_val, tau_k = float(s[j] * np.sqrt(3.0 / t[j])), float(t[j])
    else:
        notes.append(f"no +1/2 slope region (closest slope {slope[j]:+.2f} at tau {t[j]:.3g} s)")
    return SlopeReadings(N=n_val, B=b_val, K=k_val, tau_n_s=tau_n, tau_min_s=float(t[i_min]),
                         adev_min=float(s[i_min]), tau_k_s=tau_k, notes=tuple(notes))
