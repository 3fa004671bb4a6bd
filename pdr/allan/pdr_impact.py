"""Predicted PDR error growth from gyro errors, by simulating seed 004's PDR mechanization (eqs. 20-22).

Scenario of seed 004 Sec. 3 ("Effect of Sensor Quality Grade to the Accuracy of PDR"): a walker with
constant step length 0.75 m at 2 steps/s along the positive x axis. The gyro is integrated into
heading at the gyro rate (eq. 20, ``psi_l = psi_{l-1} + omega_l dt_g``), the heading is averaged over
each step (eq. 21) and the position propagated per step (eq. 22). The relative position error is the
distance between estimated and true positions divided by the distance walked.

- :func:`bias_impact`: an uncompensated constant gyro bias (Table 3): time until the relative position
  error reaches 2 % and 3 % and the heading error 3 deg. Table 3: 25 deg/h -> 5.5 min, 8.3 min, 7.2 min.
- :func:`scale_factor_impact`: a scale-factor error during a 180 deg turn in place before walking
  (Table 4): constant heading error and relative position error. Table 4: 1 % -> 1.8 deg, 3.14 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pdr.errors import InputError

_BLOCK_STEPS = 1 << 20


@dataclass(frozen=True)
class Walker:
    """PDR scenario parameters (seed 004 Sec. 3 defaults)."""

    step_length_m: float = 0.75
    step_rate_hz: float = 2.0
    gyro_rate_hz: float = 100.0

    def __post_init__(self) -> None:
        for name in ("step_length_m", "step_rate_hz", "gyro_rate_hz"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"{name} must be positive, got {v}", field=name)


@dataclass(frozen=True)
class BiasImpact:
    """Times (s) until the thresholds are first reached; ``None`` if not within ``horizon_s``."""

    bias_rad_s: float
    time_to_rel_error_s: dict[float, float | None]
    time_to_heading_error_s: float | None
    heading_threshold_deg: float
    horizon_s: float


def _step_mean_heading(k: np.ndarray, bias_rad_s: float, w: Walker) -> np.ndarray:
    """Eq. 21 mean over the gyro samples of steps ``k`` of the eq. 20 heading ``psi_l = l dt_g b``."""
    dt_g = 1.0 / w.gyro_rate_hz
    t_step = 1.0 / w.step_rate_hz
    first = np.ceil(k * t_step / dt_g - 1e-9)
    last = np.ceil((k + 1) * t_step / dt_g - 1e-9) - 1.0  # samples l with t_s <= l dt_g < t_e
    return bias_rad_s * dt_g * (first + last) / 2.0


def bias_impact(bias_rad_s: float, walker: Walker | None = None, rel_thresholds: tuple[float, ...] = (0.02, 0.03),
                heading_threshold_deg: float = 3.0, horizon_s: float = 366 * 86400.0) -> BiasImpact:
    """Simulate eqs. 20-22 with a constant gyro bias until every threshold is crossed (Table 3)."""
    w = walker or Walker()
    b = abs(float(bias_rad_s))
    if not np.isfinite(b):
        raise InputError(f"gyro bias must be finite, got {bias_rad_s}", field="bias_rad_s")
    dt_g = 1.0 / w.gyro_rate_hz
    # eq. 20 with a true rate of zero: psi_l = l dt_g b; first sample whose heading error reaches the threshold
    t_heading = None
    if b > 0:
        lam = np.ceil(np.deg2rad(heading_threshold_deg) / (b * dt_g) - 1e-12)
        t_heading = float(lam * dt_g) if lam * dt_g <= horizon_s else None
    found: dict[float, float | None] = {r: None for r in rel_thresholds}
    n_total = int(horizon_s * w.step_rate_hz)
    x = y = 0.0
    start = 0
    while b > 0 and start < n_total and any(v is None for v in found.values()):
        k = np.arange(start, min(start + _BLOCK_STEPS, n_total), dtype=np.float64)
        psi = _step_mean_heading(k, b, w)
        xs = x + np.cumsum(w.step_length_m * np.cos(psi))  # eq. 22
        ys = y + np.cumsum(w.step_length_m * np.sin(psi))
        walked = (k + 1.0) * w.step_length_m
        rel = np.hypot(xs - walked, ys) / walked
        for r in rel_thresholds:
            if found[r] is None:
                hit = np.flatnonzero(rel >= r)
                if hit.size:
                    found[r] = float((k[hit[0]] + 1.0) / w.step_rate_hz)
        x, y = float(xs[-1]), float(ys[-1])
        start += k.size
    return BiasImpact(bias_rad_s=float(bias_rad_s), time_to_rel_error_s=found, time_to_heading_error_s=t_heading,
                      heading_threshold_deg=heading_threshold_deg, horizon_s=horizon_s)


@dataclass(frozen=True)
class ScaleFactorImpact:
    """Constant heading error (deg) and relative position error (fraction) after the turn (Table 4)."""

    scale_factor_error: float
    heading_error_deg: float
    rel_position_error: float


def scale_factor_impact(scale_factor_error: float, walker: Walker | None = None, turn_deg: float = 180.0,
                        turn_rate_deg_s: float = 90.0, walk_steps: int = 200) -> ScaleFactorImpact:
    """Turn ``turn_deg`` in place (from -180 deg) with a scaled gyro, then walk along +x (Table 4).

    ``scale_factor_error`` is a fraction (0.01 = 1 %).
    """
    w = walker or Walker()
    s = float(scale_factor_error)
    if not np.isfinite(s) or turn_rate_deg_s <= 0 or walk_steps < 1:
        raise InputError("scale factor must be finite, turn rate positive and at least one step",
                         field="scale_factor_error")
    dt_g = 1.0 / w.gyro_rate_hz
    n_turn = int(np.ceil(turn_deg / turn_rate_deg_s * w.gyro_rate_hz))
    omega_true = np.full(n_turn, np.deg2rad(turn_deg) / (n_turn * dt_g))
    psi0 = -np.pi
    psi_turn = psi0 + np.cumsum((1.0 + s) * omega_true * dt_g)  # eq. 20 with the scaled gyro
    err = float(psi_turn[-1] - (psi0 + np.deg2rad(turn_deg)))
    # walking straight: omega = 0, heading (and its error) constant; eqs. 21-22 per step
    psi = np.full(walk_steps, err)
    xs = np.cumsum(w.step_length_m * np.cos(psi))
    ys = np.cumsum(w.step_length_m * np.sin(psi))
    walked = np.arange(1, walk_steps + 1) * w.step_length_m
    rel = np.hypot(xs - walked, ys) / walked
    return ScaleFactorImpact(scale_factor_error=s, heading_error_deg=float(np.rad2deg(err)),
                             rel_position_error=float(rel[-1]))


def human_duration(seconds: float | None) -> str:
    """'5.5 min', '3.4 h', '41 days' style rendering (as in Table 3)."""
    if seconds is None:
        return "not reached"
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.3g} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.3g} h"
    return f"{seconds / 86400:.3g} days"
