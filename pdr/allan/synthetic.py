"""Simulated static sensor output with known IEEE noise terms (for tests and demonstrations).

Each generator returns ``n`` samples at ``rate_hz`` whose Allan variance follows one term of
:mod:`pdr.allan.noise_model` in the limit of a long record:

- :func:`white_noise`: per-sample standard deviation ``N sqrt(rate)``, AVAR = ``N^2 / tau``;
- :func:`random_walk`: seed 004 eq. 4 with increments of standard deviation ``K / sqrt(rate)``,
  AVAR = ``K^2 tau / 3``;
- :func:`gauss_markov`: seed 004 eq. 3, ``x(t) = exp(-dt / gamma) x(t - 1) + eta(t)``, stationary
  standard deviation ``sigma``;
- :func:`flicker_noise`: 1/f noise with two-sided PSD ``B^2 / (2 pi |f|)`` shaped in the frequency
  domain between ``1 / duration`` and Nyquist, AVAR = ``(2 ln 2 / pi) B^2`` away from the band edges;
- :func:`sum_of_gauss_markov`: a sum of first-order GM processes with log-spaced correlation times
  whose AVAR approximates the same flicker floor (the usual finite-state model of bias instability).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from pdr.allan.noise_model import FLICKER_FACTOR
from pdr.errors import InputError

FloatArray = NDArray[np.float64]


def _check(n: int, rate_hz: float) -> None:
    if n < 1 or not np.isfinite(rate_hz) or rate_hz <= 0:
        raise InputError(f"need n >= 1 samples at a positive rate (n={n}, rate={rate_hz})", field="n")


def white_noise(n: int, rate_hz: float, n_density: float, rng: np.random.Generator) -> FloatArray:
    """(n,) white noise of density ``n_density`` (unit/sqrt(Hz))."""
    _check(n, rate_hz)
    return rng.standard_normal(n) * n_density * np.sqrt(rate_hz)


def random_walk(n: int, rate_hz: float, k_density: float, rng: np.random.Generator) -> FloatArray:
    """(n,) random walk (seed 004 eq. 4) of density ``k_density`` (unit/s/sqrt(Hz))."""
    _check(n, rate_hz)
    return np.cumsum(rng.standard_normal(n) * k_density / np.sqrt(rate_hz))


def gauss_markov(n: int, rate_hz: float, sigma: float, gamma_s: float, rng: np.random.Generator) -> FloatArray:
    """(n,) stationary first-order Gauss-Markov process, seed 004 eq. 3.

    ``sigma`` is the stationary standard deviation and ``gamma_s`` the correlation time (s); the
    driving noise has standard deviation ``sigma sqrt(1 - exp(-2 dt / gamma))``.
    """
    _check(n, rate_hz)
    if gamma_s <= 0:
        raise InputError(f"correlation time must be positive, got {gamma_s}", field="gamma_s")
    phi = np.exp(-1.0 / (rate_hz * gamma_s))
    eta = rng.standard_normal(n) * sigma * np.sqrt(1.0 - phi**2)
    eta[0] = rng.standard_normal() * sigma  # start in the stationary distribution
    return np.asarray(lfilter([1.0], [1.0, -phi], eta), dtype=np.float64)


def gauss_markov_avar(tau_s: FloatArray, sigma: float, gamma_s: float) -> FloatArray:
    """Analytic AVAR of a continuous first-order GM process (IEEE Std 952 Annex C)."""
    x = np.asarray(tau_s, dtype=np.float64) / gamma_s
    return 2.0 * sigma**2 / x * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


def flicker_noise(n: int, rate_hz: float, b_instability: float, rng: np.random.Generator) -> FloatArray:
    """(n,) 1/f noise whose flat Allan deviation is ``0.664 b_instability`` (unit of the rate)."""
    _check(n, rate_hz)
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, d=1.0 / rate_hz)
    gain = np.zeros_like(f)
    # unit white noise has two-sided PSD 1 / rate; scale to B^2 / (2 pi f)
    gain[1:] = np.sqrt(b_instability**2 / (2.0 * np.pi * f[1:]) * rate_hz)
    return np.fft.irfft(spec * gain, n)


def sum_of_gauss_markov(n: int, rate_hz: float, b_instability: float, gamma_min_s: float, gamma_max_s: float,
                        rng: np.random.Generator, per_decade: float = 2.0) -> FloatArray:
    """(n,) sum of GM processes (eq. 3) approximating a flicker floor ``0.664 b_instability``.

    Correlation times are log-spaced between ``gamma_min_s`` and ``gamma_max_s``; each process gets the
    variance that makes the summed analytic AVAR flat at ``(2 ln 2 / pi) B^2`` over that span
    (least squares on a log grid, non-negative).
    """
    _check(n, rate_hz)
    from scipy.optimize import nnls

    k = max(2, int(np.ceil(np.log10(gamma_max_s / gamma_min_s) * per_decade)) + 1)
    gammas = np.logspace(np.log10(gamma_min_s), np.log10(gamma_max_s), k)
    tau = np.logspace(np.log10(gamma_min_s * 2.0), np.log10(gamma_max_s), 60)
    a = np.column_stack([gauss_markov_avar(tau, 1.0, g) for g in gammas])
    var, _ = nnls(a, np.full(tau.size, (FLICKER_FACTOR * b_instability) ** 2))
    out = np.zeros(n)
    for g, v in zip(gammas, var, strict=True):
        if v > 0:
            out += gauss_markov(n, rate_hz, float(np.sqrt(v)), float(g), rng)
    return out
