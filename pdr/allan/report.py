"""The report files: ``report.json`` (every number), PNG plots, ``report.html``, ``imu.yaml``, ``filter_params.json``.

``report.json`` holds, for each characterised sensor (``gyro``, ``acc``) and axis (``x``, ``y``, ``z``),
``tau_s`` and ``adev`` (overlapping, rad/s or m/s^2) with the confidence bounds and EDF, and the noise
terms in SI units under ``N``, ``B`` (already divided by 0.664), ``K``, ``Q`` and ``R``: ``null`` for
a term the record cannot resolve (the reason and an upper bound are under ``fit``). Several records
of the same sensor model give ``comparison.json`` with the spread of N and B across units.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from pdr.allan import filter_params, grade, html_report, plots
from pdr.allan.characterise import RecordingResult, SensorResult
from pdr.allan.noise_model import TERMS
from pdr.allan.pdr_impact import human_duration
from pdr.allan.units import SI_UNITS, to_datasheet

SCHEMA = "pdr.allan.report/1"


def jsonable(obj: Any) -> Any:
    """Plain JSON types; NaN and infinities become ``None``."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if obj is None or isinstance(obj, (str, int, bool)):
        return obj
    return str(obj)


def sensor_dict(sr: SensorResult) -> dict[str, Any]:
    """Every number of one sensor's analysis."""
    tau = sr.curve.tau_s
    out: dict[str, Any] = {
        "unit": sr.unit, "term_units": dict(SI_UNITS[sr.sensor]), "rate_hz": sr.rate_hz, "n_samples": sr.n_samples,
        "duration_s": sr.n_samples / sr.rate_hz, "estimator": "overlapping", "tau_s": tau, "m": sr.curve.m,
        "elapsed_s": sr.elapsed_s,
    }
    flags: list[str] = []
    if sr.quality is not None:
        out["quality"] = asdict(sr.quality)
        flags += list(sr.quality.flags)
    for name, a in sr.axes.items():
        ax: dict[str, Any] = {"tau_s": tau, "adev": a.adev, "adev_lo": a.adev_lo, "adev_hi": a.adev_hi, "edf": a.edf,
                              "n_terms": sr.curve.n_terms}
        for kind, dev in a.extra_adev.items():
            ax[f"adev_{kind}"] = dev
        for k in TERMS:
            ax[k] = a.fit.value[k]
        ax["fit"] = {
            "estimate": a.fit.estimate, "std_error": a.fit.std_error, "upper_bound": a.fit.upper_bound,
            "resolved": a.fit.resolved, "reason": a.fit.reason, "max_share": a.fit.share,
            "chi2_reduced": a.fit.chi2_reduced, "iterations": a.fit.iterations, "dominant": list(a.fit.dominant),
            "model_adev": np.sqrt(a.fit.model),
        }
        sl = a.slopes
        ax["slopes"] = {"N": sl.N, "B": sl.B, "K": sl.K, "tau_n_s": sl.tau_n_s, "tau_min_s": sl.tau_min_s,
                        "adev_min": sl.adev_min, "tau_k_s": sl.tau_k_s, "notes": list(sl.notes)}
        ax["datasheet"] = {k: to_datasheet(sr.sensor, k, a.fit.value[k]) for k in TERMS}
        ax["datasheet_slopes"] = {k: to_datasheet(sr.sensor, k, getattr(sl, k)) for k in ("N", "B", "K")}
        ax["datasheet_upper_bound"] = {k: to_datasheet(sr.sensor, k, a.fit.upper_bound[k]) for k in TERMS
                                       if a.fit.value[k] is None}
        ax["disagreements"] = list(a.disagreements)
        flags += [f"{sr.sensor} {name}: {d}" for d in a.disagreements]
        out[name] = ax
    out["grade"] = {"overall": sr.grade, "calls": [asdict(c) for c in sr.grade_calls],
                    "table1": {f"{s}/{p}": dict(zip(("unit", *grade.GRADES), v, strict=True))
                               for (s, p), v in grade.TABLE1.items() if s == sr.sensor},
                    "reference": grade.REFERENCE,
                    "note": f"{grade.REFERENCE_SHORT} Table 1 values are indicative orders of magnitude, "
                            "not definitions"}
    if sr.sensor == "gyro":
        impact: dict[str, Any] = {"walker": asdict(sr.walker), "axes": {},
                                  "scenario": f"{grade.REFERENCE_SHORT} Sec. 3, eqs. 20-22 (Table 3 bias, "
                                              "Table 4 scale factor)"}
        for name, bi in sr.bias_impact.items():
            b, src = sr.bias_used[name]
            impact["axes"][name] = {
                "bias_rad_s": b, "bias_deg_h": b * 180.0 / np.pi * 3600.0, "bias_source": src,
                "time_to_2pct_s": bi.time_to_rel_error_s.get(0.02), "time_to_3pct_s": bi.time_to_rel_error_s.get(0.03),
                "time_to_3deg_s": bi.time_to_heading_error_s,
                "readable": {"2pct": human_duration(bi.time_to_rel_error_s.get(0.02)),
                             "3pct": human_duration(bi.time_to_rel_error_s.get(0.03)),
                             "3deg": human_duration(bi.time_to_heading_error_s)},
            }
        if sr.scale_factor is not None:
            impact["scale_factor"] = {"error_pct": 100 * sr.scale_factor.scale_factor_error,
                                      "heading_error_deg": sr.scale_factor.heading_error_deg,
                                      "rel_position_error_pct": 100 * sr.scale_factor.rel_position_error,
                                      "source": sr.scale_factor_source}
        out["pdr_impact"] = impact
    out["filter"] = sr.filter
    out["flags"] = flags
    return out


