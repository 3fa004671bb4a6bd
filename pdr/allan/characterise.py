"""The whole Allan-variance characterisation of a sensor (arrays) or of a recording (gyro and accelerometer).

Per axis: overlapping Allan deviation with confidence intervals (EDF of the locally dominant noise
term), the IEEE noise-model fit, the classic slope readings and the disagreements between the two.
Per sensor: grade (seed 004 Table 1), filter parameters and, for a gyro, the PDR impact of its bias
instability and of a stated scale-factor error (Tables 3-4).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.allan import filter_params, grade
from pdr.allan.confidence import ONE_SIGMA, chi2_interval, edf_table
from pdr.allan.estimators import AllanCurve, allan_curve, as_samples
from pdr.allan.noise_model import TERMS, NoiseFit, fit_noise_model
from pdr.allan.pdr_impact import BiasImpact, ScaleFactorImpact, Walker, bias_impact, scale_factor_impact
from pdr.allan.record_checks import StreamQuality, prepare_stream
from pdr.allan.slopes import SlopeReadings, read_slopes
from pdr.allan.units import DEG, SI_UNITS, UG, check_sensor
from pdr.errors import InputError
from pdr.recording import Recording

FloatArray = NDArray[np.float64]
AXES: tuple[str, ...] = ("x", "y", "z")


@dataclass(frozen=True)
class Settings:
    """Analysis options (see ``pdr allan --help``)."""

    per_decade: float = 6.0
    tau_min_s: float | None = None
    tau_max_s: float | None = None
    all_taus: bool = False
    extra_estimators: tuple[str, ...] = ()
    confidence: float = ONE_SIGMA
    terms: tuple[str, ...] = TERMS
    disagreement_tolerance: float = 0.25
    gap_policy: str = "longest"
    motion_policy: str = "flag"
    scale_factor_error: float | None = None
    walker: Walker = field(default_factory=Walker)


@dataclass(frozen=True)
class AxisResult:
    """One axis: curve (overlapping ADEV and its interval), fit, slope readings, disagreements."""

    axis: str
    adev: FloatArray
    adev_lo: FloatArray
    adev_hi: FloatArray
    edf: FloatArray
    fit: NoiseFit
    slopes: SlopeReadings
    disagreements: tuple[str, ...]
    extra_adev: Mapping[str, FloatArray]


@dataclass(frozen=True)
class SensorResult:
    """One sensor (``gyro`` or ``acc``) of a record."""

    sensor: str
    rate_hz: float
    n_samples: int
    curve: AllanCurve
    axes: Mapping[str, AxisResult]
    grade_calls: tuple[grade.GradeCall, ...]
    grade: str | None
    filter: Mapping[str, Any]
    bias_impact: Mapping[str, BiasImpact]
    bias_used: Mapping[str, tuple[float, str]]
    scale_factor: ScaleFactorImpact | None
    scale_factor_source: str
    quality: StreamQuality | None
    elapsed_s: float
    walker: Walker = field(default_factory=Walker)

    @property
    def unit(self) -> str:
        return "rad/s" if self.sensor == "gyro" else "m/s^2"


@dataclass(frozen=True)
class RecordingResult:
    """Every characterised sensor of one recording, with its metadata."""

    source: str
    format: str
    device: Mapping[str, Any]
    duration_s: float
    temperature: Mapping[str, float] | None
    warnings: tuple[str, ...]
    meta: Mapping[str, Any]
    sensors: Mapping[str, SensorResult]
    settings: Settings


def _line_reading(line: str, at_s: float, through_s: float | None, tau_s: FloatArray) -> str:
    """How a slope reading of ``line`` at ``at_s`` was taken: on the curve, or extrapolated beyond its taus from the
    point at ``through_s`` (a short record has no tau of 3 s, nor even of 1 s).
    """
    if through_s is None or tau_s[0] <= at_s <= tau_s[-1]:
        return f"{line} at {at_s:g} s"
    why = ("the record is too short to read it there" if at_s > tau_s[-1] else
           f"the curve starts at {tau_s[0]:.3g} s")
    return f"{line} through tau {through_s:.3g} s extrapolated to {at_s:g} s: {why}"


def _disagreements(fit: NoiseFit, sl: SlopeReadings, tol: float, tau_s: FloatArray) -> tuple[str, ...]:
    out = []
    for k, what in (("N", _line_reading("-1/2 line", 1.0, sl.tau_n_s, tau_s)), ("B", "minimum / 0.664"),
                    ("K", _line_reading("+1/2 line", 3.0, sl.tau_k_s, tau_s))):
        f, s = fit.value[k], getattr(sl, k)
        if f is not None and s is not None:
            rel = abs(f - s) / s
            if rel > tol:
                extra = " (the minimum also holds white and random-walk noise, so it over-reads B)" if k == "B" else ""
                out.append(f"{k}: fit {f:.4g} and slope reading ({what}) {s:.4g} differ by {100 * rel:.0f} %{extra}")
        elif f is not None and s is None:
            out.append(f"{k}: resolved by the fit but no slope reading ({what}) is possible on this curve")
        elif f is None and s is not None:
            out.append(f"{k}: slope reading ({what}) {s:.4g} but the fit cannot resolve it: {fit.reason[k]}")
    return tuple(out)


def _bias_for_impact(ax: AxisResult) -> tuple[float, str]:
    if ax.fit.value["B"] is not None:
        return float(ax.fit.value["B"]), "fit"
    if ax.slopes.B is not None:
        return float(ax.slopes.B), "slope reading"
    return float(ax.fit.upper_bound["B"]), "upper bound"


def characterise_samples(samples: ArrayLike, rate_hz: float, sensor: str, *, axis_names: Sequence[str] = AXES,
                         settings: Settings | None = None, quality: StreamQuality | None = None) -> SensorResult:
    """Characterise one sensor from uniformly sampled data.

    Parameters
    ----------
    samples
        (n, A) samples in SI units (rad/s for ``gyro``, m/s^2 for ``acc``), body frame axes.
    rate_hz
        Sampling rate (Hz).
    sensor
        ``gyro`` or ``acc`` (sets units, grade table and whether the PDR impact is computed).
    axis_names
        Names of the A columns.
    """
    t_start = time.perf_counter()
    st = settings or Settings()
    check_sensor(sensor)
    y = as_samples(samples, name=sensor)
    if len(axis_names) != y.shape[1]:
        raise InputError(f"{y.shape[1]} columns but {len(axis_names)} axis names", source=sensor)
    curve = allan_curve(y, rate_hz, per_decade=st.per_decade, tau_min_s=st.tau_min_s, tau_max_s=st.tau_max_s,
                        all_taus=st.all_taus)
    if curve.m.size < 3:
        raise InputError(f"record of {y.shape[0]} samples gives only {curve.m.size} averaging times; "
                         "it is too short for a noise analysis", source=sensor)
    extra = {k: allan_curve(y, rate_hz, kind=k, m=curve.m[curve.m <= (y.shape[0] + 1) // 3] if k == "modified"
                            else curve.m).adev for k in st.extra_estimators if k != "overlapping"}
    edfs = edf_table(curve.m, curve.n_samples, curve.kind)
    axes: dict[str, AxisResult] = {}
    for j, name in enumerate(axis_names):
        avar = curve.avar[:, j]
        if np.all(avar == 0):
            raise InputError(f"axis {name} is constant over the whole record (stuck sensor?)", source=sensor)
        fit = fit_noise_model(curve.tau_s, avar, edfs, terms=st.terms, confidence=st.confidence)
        lo, hi = chi2_interval(avar, fit.edf, st.confidence)
        positive = np.maximum(curve.adev[:, j], np.finfo(float).tiny)
        sl = read_slopes(curve.tau_s, positive, edf=fit.edf)
        axes[name] = AxisResult(axis=name, adev=curve.adev[:, j], adev_lo=np.sqrt(lo), adev_hi=np.sqrt(hi),
                                edf=fit.edf, fit=fit, slopes=sl,
                                disagreements=_disagreements(fit, sl, st.disagreement_tolerance, curve.tau_s),
                                extra_adev={k: v[:, j] for k, v in extra.items()})
    calls: list[grade.GradeCall] = []
    for ax in axes.values():
        n_val = ax.fit.value["N"] if ax.fit.value["N"] is not None else ax.slopes.N
        if sensor == "gyro":
            b_val = ax.fit.value["B"] if ax.fit.value["B"] is not None else ax.slopes.B
            if b_val is not None:
                calls.append(grade.grade_value("gyro", "bias_instability", b_val * DEG * 3600.0, ax.axis))
            if n_val is not None:
                calls.append(grade.grade_value("gyro", "angular_random_walk", n_val * DEG * 60.0, ax.axis))
        elif n_val is not None:
            calls.append(grade.grade_value("acc", "noise_density", n_val * UG, ax.axis))
    overall = grade.worst(calls)
    per_axis = {k: filter_params.axis_parameters(a.fit, a.slopes, curve.rate_hz) for k, a in axes.items()}
    filt = {"axes": per_axis, "sensor": filter_params.sensor_parameters(per_axis), "rate_hz": curve.rate_hz}
    impacts: dict[str, BiasImpact] = {}
    used: dict[str, tuple[float, str]] = {}
    sf: ScaleFactorImpact | None = None
    sf_source = ""
    if sensor == "gyro":
        for k, a in axes.items():
            used[k] = _bias_for_impact(a)
            impacts[k] = bias_impact(used[k][0], st.walker)
        if st.scale_factor_error is not None:
            sf = scale_factor_impact(st.scale_factor_error, st.walker)
            sf_source = "stated"
        elif overall in grade.GRADES:
            typical = grade.TABLE1[("gyro", "scale_factor_error")][1 + grade.GRADES.index(overall)]
            sf = scale_factor_impact(float(typical) / 100.0, st.walker)
            sf_source = (f"assumed: {grade.REFERENCE_SHORT} Table 1 value for a {overall}-grade gyro "
                         "(not measurable from a static record)")
    return SensorResult(sensor=sensor, rate_hz=curve.rate_hz, n_samples=curve.n_samples, curve=curve, axes=axes,
                        grade_calls=tuple(calls), grade=overall, filter=filt, bias_impact=impacts, bias_used=used,
                        scale_factor=sf, scale_factor_source=sf_source, quality=quality,
                        elapsed_s=time.perf_counter() - t_start, walker=st.walker)


def _temperature(rec: Recording) -> dict[str, float] | None:
    if not rec.has("temperature"):
        return None
    v = rec.values("temperature")[:, 0]
    t = rec.t_s("temperature")
    head = v[t <= t[0] + 60.0]
    tail = v[t >= t[-1] - 60.0]
    return {"mean_degC": float(v.mean()), "min_degC": float(v.min()), "max_degC": float(v.max()),
            "change_degC": float(tail.mean() - head.mean())}


def characterise_recording(rec: Recording, sensors: Sequence[str] = ("gyro", "acc"), axes: Sequence[str] = AXES,
                           settings: Settings | None = None) -> RecordingResult:
    """Characterise the requested sensors and axes of a (static) recording."""
    st = settings or Settings()
    bad = [a for a in axes if a not in AXES]
    if bad or not axes:
        raise InputError(f"unknown axes {bad}; expected some of {AXES}", field="axis")
    present = [s for s in sensors if rec.has(s)]
    missing = [s for s in sensors if not rec.has(s)]
    if not present:
        raise InputError(f"recording has none of the streams {list(sensors)} (it has {sorted(rec.streams)})",
                         source=rec.source or None)
    cols = [AXES.index(a) for a in axes]
    results: dict[str, SensorResult] = {}
    for s in present:
        check_sensor(s)
        vals, rate, quality = prepare_stream(rec.stream(s), gap_policy=st.gap_policy, motion_policy=st.motion_policy)
        results[s] = characterise_samples(vals[:, cols], rate, s, axis_names=tuple(axes), settings=st,
                                          quality=quality)
    warnings = tuple(rec.warnings) + tuple(f"recording has no '{s}' stream; not characterised" for s in missing)
    dev = rec.device
    return RecordingResult(
        source=rec.source, format=rec.format,
        device={"platform": dev.platform, "model": dev.model, "role": _role(dev.platform, dev.role),
                "device_id": dev.device_id},
        duration_s=rec.duration_s, temperature=_temperature(rec), warnings=warnings, meta=dict(rec.meta),
        sensors=results, settings=st)


def _role(platform: str, role: str) -> str:
    """The device's role as a report names it: a reader's default role ``phone`` on a platform that is no phone
    (``imu``: a lab or shoe IMU) is not a fact about the device, so it reads ``standalone IMU``.
    """
    return "standalone IMU" if role == "phone" and platform not in ("android", "ios") else role


__all__ = ["AXES", "SI_UNITS", "AxisResult", "RecordingResult", "SensorResult", "Settings", "characterise_recording",
           "characterise_samples"]
