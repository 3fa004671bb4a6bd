"""``pdr inspect LOG``: what a log holds (format, device, streams with rates and gaps, truth, warnings).

Rates are medians of the sample intervals (``rate_hz``) next to the mean over the whole stream
(``mean_rate_hz``; lower when samples are missing). A gap is an interval longer than ``--gap-factor``
median intervals. Times are seconds on the recording's axis (``t_s``, origin ``t0_ns``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import Any

import numpy as np

from pdr.io import registry
from pdr.preprocess import GAP_FACTOR, find_gaps
from pdr.recording import GroundTruth, Labels, Recording, SensorStream


def _num(x: float) -> float | None:
    """JSON-friendly float: None for NaN/inf."""
    return float(x) if math.isfinite(x) else None


def stream_summary(stream: SensorStream, origin_ns: int, gap_factor: float = GAP_FACTOR) -> dict[str, Any]:
    """Samples, rates (Hz), time span (s), unit, gaps and the median sample norm of one stream."""
    t = stream.t_s(origin_ns)
    n = len(stream)
    gaps = find_gaps(t, factor=gap_factor) if n > 1 else []
    duration = float(t[-1] - t[0]) if n else 0.0
    return {
        "kind": stream.kind,
        "unit": stream.spec.unit,
        "columns": list(stream.spec.columns),
        "samples": n,
        "rate_hz": _num(stream.median_rate_hz()),
        "mean_rate_hz": _num((n - 1) / duration) if duration > 0 else None,
        "duration_s": duration,
        "first_s": float(t[0]) if n else None,
        "last_s": float(t[-1]) if n else None,
        "gaps": len(gaps),
        "longest_gap_s": max(g.duration_s for g in gaps) if gaps else None,
        "median_norm": _num(float(np.median(np.linalg.norm(stream.values, axis=1)))) if n else None,
    }


def _labels_summary(lab: Labels) -> dict[str, Any]:
    return {"intervals": len(lab), "labels": sorted(set(lab.label))}


def truth_summary(truth: GroundTruth) -> dict[str, Any]:
    """Which ground truth is present, with sizes."""
    out: dict[str, Any] = {}
    if truth.positions is not None:
        p = truth.positions
        out["positions"] = {"points": len(p), "kind": p.kind, "frame": p.frame,
                            "floors": sorted({float(f) for f in p.floor[np.isfinite(p.floor)]})
                            if p.floor is not None else []}
    if truth.step_times_s is not None:
        out["step_times_s"] = {"steps": int(truth.step_times_s.size)}
    if truth.step_count is not None:
        out["step_count"] = int(truth.step_count)
    if truth.step_lengths_m is not None:
        out["step_lengths_m"] = {"steps": int(truth.step_lengths_m.size)}
    if truth.modes is not None:
        out["modes"] = _labels_summary(truth.modes)
    if truth.landmarks is not None:
        out["landmarks"] = _labels_summary(truth.landmarks)
    for name, arr in truth.extra.items():
        out.setdefault("extra", {})[name] = {"shape": list(arr.shape), "dtype": str(arr.dtype)}
    return out


def _jsonable(x: Any) -> Any:
    if isinstance(x, Mapping):
        return {str(k): _jsonable(v) for k, v in dict(x).items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.generic):
        return _jsonable(x.item())
    if isinstance(x, float):
        return _num(x)
    if x is None or isinstance(x, str | int | bool):
        return x
    return str(x)


def summarize(recording: Recording, gap_factor: float = GAP_FACTOR) -> dict[str, Any]:
    """Everything ``pdr inspect`` reports, as a JSON-serialisable dict."""
    start, end = recording.time_span_s()
    d = recording.device
    return {
        "source": recording.source,
        "format": recording.format,
        "device": {"platform": d.platform, "model": d.model, "role": d.role, "placement": d.placement,
                   "device_id": d.device_id},
        "t0_ns": recording.origin_ns,
        "start_s": start,
        "end_s": end,
        "duration_s": end - start,
        "streams": [stream_summary(s, recording.origin_ns, gap_factor) for s in recording.streams.values()],
        "truth": truth_summary(recording.truth),
        "location": location_summary(recording),
        "warnings": list(recording.warnings),
        "meta": _jsonable(recording.meta),
    }


def location_summary(recording: Recording) -> dict[str, Any] | None:
    """The log's location fix (``meta["location"]``) and the earth's field there (World Magnetic Model,
    :func:`pdr.geomagnetic.field_at_fix`: what the attitude filter's magnetometer gate checks), or None without a
    fix. ``earth_field`` is None when the model does not answer (no date, or one outside its years).
    """
    from pdr.geomagnetic import field_at_fix
    from pdr.recording import LOCATION_META

    fix = recording.meta.get(LOCATION_META)
    if not isinstance(fix, Mapping) or fix.get("lat_deg") is None or fix.get("lon_deg") is None:
        return None
    earth = field_at_fix(fix)
    return {"lat_deg": float(fix["lat_deg"]), "lon_deg": float(fix["lon_deg"]),
            "unix_time_s": fix.get("unix_time_s"), "fixes": fix.get("fixes"),
            "earth_field": None if earth is None else {"inclination_deg": earth.inclination_deg,
                                                       "declination_deg": earth.declination_deg,
                                                       "intensity_uT": earth.intensity_uT}}


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def format_text(summary: dict[str, Any]) -> str:
    """Human-readable report of :func:`summarize`'s output."""
    d = summary["device"]
    lines = [
        f"file:      {summary['source']}",
        f"format:    {summary['format']}",
        f"device:    {d['platform']} {d['model'] or '(model unknown)'}, role {d['role']}, "
        f"placement {d['placement'] or 'unknown'}" + (f", id {d['device_id']}" if d["device_id"] else ""),
        f"duration:  {summary['duration_s']:.3f} s (t_s {summary['start_s']:.3f} .. {summary['end_s']:.3f}, "
        f"t0_ns {summary['t0_ns']})",
        "streams:",
        f"  {'kind':<12}{'samples':>9}{'rate_Hz':>10}{'mean_Hz':>10}{'duration_s':>12}{'first_s':>11}"
        f"{'last_s':>11}  {'unit':<7}{'|v|_med':>10}{'gaps':>6}{'longest_s':>11}",
    ]
    for s in summary["streams"]:
        lines.append(
            f"  {s['kind']:<12}{s['samples']:>9}{_fmt(s['rate_hz'], '.2f'):>10}{_fmt(s['mean_rate_hz'], '.2f'):>10}"
            f"{s['duration_s']:>12.3f}{_fmt(s['first_s'], '.3f'):>11}{_fmt(s['last_s'], '.3f'):>11}  "
            f"{s['unit']:<7}{_fmt(s['median_norm'], '.4g'):>10}{s['gaps']:>6}{_fmt(s['longest_gap_s'], '.3f'):>11}")
    truth = summary["truth"]
    if not truth:
        lines.append("truth:     none")
    else:
        lines.append("truth:")
        for name, info in truth.items():
            if name == "extra":
                for k, v in info.items():
                    lines.append(f"  extra.{k}: shape {tuple(v['shape'])} {v['dtype']}")
            elif isinstance(info, dict):
                lines.append(f"  {name}: " + ", ".join(f"{k} {v}" for k, v in info.items()))
            else:
                lines.append(f"  {name}: {info}")
    loc = summary["location"]
    if loc is not None:
        when = ("" if loc["unix_time_s"] is None else
                f", {datetime.fromtimestamp(loc['unix_time_s'], tz=UTC):%Y-%m-%d %H:%M} UTC")
        fixes = f" (first of {loc['fixes']} fixes)" if loc["fixes"] else ""
        lines.append(f"location:  {loc['lat_deg']:.5f}, {loc['lon_deg']:.5f}{when}{fixes}")
        e = loc["earth_field"]
        lines.append("  earth's field there (World Magnetic Model): " + (
            "unknown (no date, or one outside the model's years)" if e is None else
            f"dip {e['inclination_deg']:.1f} deg, declination {e['declination_deg']:+.1f} deg, "
            f"{e['intensity_uT']:.1f} uT (the magnetometer gate's dip)"))
    if summary["warnings"]:
        lines.append("warnings:")
        lines += [f"  - {w}" for w in summary["warnings"]]
    else:
        lines.append("warnings:  none")
    return "\n".join(lines)


def _list_formats(as_json: bool) -> int:
    formats = registry.format_descriptions()
    if as_json:
        print(json.dumps(formats, indent=1))
    else:
        width = max(len(n) for n in formats)
        for name, desc in formats.items():
            print(f"{name:<{width}}  {desc}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.formats:
        return _list_formats(args.json)
    if args.log is None:
        print("error: give a LOG to inspect (or --formats)", file=sys.stderr)
        return 2
    recording = registry.read_recording(args.log, args.format)
    summary = summarize(recording, args.gap_factor)
    if args.json:
        print(json.dumps(summary, indent=1, allow_nan=False))
    else:
        print(format_text(summary))
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "inspect", help="show a log's format, device, streams (rates, durations, gaps, units) and truth",
        description=__doc__.split("\n\n", 1)[0] if __doc__ else None)
    p.add_argument("log", nargs="?", metavar="LOG", help="log file or folder")
    p.add_argument("--format", metavar="F", help="force a reader instead of detecting the format "
                   "(see --formats)")
    p.add_argument("--json", action="store_true", help="print a JSON document instead of text")
    p.add_argument("--formats", action="store_true", help="list the supported formats and exit")
    p.add_argument("--gap-factor", type=float, default=GAP_FACTOR, metavar="K",
                   help=f"an interval longer than K median intervals is a gap (default {GAP_FACTOR:g})")
    p.set_defaults(func=run)