def report_dict(res: RecordingResult) -> dict[str, Any]:
    """The full JSON report of one recording."""
    rec = {"source": res.source, "format": res.format, "device": res.device, "duration_s": res.duration_s,
           "temperature": res.temperature, "warnings": list(res.warnings), "meta": res.meta}
    out: dict[str, Any] = {"schema": SCHEMA, "recording": rec, "settings": asdict(res.settings)}
    flags: list[str] = list(res.warnings)
    for s, sr in res.sensors.items():
        out[s] = sensor_dict(sr)
        flags += [f"{s}: {f}" for f in out[s]["flags"] if not f.startswith(f"{s} ")] + \
                 [f for f in out[s]["flags"] if f.startswith(f"{s} ")]
    out["flags"] = flags
    return jsonable(out)


def write_report(res: RecordingResult, out_dir: str | Path) -> dict[str, Path]:
    """Write report.json, <sensor>.png, report.html, imu.yaml and filter_params.json into ``out_dir``."""
    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    data = report_dict(res)
    paths = {"json": d / "report.json", "html": d / "report.html", "yaml": d / "imu.yaml",
             "filter": d / "filter_params.json"}
    paths["json"].write_text(json.dumps(data, indent=1, allow_nan=False))
    pngs: dict[str, bytes] = {}
    for s, sr in res.sensors.items():
        p = d / f"{s}.png"
        pngs[s] = plots.write_plot(sr, p, f" - {Path(res.source).name}" if res.source else "")
        paths[f"png_{s}"] = p
    gyro = res.sensors.get("gyro")
    acc = res.sensors.get("acc")
    first = gyro or acc
    rate = first.rate_hz if first is not None else 0.0
    notes = []
    if gyro and acc and abs(gyro.rate_hz - acc.rate_hz) > 1e-6 * gyro.rate_hz:
        notes.append(f"gyro at {gyro.rate_hz:g} Hz, accelerometer at {acc.rate_hz:g} Hz; update_rate is the gyro's")
    paths["yaml"].write_text(filter_params.kalibr_yaml(gyro.filter["sensor"] if gyro else None,
                                                       acc.filter["sensor"] if acc else None, rate,
                                                       source=Path(res.source).name if res.source else "",
                                                       notes=notes))
    paths["filter"].write_text(json.dumps(jsonable({s: sr.filter for s, sr in res.sensors.items()}), indent=1))
    paths["html"].write_text(html_report.render(data, pngs))
    return paths


def comparison_dict(reports: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Spread of the resolved N and B (and K) across several reports of the same sensor model."""
    out: dict[str, Any] = {"sources": [r["recording"]["source"] for r in reports], "sensors": {}}
    for s in ("gyro", "acc"):
        if not all(s in r for r in reports):
            continue
        sens: dict[str, Any] = {}
        axes = [a for a in ("x", "y", "z") if all(a in r[s] for r in reports)]
        for a in axes:
            row: dict[str, Any] = {}
            for k in ("N", "B", "K"):
                vals = [r[s][a][k] for r in reports]
                got = np.array([v for v in vals if v is not None], dtype=float)
                row[k] = {"values": vals, "n_resolved": int(got.size),
                          "mean": float(got.mean()) if got.size else None,
                          "std": float(got.std(ddof=1)) if got.size > 1 else None,
                          "min": float(got.min()) if got.size else None, "max": float(got.max()) if got.size else None,
                          "spread_pct": float(100 * (got.max() - got.min()) / got.mean()) if got.size > 1 else None,
                          "cv_pct": float(100 * got.std(ddof=1) / got.mean()) if got.size > 1 else None}
                if got.size:
                    row[k]["datasheet_mean"] = to_datasheet(s, k, float(got.mean()))
            sens[a] = row
        sens["grades"] = [r[s]["grade"]["overall"] for r in reports]
        out["sensors"][s] = sens
    return jsonable(out)


def write_comparison(reports: Sequence[Mapping[str, Any]], out_dir: str | Path) -> Path:
    """Write ``comparison.json`` for several reports into ``out_dir``."""
    p = Path(out_dir) / "comparison.json"
    p.write_text(json.dumps(comparison_dict(reports), indent=1, allow_nan=False))
    return p
