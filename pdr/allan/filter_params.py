"""Noise parameters for our filters and a Kalibr-style ``imu.yaml`` from the fitted noise terms.

Continuous-time densities (SI): white noise density ``N`` and bias random-walk density ``K``;
discrete per-sample standard deviations at the sensor rate ``f``: white ``N sqrt(f)`` and bias
random-walk increment ``K / sqrt(f)`` (seed 004 eq. 4). The bias instability is also given as the
first-order Gauss-Markov process of seed 004 eq. 3 whose Allan-deviation peak equals the measured
minimum: for a GM of standard deviation ``sigma`` and correlation time ``gamma`` the ADEV peaks at
``tau ~ 1.89 gamma`` with value ``~ 0.618 sigma`` (= 0.437 sqrt(2 sigma^2 / gamma) sqrt(gamma); computed
from the analytic GM AVAR).
A term the record could not resolve is replaced by its upper bound and marked ``"bound"``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from pdr.allan.noise_model import NoiseFit
from pdr.allan.slopes import SlopeReadings
from pdr.allan.synthetic import gauss_markov_avar


@lru_cache(maxsize=1)
def gm_peak_constants() -> tuple[float, float]:
    """(tau_peak / gamma, adev_peak / sigma) of a unit first-order Gauss-Markov process."""
    res = minimize_scalar(lambda x: -gauss_markov_avar(np.array([x]), 1.0, 1.0)[0], bounds=(0.1, 10.0),
                          method="bounded", options={"xatol": 1e-10})
    return float(res.x), float(np.sqrt(-res.fun))


def _term(fit: NoiseFit, name: str) -> tuple[float, str]:
    v = fit.value[name]
    return (float(v), "fit") if v is not None else (float(fit.upper_bound[name]), "bound")


def axis_parameters(fit: NoiseFit, slopes: SlopeReadings, rate_hz: float) -> dict[str, Any]:
    """Filter parameters of one axis (SI units; see module docstring)."""
    n, n_src = _term(fit, "N")
    k, k_src = _term(fit, "K")
    ratio_tau, ratio_dev = gm_peak_constants()
    gamma = slopes.tau_min_s / ratio_tau
    return {
        "noise_density": n, "noise_density_source": n_src,
        "bias_random_walk_density": k, "bias_random_walk_source": k_src,
        "white_std_per_sample": n * np.sqrt(rate_hz),
        "bias_random_walk_std_per_sample": k / np.sqrt(rate_hz),
        "bias_instability": fit.value["B"],
        "gauss_markov": {"correlation_time_s": gamma, "sigma": slopes.adev_min / ratio_dev,
                         "phi_per_sample": float(np.exp(-1.0 / (rate_hz * gamma)))},
    }


def sensor_parameters(per_axis: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """Conservative (largest over axes) densities of one sensor, for filters that take one value."""
    keys = ("noise_density", "bias_random_walk_density", "white_std_per_sample", "bias_random_walk_std_per_sample")
    out: dict[str, Any] = {k: max(float(p[k]) for p in per_axis.values()) for k in keys}
    out["bias_random_walk_source"] = ("bound" if any(p["bias_random_walk_source"] == "bound"
                                                     for p in per_axis.values()) else "fit")
    return out


def kalibr_yaml(gyro: Mapping[str, Any] | None, acc: Mapping[str, Any] | None, rate_hz: float,
                source: str = "", notes: Sequence[str] = ()) -> str:
    """Kalibr ``imu.yaml`` text (continuous-time densities, largest over axes)."""
    head = "# IMU noise model from `pdr allan` (Allan-variance fit, largest value over the axes)"
    lines = [head + (f": {source}" if source else ""),
             *(f"# {n}" for n in notes),
             "rostopic: /imu0", f"update_rate: {rate_hz:.6g}  # Hz"]
    for name, sensor, unit_n, unit_k in (("accelerometer", acc, "m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)"),
                                        ("gyroscope", gyro, "rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)")):
        if sensor is None:
            lines.append(f"# {name}: not characterised")
            continue
        bound = ("; upper bound, the record is too short to resolve it"
                 if sensor["bias_random_walk_source"] == "bound" else "")
        lines.append(f"{name}_noise_density: {sensor['noise_density']:.6e}  # {unit_n}")
        lines.append(f"{name}_random_walk: {sensor['bias_random_walk_density']:.6e}  # {unit_k}{bound}")
    return "\n".join(lines) + "\n"
