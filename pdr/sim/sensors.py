"""Sensor error models of the simulator, after seed 004 Sec. 2 (eqs. 2-5).

One :class:`ErrorModel` describes one sensor (a triad, or the one-channel barometer) in the unit of its
stream (m/s^2, rad/s, uT, hPa). A measurement is

    y = Q[ (I + S + M) x + b + b_i(t) + b_r(t) + w ]

with ``x`` the true value, ``S = diag(s)`` scale-factor errors and ``M`` off-diagonal misalignment
(cross-axis sensitivity), both random constants (eq. 2); ``b`` the turn-on bias, a random constant (eq. 2);
``b_i`` the bias instability, a first-order Gauss-Markov process (eq. 3) or 1/f (flicker) noise built as a
sum of Gauss-Markov processes with log-spaced correlation times (a finite AR approximation, eq. 5);
``b_r`` the rate random walk (eq. 4); ``w`` white noise (angular / velocity random walk) and ``Q`` the
quantisation to a step of one LSB. For the magnetometer the same model reads as hard iron (``b``) and
soft iron (``I + S + M``).

Parameter units (``u`` = the stream's unit): ``bias_sigma`` u; ``bias_instability`` u (Gauss-Markov:
stationary standard deviation of eq. 3; flicker: the IEEE bias-instability coefficient B, i.e. an Allan
deviation floor of ``0.664 B``); ``bias_instability_tau_s`` s; ``white_noise_density`` u/sqrt(Hz) (per-sample
standard deviation ``density * sqrt(rate)``); ``rate_random_walk_density`` u/s/sqrt(Hz) (random-walk standard
deviation ``density * sqrt(t)``); ``scale_factor_sigma`` and ``misalignment_sigma`` dimensionless (1 = 100 %);
``quantization_step`` u (0: none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from pdr.errors import InputError

Array = NDArray[np.float64]

BIAS_INSTABILITY_MODELS = ("gauss_markov", "flicker")


@dataclass(frozen=True)
class ErrorModel:
    """Error parameters of one sensor; see the module docstring for the model and the units."""

    bias_sigma: float = 0.0
    bias_instability: float = 0.0
    bias_instability_model: str = "gauss_markov"
    bias_instability_tau_s: float = 100.0
    white_noise_density: float = 0.0
    rate_random_walk_density: float = 0.0
    scale_factor_sigma: float = 0.0
    misalignment_sigma: float = 0.0
    quantization_step: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "bias_instability_model":
                if v not in BIAS_INSTABILITY_MODELS:
                    raise InputError(f"must be one of {BIAS_INSTABILITY_MODELS}, got {v!r}", field=f.name)
            elif not (isinstance(v, int | float) and math.isfinite(v) and v >= 0.0):
                raise InputError(f"must be a finite non-negative number, got {v!r}", field=f.name)
        if self.bias_instability_tau_s <= 0.0:
            raise InputError("must be positive", field="bias_instability_tau_s")

    def with_overrides(self, overrides: dict[str, Any], source: str = "sensors") -> ErrorModel:
        """A copy with some parameters replaced (unknown names raise :class:`InputError`)."""
        names = {f.name for f in fields(self)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise InputError(f"unknown error parameter(s) {unknown}; expected some of {sorted(names)}",
                             source=source)
        try:
            return replace(self, **overrides)
        except InputError as exc:
            raise InputError(exc.message, source=source, field=exc.field) from None


@dataclass(frozen=True)
class ErrorRealization:
    """The random constants drawn for one run: ``bias`` (k,) in u and ``matrix`` (k, k) = I + S + M."""

    bias: Array
    matrix: Array


def realize(model: ErrorModel, n_axes: int, rng: np.random.Generator) -> ErrorRealization:
    """Draw turn-on bias, scale factors and misalignment (random constants, seed 004 eq. 2)."""
    bias = rng.normal(0.0, 1.0, n_axes) * model.bias_sigma
    scale = rng.normal(0.0, 1.0, n_axes) * model.scale_factor_sigma
    mis = rng.normal(0.0, 1.0, (n_axes, n_axes)) * model.misalignment_sigma
    np.fill_diagonal(mis, 0.0)
    return ErrorRealization(bias, np.eye(n_axes) + np.diag(scale) + mis)


def gauss_markov(n: int, dt_s: float, sigma: float, tau_s: float, n_axes: int, rng: np.random.Generator) -> Array:
    """First-order Gauss-Markov process (seed 004 eq. 3), started in its stationary distribution.

    ``x_k = exp(-dt/tau) x_{k-1} + eta_k`` with ``var(eta) = sigma^2 (1 - exp(-2 dt/tau))`` so that the
    stationary standard deviation is ``sigma``. Returns (n, n_axes).
    """
    phi = math.exp(-dt_s / tau_s)
    drive = rng.normal(0.0, 1.0, (n, n_axes)) * sigma * math.sqrt(1.0 - phi * phi)
    x0 = rng.normal(0.0, 1.0, n_axes) * sigma
    out = lfilter([1.0], [1.0, -phi], drive, axis=0, zi=(phi * x0)[None, :])[0]
    return np.asarray(out, dtype=np.float64)


def flicker(n: int, dt_s: float, coefficient: float, n_axes: int, rng: np.random.Generator) -> Array:
    """1/f noise with one-sided PSD ``B^2 / (2 pi f)`` between about ``1/(2 pi T)`` and ``1/(4 pi dt)``.

    A sum of Gauss-Markov processes (eq. 3) with correlation times spaced by a factor ``r`` (two per decade)
    from ``2 dt`` to the record length ``T``, each of variance ``B^2 ln(r) / (2 pi)``: their PSDs add up to
    ``B^2 / (2 pi f)`` inside that band (a finite-order AR model of the long-memory process, eq. 5).
    """
    ratio = math.sqrt(10.0)
    tau_min, tau_max = 2.0 * dt_s, max(n * dt_s, 4.0 * dt_s)
    taus = tau_min * ratio ** np.arange(int(math.ceil(math.log(tau_max / tau_min) / math.log(ratio))) + 1)
    sigma = coefficient * math.sqrt(math.log(ratio) / (2.0 * math.pi))
    out = np.zeros((n, n_axes))
    for tau in taus:
        out += gauss_markov(n, dt_s, sigma, float(tau), n_axes, rng)
    return out


def random_walk(n: int, dt_s: float, density: float, n_axes: int, rng: np.random.Generator) -> Array:
    """Random walk (seed 004 eq. 4) ``x_k = x_{k-1} + eta_k``, ``var(eta) = density^2 dt``, from 0."""
    steps = rng.normal(0.0, 1.0, (n, n_axes)) * density * math.sqrt(dt_s)
    steps[0] = 0.0
    return np.cumsum(steps, axis=0)


def apply(model: ErrorModel, truth: Array, t_s: Array, rng: np.random.Generator) -> Array:
    """Corrupt uniformly sampled true values ``truth`` (N, k) at times ``t_s`` (N,) with the error model.

    The random draws happen in a fixed order, so a given generator state always gives the same output.
    """
    x = np.asarray(truth, dtype=np.float64)
    n, k = x.shape
    dt = float(np.median(np.diff(t_s))) if n > 1 else 1.0
    real = realize(model, k, rng)
    y = x @ real.matrix.T + real.bias
    if model.bias_instability > 0.0:
        if model.bias_instability_model == "flicker":
            y += flicker(n, dt, model.bias_instability, k, rng)
        else:
            y += gauss_markov(n, dt, model.bias_instability, model.bias_instability_tau_s, k, rng)
    if model.rate_random_walk_density > 0.0:
        y += random_walk(n, dt, model.rate_random_walk_density, k, rng)
    if model.white_noise_density > 0.0:
        y += rng.normal(0.0, 1.0, (n, k)) * model.white_noise_density / math.sqrt(dt)
    if model.quantization_step > 0.0:
        y = np.round(y / model.quantization_step) * model.quantization_step
    return y


_DEG = math.pi / 180.0
_MG = 9.80665e-3
_UG = 9.80665e-6

#: Error models by sensor grade. ``consumer`` and ``tactical`` follow seed 004 Table 1 (pre-calibration bias,
#: noise density, bias instability, ARW, scale factor, misalignment / cross-axis sensitivity); entries the
#: table leaves open (accelerometer bias instability, quantisation, magnetometer, barometer) are typical
#: values of smartphone-class parts. ``ideal`` has no error at all.
GRADES: MappingProxyType[str, MappingProxyType[str, ErrorModel]] = MappingProxyType({
    "ideal": MappingProxyType({k: ErrorModel() for k in ("acc", "gyro", "mag", "baro")}),
    "consumer": MappingProxyType({
        "acc": ErrorModel(bias_sigma=30 * _MG, white_noise_density=100 * _UG, scale_factor_sigma=0.01,
                          misalignment_sigma=0.01, bias_instability=0.05 * _MG,
                          bias_instability_model="flicker", rate_random_walk_density=1e-5,
                          quantization_step=16 * 9.80665 / 2**16),
        "gyro": ErrorModel(bias_sigma=1000 * _DEG / 3600, bias_instability=20 * _DEG / 3600,
                           bias_instability_model="flicker", white_noise_density=0.5 * _DEG / 60,
                           scale_factor_sigma=0.01, misalignment_sigma=0.01, rate_random_walk_density=1e-6,
                           quantization_step=2000 * _DEG / 2**16),
        "mag": ErrorModel(bias_sigma=10.0, white_noise_density=0.05, scale_factor_sigma=0.03,
                          misalignment_sigma=0.02, quantization_step=0.15),
        "baro": ErrorModel(bias_sigma=0.5, white_noise_density=0.01, rate_random_walk_density=2e-3,
                           quantization_step=0.001),
    }),
    "tactical": MappingProxyType({
        "acc": ErrorModel(bias_sigma=1 * _MG, white_noise_density=50 * _UG, scale_factor_sigma=3e-4,
                          misalignment_sigma=5e-4, bias_instability=0.01 * _MG,
                          bias_instability_model="flicker"),
        "gyro": ErrorModel(bias_sigma=1 * _DEG / 3600, bias_instability=0.1 * _DEG / 3600,
                           bias_instability_model="flicker", white_noise_density=0.1 * _DEG / 60,
                           scale_factor_sigma=1e-4, misalignment_sigma=5e-4),
        "mag": ErrorModel(bias_sigma=1.0, white_noise_density=0.02, scale_factor_sigma=0.005,
                          misalignment_sigma=0.005),
        "baro": ErrorModel(bias_sigma=0.1, white_noise_density=0.005, rate_random_walk_density=5e-4),
    }),
})
