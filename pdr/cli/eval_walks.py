"""``pdr eval ipin|ms|steps DIR``: the phone pipeline's tracks and step counts scored against the datasets'
truth (landmarks, waypoints, step counts), beside the phone's own attitude and a plain step counter.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import re
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from pdr.cli import progress
from pdr.cli.track import (
    common_options,
    compile_ahead,
    config_from_args,
    reference_rows,
    rows_notices,
    run_pipeline,
)
from pdr.errors import InputError, UnknownFormatError
from pdr.evaluation.error_budget import BUDGET_TRACKS, budget_tracks
from pdr.evaluation.mocap_steps import (
    MOCAP_MATCH_S,
    matched_steps,
    mocap_step_count,
    mocap_step_times,
    mocap_trajectory,
)
from pdr.evaluation.scoring import (
    WALK_EDGE_S,
    absolute_waypoint_errors,
    alternating_contacts,
    bounce_free_step_count,
    distance_ratio,
    distance_ratio_same_floor,
    floors_at,
    landmark_errors,
    leg_direction_errors,
    plain_step_count,
    step_count_error_pct,
    unmatched_by_phase,
    waypoint_errors,
)
from pdr.evaluation.walking_recordings import MOBIFALL_NOT_WALKING, MOBIFALL_WALKING
from pdr.io import detect_format, mobifall, read_recording
from pdr.io.text import strip_gz
from pdr.phone.heading_smoother import smoothed_rows
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, PipelineConfig
from pdr.phone.step_length import StepLengthModel
from pdr.phone.steps import StepConfig
from pdr.phone.track_schema import write_csv
from pdr.recording import Recording

if TYPE_CHECKING:
    # The map matcher (its compiled kernels, the site's plans) is imported where a command line asks for it.
    from pdr.mapmatch.particles import MapMatchConfig
    from pdr.site.plan import SitePlan

T = TypeVar("T")


def register_eval_ipin(targets: argparse._SubParsersAction) -> None:
    _register_eval(targets, "ipin",
                   "IPIN logfiles: landmark error (absolute and first-segment aligned), distance ratio", eval_ipin)


def register_eval_ms(targets: argparse._SubParsersAction) -> None:
    _register_eval(targets, "ms", "MS indoor traces: waypoint error after start and rotation alignment", eval_ms)


def register_eval_steps(targets: argparse._SubParsersAction) -> None:
    _register_eval(targets, "steps", "step-count error per walk and placement (Oxford step counter, Sensor Logger "
                   "walks, attitude_smartphones motion capture; MobiFall counts only)", eval_steps)


def _register_eval(targets: argparse._SubParsersAction, name: str, helptext: str,
                   func: Callable[[argparse.Namespace], int]) -> None:
    """``pdr eval NAME`` (ipin, ms, steps): the options these phone evaluations share, and NAME's own."""
    p = targets.add_parser(name, help=helptext)
    p.add_argument("dir", help="dataset folder (searched recursively), or one log file")
    p.add_argument("--json", action="store_true", help="print figures as JSON")
    p.add_argument("--tracks", help="also write each track CSV into this folder (for tools/score_tracks.py)")
    p.add_argument("--limit", type=int, default=0, help="only the first N files (0: all)")
    if name != "steps":
        common_options(p)
    else:
        p.add_argument("--step", metavar="JSON", default="{}",
                       help="step detector parameters (pdr.phone.steps.StepConfig fields) as a JSON object, e.g. "
                            "'{\"floor_gain\": 1.0, \"slow_missed_steps\": true, \"gait_min_corr\": 0.5}'"
                            " (the automatic peak-floor gain, gated by gait periodicity)")
    if name == "ms":
        p.add_argument("--map", action="store_true",
                       help="also map-match each trace on its floor's plan (pdr.site.ms: the floor folder's "
                            "geojson_map.json), starting at its first waypoint with the heading unknown, and score "
                            "it absolutely (no rotation): online and offline-smoothed, beside PDR from the same "
                            "start")
        p.add_argument("--map-config", metavar="JSON", default="{}",
                       help="particle filter parameters (pdr.mapmatch.particles.MapMatchConfig fields) as JSON")
        p.add_argument("--calibrate", default="none", choices=("none", "cross"),
                       help="also score each trace (and map-match it, with --map) after recalibrating the "
                            "step-length scale K (pdr calibrate) on the traces of the OTHER floor folders walked "
                            "with the same phone (never the trace's own floor): tune on F3, report on F4 and the "
                            "reverse")
    if name == "ipin":
        p.add_argument("--calibrate", default="none", choices=("none", "cross", "cross-rep"),
                       help="also score each log after recalibrating the step-length scale K (pdr calibrate) "
                            "on OTHER logs of the same phone: cross = its other routes, cross-rep = the other "
                            "repetitions of its route (never the log itself)")
        p.add_argument("--smoother", default="both", choices=("both", "off"),
                       help="both: also score the offline-smoothed tracks (pdr track's default; "
                            "pdr.phone.heading_smoother) next to the causal ones")
        p.add_argument("--budget", action="store_true",
                       help="also score the track (smoothed when --smoother both) re-walked with the true "
                            "heading of each straight leg, with its length scaled to the truth, and both "
                            "(pdr.evaluation.error_budget): how much of the error heading and step-length "
                            "scale explain")
        p.add_argument("--legs", action="store_true",
                       help="also print, per leg between two landmarks on one floor at least 3 m apart, the true "
                            "bearing and the direction error of the causal, smoothed and reference tracks over it "
                            "(where a walk's heading goes wrong)")
        p.add_argument("--trim-start", type=float, default=0.0, metavar="S",
                       help="drop each log's first S seconds (refused if that reaches its first landmark): "
                            "shows how much the figures depend on the start conditions")
    p.set_defaults(func=func)


def _files(d: str, patterns: tuple[str, ...], log_of: Callable[[Path], Path] = lambda f: f) -> list[Path]:
    """The dataset's logs matching ``patterns`` under folder ``d``, or ``d`` itself when it is one such file;
    an InputError when there is none (an evaluation of nothing would print ``ALL (0 files) ... nan``).

    In a folder, a matching file whose log (``log_of(file)``: the file, or for a folder-format log its folder) no
    reader recognises (a dataset's ``README.txt``) is left out, and named on stderr.
    """
    root = Path(d)
    if not root.exists():
        raise InputError("no such file or folder", source=d)
    if root.is_file():
        if any(root.match(pat) for pat in patterns):
            return [root]
        raise InputError(f"not a log this evaluation reads: give a folder of, or one file named, "
                         f"{' or '.join(patterns)}", source=d)
    found: set[Path] = set()
    for pat in patterns:
        found.update(root.rglob(pat))
    out, not_logs = [], []
    for f in sorted(found):
        try:
            detect_format(log_of(f))
            out.append(f)
        except UnknownFormatError:
            not_logs.append(f)
    if not_logs:
        print(f"{d}: left out {len(not_logs)} file(s) that are not a supported log: "
              + ", ".join(str(f.relative_to(root)) for f in not_logs), file=sys.stderr)
    if not out:
        raise InputError(f"no {' or '.join(patterns)} files in this folder or below it"
                         + (" that a reader recognises" if not_logs else ""), source=d)
    return out


def _one_copy_per_walk(d: str, files: list[Path]) -> list[Path]:
    """``files`` less every MATLAB copy (``.mat``) of a walk that is also there as a text log: the IPIN package ships
    some walks in both formats (``../shared/data/ipin2023_t3``: trial 52 repetition 01), and scoring both would count
    that walk twice in the overall figures. The text log is kept (it has the phone's own orientation, the
    reference). Those left out are named on stderr.
    """
    def walk(f: Path) -> str:
        return strip_gz(f.name).rsplit(".", 1)[0]

    texts = {walk(f) for f in files if f.suffix != ".mat"}
    copies = [f for f in files if f.suffix == ".mat" and walk(f) in texts]
    if copies:
        print(f"{d}: left out {len(copies)} MATLAB copy(ies) of a walk also given as a text log: "
              + ", ".join(f.name for f in copies), file=sys.stderr)
    return [f for f in files if f not in copies]


def _pct(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) if a.size else math.nan


def _emit(summary: dict[str, Any], per_file: list[dict[str, Any]], as_json: bool, lines: Iterator[str]) -> None:
    if as_json:
        print(json.dumps({"overall": summary, "files": per_file}, indent=2))
    else:
        for line in lines:
            print(line)


def _floor_changes(events: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and new floors of the pipeline's floor changes."""
    ch = [(float(e["t_s"]), float(e["floor"])) for e in events if e.get("type") == "floor_change"]
    return np.array([c[0] for c in ch]), np.array([c[1] for c in ch])


def _track_arrays(rows: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """A track's step times (s) and east/north positions (N, 2; m)."""
    return np.array([r["t_s"] for r in rows]), np.array([[r["east_m"], r["north_m"]] for r in rows])


def _ipin_scores(rows: list[dict[str, Any]], t_truth: np.ndarray, pt: Any,
                 changes: tuple[np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0))) -> dict[str, Any]:
    """Landmark errors, distance ratios and floor agreement of one track (see :mod:`pdr.evaluation.scoring`;
    ``changes``: the times (s) and floors of the pipeline's floor changes, for the floor at each landmark).
    """
    t, en = _track_arrays(rows)
    e_abs = landmark_errors(t, en, t_truth, pt.pos_m, "none")
    e_al = landmark_errors(t, en, t_truth, pt.pos_m, "first-segment")
    floors = pt.floor if pt.floor is not None else np.zeros(len(t_truth))
    floors_ok = None
    if pt.floor is not None and np.isfinite(pt.floor).all():
        floors_ok = int(np.sum(floors_at(t_truth, float(pt.floor[0]), *changes) == pt.floor))
    return {"steps": len(rows), "landmarks": int(e_abs.size), "p75_abs_m": _pct(e_abs, 75),
            "median_abs_m": _pct(e_abs, 50), "p75_aligned_m": _pct(e_al, 75),
            "distance_ratio": distance_ratio(t, en, t_truth, pt.pos_m),
            "distance_ratio_same_floor": distance_ratio_same_floor(t, en, t_truth, pt.pos_m, floors),
            "floors_right": floors_ok, "floor_landmarks": len(t_truth), "_abs": e_abs, "_aligned": e_al,
            "steps_before_first_landmark": int(np.sum(t < t_truth[0]))}


def _ipin_legs(tracks: dict[str, list[dict[str, Any]] | None], t_truth: np.ndarray, pt: Any) -> list[dict[str, Any]]:
    """Per leg of the landmark truth (:func:`pdr.evaluation.scoring.leg_direction_errors`): its times, length and
    true bearing, and each named track's direction error over it (deg; None where the track is absent).
    """
    legs: list[dict[str, Any]] = []
    for name, rows in tracks.items():
        if rows is None or len(rows) < 2:
            continue
        t, en = _track_arrays(rows)
        for i, leg in enumerate(leg_direction_errors(t, en, t_truth, pt.pos_m, pt.floor)):
            if i == len(legs):
                legs.append({k: v for k, v in leg.items() if k != "error_deg"} | {n: None for n in tracks})
            legs[i][name] = leg["error_deg"]
    return legs


def _legs_lines(legs: list[dict[str, Any]], t_first_s: float) -> Iterator[str]:
    """One line per leg, times from the first landmark."""
    for leg in legs:
        errors = ", ".join(f"{name} " + ("n/a" if leg[name] is None else f"{leg[name]:+.1f}")
                           for name in LEG_TRACKS)
        yield (f"  leg {leg['t0_s'] - t_first_s:6.1f}-{leg['t1_s'] - t_first_s:6.1f} s, {leg['length_m']:5.1f} m, "
               f"true bearing {leg['true_deg']:5.1f} deg: direction error {errors} deg")


def _legs_summary(per: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean absolute direction error (deg) per track over every leg of the scored walks (None: no such track)."""
    legs = [leg for p in per for leg in p.get("legs", [])]
    means: dict[str, float | None] = {}
    for n in LEG_TRACKS:
        e = [abs(leg[n]) for leg in legs if leg[n] is not None]
        means[f"{n}_mean_abs_deg"] = float(np.mean(e)) if e else None
    return {"legs": len(legs), **means}


def _legs_summary_line(m: dict[str, Any]) -> str:
    means = ", ".join(f"{n} " + ("n/a" if m[f"{n}_mean_abs_deg"] is None else f"{m[f'{n}_mean_abs_deg']:.1f}")
                      for n in LEG_TRACKS)
    return f"LEGS: mean |direction error| over {m['legs']} legs: {means} deg"


#: The tracks whose direction per leg ``--legs`` prints, in order.
LEG_TRACKS = ("ours", "smoothed", "reference")


def _ipin_summary(scores: list[dict[str, Any]]) -> dict[str, Any]:
    a = np.concatenate([p["_abs"] for p in scores]) if scores else np.zeros(0)
    s = np.concatenate([p["_aligned"] for p in scores]) if scores else np.zeros(0)
    r = np.array([p["distance_ratio"] for p in scores])
    rf = np.array([p["distance_ratio_same_floor"] for p in scores])
    rf = rf[np.isfinite(rf)]
    with_floor = [p for p in scores if p["floors_right"] is not None]
    return {"files": len(scores), "median_abs_m": _pct(a, 50), "p75_abs_m": _pct(a, 75),
            "steps": sum(p["steps"] for p in scores),
            "steps_before_first_landmark": sum(p["steps_before_first_landmark"] for p in scores),
            "files_with_steps_before_first_landmark": sum(p["steps_before_first_landmark"] > 0 for p in scores),
            "floors_right": sum(p["floors_right"] for p in with_floor),
            "floor_landmarks": sum(p["floor_landmarks"] for p in with_floor),
            "median_aligned_m": _pct(s, 50), "p75_aligned_m": _pct(s, 75),
            "distance_ratio_median": _pct(r, 50), "distance_ratio_iqr": [_pct(r, 25), _pct(r, 75)],
            "abs_ratio_minus_1_median": _pct(np.abs(r - 1), 50), "abs_ratio_minus_1_max": _pct(np.abs(r - 1), 100),
            "same_floor_ratio_median": _pct(rf, 50), "same_floor_ratio_iqr": [_pct(rf, 25), _pct(rf, 75)],
            "same_floor_abs_ratio_minus_1_max": _pct(np.abs(rf - 1), 100),
            "same_floor_outside_3pct": int(np.sum(np.abs(rf - 1) > 0.03))}


def _steps_before_line(m: dict[str, Any]) -> str:
    """The steps found before the first landmark: every IPIN 2023 log starts with its calibration (20-40 s of
    arbitrary motion, then 20-40 s standing; the dataset's SOURCE.md), so none of them is a walking step.
    """
    n, total, files = m["steps_before_first_landmark"], m["steps"], m["files_with_steps_before_first_landmark"]
    return (f"steps before the first landmark (the logs' calibration: arbitrary motion, then a stand; no walking "
            f"step): {n} of {total} ({100.0 * n / max(total, 1):.1f} %), in {files} of {m['files']} files")


def _ipin_summary_line(label: str, m: dict[str, Any]) -> str:
    return (f"{label} ({m['files']} files): absolute median {m['median_abs_m']:.2f} "
            f"p75 {m['p75_abs_m']:.2f} m; aligned median {m['median_aligned_m']:.2f} "
            f"p75 {m['p75_aligned_m']:.2f} m; distance ratio median {m['distance_ratio_median']:.3f} "
            f"(IQR {m['distance_ratio_iqr'][0]:.3f}-{m['distance_ratio_iqr'][1]:.3f}), "
            f"max |ratio-1| {m['abs_ratio_minus_1_max']:.3f}; same-floor distance ratio median "
            f"{m['same_floor_ratio_median']:.3f} (IQR {m['same_floor_ratio_iqr'][0]:.3f}-"
            f"{m['same_floor_ratio_iqr'][1]:.3f}), max |ratio-1| "
            f"{m['same_floor_abs_ratio_minus_1_max']:.3f}, {m['same_floor_outside_3pct']} outside 3 %; floors-right "
            f"{_floors_right(m)}")


def _floors_right(m: dict[str, Any]) -> str:
    """``right/landmarks (percent)`` of the landmarks on the right floor, or ``n/a`` without floor truth."""
    n = m["floor_landmarks"] if m["floors_right"] is not None else 0
    return f"{m['floors_right']}/{n} ({100.0 * m['floors_right'] / n:.1f} %)" if n else "n/a"


def _recalibrated(done: list[dict[str, Any]], i: int, groups: list[str], mode: str
                  ) -> tuple[StepLengthModel, Recording, list[dict[str, Any]]] | None:
    """For the ``i``-th log of ``done``: the step-length model calibrated on its partners' walks (the same phone's
    logs of other ``groups``, :func:`pdr.cli.calibrate.calibration_partners` and ``calibrate_on_walks``), its
    recording read again and the partners; None (the log marked) when there is no partner to calibrate on.
    """
    from pdr.cli.calibrate import calibrate_on_walks, calibration_partners

    phones, usable = [d["phone"] for d in done], [d["walk"] is not None for d in done]
    partners = [done[k] for k in calibration_partners(i, groups, phones, usable, mode)]
    d = done[i]
    if not partners:
        d["per"]["calibrated"] = {"error": "no calibration walk"}
        return None
    model = calibrate_on_walks(d["cfg"].step_length, [o["walk"] for o in partners])
    return model, read_recording(d["path"]), partners


def _trim_start(rec: Recording, trim_s: float, first_landmark_s: float) -> Recording:
    """``rec`` without its first ``trim_s`` seconds; refused when that would reach the first landmark."""
    if trim_s == 0:
        return rec
    start, end = rec.time_span_s()
    if not (0 < trim_s and start + trim_s < first_landmark_s):
        raise InputError(f"--trim-start {trim_s} s must be positive and end before the first landmark "
                         f"({first_landmark_s - start:.1f} s into the log)", source=rec.source or None,
                         field="trim_start")
    return rec.slice_time(start + trim_s, end + 1.0)


def eval_ipin(args: argparse.Namespace) -> int:
    """Per-file and overall IPIN figures; with ``--calibrate`` also after a per-phone step-length calibration.

    ``--calibrate cross``: each log's step-length scale K is recalibrated (``pdr calibrate``'s code,
    :func:`pdr.cli.calibrate.calibrate_on_walks`) on the same phone's logs of OTHER routes, over their
    landmark intervals on one floor; ``cross-rep``: on the other repetitions of the same route with the same
    phone. The evaluated log never takes part in its own calibration. The phone model stands for the walker.
    With ``--smoother both`` (the default) the calibrated tracks are also scored after the offline heading smoother.
    """
    from dataclasses import replace

    from pdr.cli.calibrate import landmark_walk, trial_key
    files = _one_copy_per_walk(args.dir, _files(args.dir, ("*.txt", "*.txt.gz", "*.mat")))
    if args.limit:
        files = files[:args.limit]
    per: list[dict[str, Any]] = []
    done: list[dict[str, Any]] = []           # scored files with what a second pass needs
    site = Site.load(args.site) if args.site else None
    if files:
        compile_ahead(args.method)
    for f in progress.each(files, "eval ipin"):
        rec = read_recording(f)
        pt = rec.truth.positions
        if pt is None or len(pt) < 2:
            per.append({"file": f.name, "error": "no truth to score against (fewer than 2 positions)"})
            continue
        t_truth = rec.origin_ns / 1e9 + pt.t_s
        rec = _trim_start(rec, args.trim_start, float(t_truth[0]))
        floor0 = float(pt.floor[0]) if pt.floor is not None and np.isfinite(pt.floor[0]) else 0.0
        cfg = config_from_args(args, floor0)
        events = PdrPipeline(cfg, site).run(rec)
        rows, notices = rows_notices(events)
        changes = _floor_changes(events)
        name = f.name[:-4] if f.name.endswith(".txt") else f.name
        smoothed = smoothed_rows(rows, notices) if args.smoother == "both" else None
        if args.tracks:
            Path(args.tracks).mkdir(parents=True, exist_ok=True)
            write_csv(rows, Path(args.tracks) / (name.removesuffix(".txt") + ".csv"))
            if smoothed is not None:
                write_csv(smoothed, Path(args.tracks) / (name.removesuffix(".txt") + ".smoothed.csv"))
        if len(rows) < 2:
            per.append({"file": f.name, "steps": len(rows), "error": "empty track", "notices": notices})
            continue
        walk = landmark_walk(rows, t_truth, pt.pos_m, pt.floor)
        # Metres per detected step the truth implies on one floor (the walker's stride, if no step is missed).
        p = {"file": f.name, "phone": rec.device.model, **_ipin_scores(rows, t_truth, pt, changes),
             "truth_m_per_step": walk.length_m / walk.patterns.shape[0] if walk is not None else math.nan}
        if smoothed is not None:
            p["smoothed"] = _ipin_scores(smoothed, t_truth, pt, changes)
        ref = reference_rows(rec, cfg, site)
        if ref is not None and len(ref) >= 2:
            p["reference"] = _ipin_scores(ref, t_truth, pt, changes)   # floors: the same barometer
            if args.smoother == "both":
                p["reference"]["smoothed"] = _ipin_scores(smoothed_rows(ref, []), t_truth, pt, changes)
        if args.legs:
            p["legs"] = _ipin_legs({"ours": rows, "smoothed": smoothed, "reference": ref}, t_truth, pt)
            p["_t_first_s"] = float(t_truth[0])
        if args.budget:
            p["budget"] = {name: _ipin_scores(track, t_truth, pt) for name, track in
                           budget_tracks(smoothed or rows, t_truth, pt.pos_m, pt.floor).items()}
        per.append(p)
        done.append({"path": f, "per": p, "cfg": cfg, "route": trial_key(f), "phone": rec.device.model,
                     "walk": walk})
    if not done:
        why = "; ".join(f"{p['file']}: {p['error']}" for p in per[:5])
        raise InputError(f"none of the {len(files)} file(s) could be scored ({why})", source=args.dir)
    summary = _ipin_summary([d["per"] for d in done])
    if args.smoother == "both":
        summary["smoothed"] = _ipin_summary([d["per"]["smoothed"] for d in done])
    summary["reference"] = _reference_summary([d["per"] for d in done], args.smoother == "both")
    if args.legs:
        summary["legs"] = _legs_summary([d["per"] for d in done])
    if args.budget:
        summary["budget"] = {"of": "smoothed" if args.smoother == "both" else "causal",
                             **{name: _ipin_summary([d["per"]["budget"][name] for d in done])
                                for name in BUDGET_TRACKS}}
    calibrated: list[dict[str, Any]] = []
    calibrated_smoothed: list[dict[str, Any]] = []
    if args.calibrate != "none":
        routes = [d["route"] for d in done]
        for i, d in enumerate(done):
            recalibrated = _recalibrated(done, i, routes, args.calibrate)
            if recalibrated is None:
                continue
            model, rec, partners = recalibrated
            truth = rec.truth.positions
            assert truth is not None   # scored in the first pass
            rec = _trim_start(rec, args.trim_start, rec.origin_ns / 1e9 + float(truth.t_s[0]))
            events = PdrPipeline(replace(d["cfg"], step_length=model), site).run(rec)
            rows, changes = rows_notices(events)[0], _floor_changes(events)
            t_truth = rec.origin_ns / 1e9 + truth.t_s
            c = {"k": model.k, "calibrated_on": [o["path"].name for o in partners],
                 **_ipin_scores(rows, t_truth, truth, changes)}
            if args.smoother == "both":
                c["smoothed"] = _ipin_scores(smoothed_rows(rows, []), t_truth, truth, changes)
                calibrated_smoothed.append(c["smoothed"])
            d["per"]["calibrated"] = c
            calibrated.append(c)
        summary["calibrated"] = {"mode": args.calibrate, **_ipin_summary(calibrated)}
        if calibrated_smoothed:
            summary["calibrated"]["smoothed"] = _ipin_summary(calibrated_smoothed)
        summary["calibrated"]["without_calibration_walk"] = len(done) - len(calibrated)

    def lines() -> Iterator[str]:
        for p in per:
            if "error" in p:
                yield f"{p['file']}: {p['error']}"
                continue
            line = (f"{p['file']}: p75 {p['p75_abs_m']:.2f} m absolute, {p['p75_aligned_m']:.2f} m aligned, "
                    f"ratio {p['distance_ratio']:.3f} (same floor {p['distance_ratio_same_floor']:.3f}), "
                    f"{p['steps']} steps ({p['truth_m_per_step']:.3f} m/step on one floor by truth, "
                    f"{p['phone'] or 'phone ?'}; {p['steps_before_first_landmark']} before the first landmark), "
                    f"floors-right {_floors_right(p)}")
            sm = p.get("smoothed")
            if sm is not None:
                line += (f" | smoothed p75 {sm['p75_abs_m']:.2f} m absolute, {sm['p75_aligned_m']:.2f} m aligned")
            ref = p.get("reference")
            line += (" | reference n/a" if ref is None else
                     f" | p75 ours {p['p75_abs_m']:.2f} reference {ref['p75_abs_m']:.2f} m" + (
                         f", smoothed ours {sm['p75_abs_m']:.2f} reference {ref['smoothed']['p75_abs_m']:.2f} m"
                         if sm is not None and "smoothed" in ref else ""))
            c = p.get("calibrated")
            if c is not None:
                line += (f" | {c['error']}" if "error" in c else
                         f" | calibrated K {c['k']:.4f} on {len(c['calibrated_on'])} logs: ratio "
                         f"{c['distance_ratio']:.3f} (same floor {c['distance_ratio_same_floor']:.3f}), "
                         f"p75 {c['p75_abs_m']:.2f} m absolute" + (
                             f" (smoothed {c['smoothed']['p75_abs_m']:.2f} m)" if "smoothed" in c else ""))
            yield line
            if "legs" in p:
                yield from _legs_lines(p["legs"], p["_t_first_s"])
        yield _ipin_summary_line("ALL", summary)
        yield _steps_before_line(summary)
        if "legs" in summary:
            yield _legs_summary_line(summary["legs"])
        if "smoothed" in summary:
            yield _ipin_summary_line("SMOOTHED (offline, pdr track's default)", summary["smoothed"])
        yield from _reference_lines(summary["reference"])
        if "calibrated" in summary:
            m = summary["calibrated"]
            yield _ipin_summary_line(f"CALIBRATED --calibrate {m['mode']}", m) + (
                f"; {m['without_calibration_walk']} files without a calibration walk (default model)"
                if m["without_calibration_walk"] else "")
            if "smoothed" in m:
                yield _ipin_summary_line(f"CALIBRATED --calibrate {m['mode']} and SMOOTHED", m["smoothed"])
        if "budget" in summary:
            b = summary["budget"]
            for name in BUDGET_TRACKS:
                yield _ipin_summary_line(f"BUDGET {b['of']} track with {name.replace('_', ' ')}", b[name])
    out = [_public(p) for p in per]
    _emit(summary, out, args.json, lines())
    return 0


#: Ours loses to the reference on a walk when its p75 is larger by more than this (m; issue 25's target).
REFERENCE_MARGIN_M = 1.0


def _reference_summary(per: list[dict[str, Any]], smoothed: bool) -> dict[str, Any]:
    """The phone's-attitude reference over the walks that have one (:func:`reference_rows`), and the walks where
    ours is worse than it by more than :data:`REFERENCE_MARGIN_M` p75 (causal, and smoothed against smoothed).
    """
    have = [p for p in per if "reference" in p]
    out: dict[str, Any] = {"without_reference": len(per) - len(have)}
    if not have:
        return out
    out.update(_ipin_summary([p["reference"] for p in have]))
    out["worse_than_reference"] = [p["file"] for p in have
                                   if p["p75_abs_m"] > p["reference"]["p75_abs_m"] + REFERENCE_MARGIN_M]
    if smoothed:
        out["smoothed"] = _ipin_summary([p["reference"]["smoothed"] for p in have])
        out["smoothed_worse_than_reference"] = [
            p["file"] for p in have
            if p["smoothed"]["p75_abs_m"] > p["reference"]["smoothed"]["p75_abs_m"] + REFERENCE_MARGIN_M]
    return out


def _reference_lines(ref: dict[str, Any]) -> Iterator[str]:
    if "files" not in ref:
        yield f"REFERENCE (phone's own attitude): n/a ({ref['without_reference']} files without orientation stream)"
        return
    n = ref["files"]
    yield _ipin_summary_line("REFERENCE (phone's own attitude)", ref)
    if "smoothed" in ref:
        yield _ipin_summary_line("REFERENCE SMOOTHED", ref["smoothed"])
    for key, what in (("worse_than_reference", "causal"), ("smoothed_worse_than_reference", "smoothed")):
        if key in ref:
            yield (f"ours worse than the reference by more than {REFERENCE_MARGIN_M:.0f} m p75 ({what}): "
                   f"{len(ref[key])} of {n} walks" + (f" ({', '.join(ref[key])})" if ref[key] else ""))
    if ref["without_reference"]:
        yield f"{ref['without_reference']} files without orientation stream: reference n/a"


def _public(d: dict[str, Any]) -> dict[str, Any]:
    """``d`` and its nested dicts without the private (``_``-prefixed) arrays, for JSON output."""
    return {k: _public(v) if isinstance(v, dict) else v for k, v in d.items() if not k.startswith("_")}


def _ms_floor(path: Path) -> str:
    """The floor folder (``F3``, ``B1``, ...) in a MS trace's path, or ``?``."""
    for part in reversed(path.parts[:-1]):
        if re.fullmatch(r"[FB]\d+", part):
            return part
    return "?"


def _ms_scores(rows: list[dict[str, Any]], rec: Recording, pt: Any) -> np.ndarray:
    t = np.array([r["t_s"] for r in rows])
    xy = np.array([[r["east_m"], r["north_m"]] for r in rows])
    return waypoint_errors(t, xy, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m)


def _ms_summary(errs: list[np.ndarray]) -> dict[str, Any]:
    a = np.concatenate(errs) if errs else np.zeros(0)
    return {"traces": len(errs), "median_m": _pct(a, 50), "p75_m": _pct(a, 75)}


def _ms_line(label: str, m: dict[str, Any]) -> str:
    return f"{label}: median {m['median_m']:.2f} p75 {m['p75_m']:.2f} m over {m['traces']} traces"


def eval_ms(args: argparse.Namespace) -> int:
    """Per trace and overall waypoint errors, ours and the reference (the phone's own attitude,
    :func:`reference_rows`) side by side, and per floor folder; with ``--map`` also absolute, map-matched errors.
    """
    from pdr.cli.calibrate import landmark_walk
    files = _files(args.dir, ("*.txt", "*.txt.gz"))
    if args.limit:
        files = files[:args.limit]
    per: list[dict[str, Any]] = []
    errs: list[np.ndarray] = []
    mapped = _MapScores(_map_config(args.map_config)) if args.map else None
    done: list[dict[str, Any]] = []         # scored traces with what the calibrated pass needs
    ours_ref: list[np.ndarray] = []         # ours on the traces that have a reference
    ref_errs: list[np.ndarray] = []
    by_floor: dict[str, dict[str, list[np.ndarray]]] = {}
    for f, rec in progress.each_recording(files, "eval ms", per):
        pt = rec.truth.positions
        if pt is None or len(pt) < 3:
            continue
        cfg = config_from_args(args)
        rows, notices = run_pipeline(rec, cfg)
        if args.tracks:
            Path(args.tracks).mkdir(parents=True, exist_ok=True)
            write_csv(rows, Path(args.tracks) / (f.name + ".csv"))
        if len(rows) < 2:
            per.append({"file": f.name, "steps": len(rows), "error": "empty track"})
            continue
        e = _ms_scores(rows, rec, pt)
        errs.append(e)
        floor = _ms_floor(f)
        fl = by_floor.setdefault(floor, {"ours": [], "ours_with_reference": [], "reference": []})
        fl["ours"].append(e)
        p: dict[str, Any] = {"file": f.name, "floor": floor, "steps": len(rows), "waypoints": int(e.size),
                             "median_m": _pct(e, 50), "p75_m": _pct(e, 75), "reference": None}
        ref = reference_rows(rec, cfg)
        if ref is not None and len(ref) >= 2:
            er = _ms_scores(ref, rec, pt)
            p["reference"] = {"median_m": _pct(er, 50), "p75_m": _pct(er, 75)}
            ours_ref.append(e)
            ref_errs.append(er)
            fl["ours_with_reference"].append(e)
            fl["reference"].append(er)
        if mapped is not None:
            p["map"] = mapped.score(f, rows, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m[:, :2])
        per.append(p)
        done.append({"path": f, "per": p, "cfg": cfg, "floor": floor, "phone": rec.device.model,
                     "walk": landmark_walk(rows, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m)})
    summary: dict[str, Any] = {**_ms_summary(errs), "reference": _ms_summary(ref_errs),
                               "ours_on_reference_traces": _ms_summary(ours_ref),
                               "worse_than_reference": [
                                   p["file"] for p in per if p.get("reference")
                                   and p["p75_m"] > p["reference"]["p75_m"] + REFERENCE_MARGIN_M],
                               "floors": {k: {n: _ms_summary(v) for n, v in d.items()}
                                          for k, d in sorted(by_floor.items())}}
    if mapped is not None:
        summary["map"] = mapped.summary()
    if args.calibrate != "none":
        summary["calibrated"] = _ms_calibrated(done, args)

    def lines() -> Iterator[str]:
        for p in per:
            if "error" in p:
                yield f"{p['file']}: {p['error']}"
                continue
            r = p["reference"]
            line = (f"{p['file']} ({p['floor']}): median {p['median_m']:.2f} p75 {p['p75_m']:.2f} m, {p['steps']} steps"
                    + (" | reference n/a" if r is None else
                       f" | p75 ours {p['p75_m']:.2f} reference {r['p75_m']:.2f} m"))
            if "map" in p:
                m = p["map"]
                line += (f" | absolute from the start: PDR p75 {m['pdr']['p75_m']:.2f}, map online "
                         f"{m['online']['p75_m']:.2f}, map smoothed {m['smoothed']['p75_m']:.2f} m, hindsight "
                         f"bound {m['hindsight']['p75_m']:.2f} m"
                         + (f" ({len(m['notices'])} notices)" if m["notices"] else ""))
            yield line
        yield _ms_line("ALL", summary)
        ref = summary["reference"]
        if ref["traces"]:
            yield _ms_line("REFERENCE (phone's own attitude)", ref)
            if ref["traces"] != summary["traces"]:
                yield _ms_line("ours on the same traces", summary["ours_on_reference_traces"])
            worse = summary["worse_than_reference"]
            yield (f"ours worse than the reference by more than {REFERENCE_MARGIN_M:.0f} m p75: {len(worse)} of "
                   f"{ref['traces']} traces" + (f" ({', '.join(worse)})" if worse else ""))
        else:
            yield "REFERENCE (phone's own attitude): n/a (no trace with an orientation stream)"
        if "calibrated" in summary:
            c = summary["calibrated"]
            yield (_ms_line(f"CALIBRATED --calibrate {args.calibrate} (K on the other floors' traces of the same "
                            "phone)", c) + f"; {c['without_calibration_walk']} traces without a calibration walk")
        for floor, d in summary["floors"].items():
            same = d["reference"]["traces"] == d["ours"]["traces"]
            yield _ms_line(f"FLOOR {floor} ours", d["ours"]) + (
                "; reference n/a" if not d["reference"]["traces"] else
                "; " + _ms_line("reference", d["reference"]) + (
                    "" if same else " (" + _ms_line("ours on them", d["ours_with_reference"]) + ")"))
        if "map" in summary:
            m = summary["map"]
            for name in _MapScores.TRACKS:
                yield _map_line(f"MAP {name} (absolute, from the first waypoint, {m['traces']} traces)", m[name])
            s = m[_MapScores.HINDSIGHT]
            yield (f"MAP bound: PDR turned and scaled about the start by each trace's least-squares rotation and "
                   f"scale on its truth (a constant heading offset and step-length scale known with hindsight): "
                   f"median {s['median_m']:.2f} p75 {s['p75_m']:.2f} m; {s['traces_over_5m']} traces over 5 m p75"
                   + _map_floors(s))
            sp = m["speed"]
            if "calibrated" in summary and "map" in summary["calibrated"]:
                cm = summary["calibrated"]["map"]
                for name in _MapScores.TRACKS:
                    yield _map_line(f"MAP {name} CALIBRATED --calibrate {args.calibrate} ({cm['traces']} traces)",
                                    cm[name])
            yield (f"MAP speed: {sp['particles']} particles, {sp['steps']} steps in {sp['wall_s']:.3f} s = "
                   f"{sp['steps_per_s']:.0f} steps/s, {sp['times_real_time']:.0f}x real time (online filter, "
                   f"warm: kernels loaded before the first timed trace); CPU time {sp['cpu_s']:.3f} s = "
                   f"{sp['times_real_time_cpu']:.0f}x real time (without the wait for other processes on the cores)")
    _emit(summary, per, args.json, lines())
    return 0


def _map_line(label: str, s: dict[str, Any]) -> str:
    """One MAP figure: median and p75 (m), the worst trace and the traces over 5 m p75, per floor folder too."""
    return (f"{label}: median {s['median_m']:.2f} p75 {s['p75_m']:.2f} m; worst trace {s['worst_file']} p75 "
            f"{s['worst_p75_m']:.2f} m; {s['traces_over_5m']} traces over 5 m p75" + _map_floors(s))


def _map_floors(s: dict[str, Any]) -> str:
    """`` | F3 (n): median .. p75 .. m, k over 5 m; F4 ...`` when a MAP figure pools several floor folders."""
    fl = s.get("floors", {})
    if len(fl) < 2:
        return ""
    return " | " + "; ".join(f"{k} ({v['traces']}): median {v['median_m']:.2f} p75 {v['p75_m']:.2f} m, "
                             f"{v['traces_over_5m']} over 5 m" for k, v in fl.items())


def _ms_calibrated(done: list[dict[str, Any]], args: argparse.Namespace) -> dict[str, Any]:
    """``pdr eval ms --calibrate cross``: each trace re-run with the step-length scale K recalibrated
    (:func:`pdr.cli.calibrate.calibrate_on_walks`) on the same phone's traces of the other floor folders, scored as
    the uncalibrated ones (rotation about the start; with ``--map`` also map-matched, absolutely).
    """
    from dataclasses import replace

    floors = [d["floor"] for d in done]
    mapped = _MapScores(_map_config(args.map_config)) if args.map else None
    errs: list[np.ndarray] = []
    for i, d in enumerate(progress.each(done, "eval ms --calibrate")):
        recalibrated = _recalibrated(done, i, floors, "cross")
        if recalibrated is None:
            continue
        model, rec, partners = recalibrated
        pt = rec.truth.positions
        assert pt is not None           # scored in the first pass
        rows, _ = run_pipeline(rec, replace(d["cfg"], step_length=model))
        if len(rows) < 2:
            d["per"]["calibrated"] = {"error": "empty track"}
            continue
        e = _ms_scores(rows, rec, pt)
        errs.append(e)
        c: dict[str, Any] = {"k": model.k, "calibrated_on": len(partners), "median_m": _pct(e, 50),
                             "p75_m": _pct(e, 75)}
        if mapped is not None:
            c["map"] = mapped.score(d["path"], rows, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m[:, :2])
        d["per"]["calibrated"] = c
    out: dict[str, Any] = {"mode": args.calibrate, **_ms_summary(errs),
                           "without_calibration_walk": len(done) - len(errs)}
    if mapped is not None:
        out["map"] = mapped.summary()
    return out


def _map_config(text: str) -> MapMatchConfig:
    """``--map-config JSON`` as a :class:`MapMatchConfig` (unknown fields and bad JSON are refused naming them)."""
    from pdr.mapmatch.particles import MapMatchConfig
    return _json_config(text, MapMatchConfig, "map-config")


def _json_config(text: str, cls: Callable[..., T], option: str) -> T:
    """``--OPTION JSON`` (a JSON object of ``cls``'s fields) as a ``cls``; bad JSON and unknown fields are refused
    naming the option.
    """
    field = option.replace("-", "_")
    try:
        fields = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"--{option}: not JSON ({exc})", field=field, source="command line") from None
    if not isinstance(fields, dict):
        raise InputError(f"--{option} must be a JSON object", field=field, source="command line")
    try:
        return cls(**fields)
    except TypeError as exc:
        raise InputError(f"--{option}: {exc}", field=field, source="command line") from None


class _MapScores:
    """``pdr eval ms --map``: each trace on its own floor's plan from its first waypoint, scored absolutely."""

    TRACKS = ("pdr", "online", "smoothed")
    #: PDR turned and scaled about the start by the least-squares rotation and scale on the truth
    #: (:func:`pdr.evaluation.scoring.waypoint_errors` with ``scale``): the error a constant heading offset and
    #: step-length scale leave, known with hindsight (what remains needs corrections within the walk).
    HINDSIGHT = "hindsight"

    def __init__(self, config: MapMatchConfig) -> None:
        self.config = config
        self.plans: dict[Path, SitePlan] = {}
        self.errors: dict[str, list[tuple[str, np.ndarray]]] = {k: [] for k in (*self.TRACKS, self.HINDSIGHT)}
        self.floor_of: dict[str, str] = {}     # trace file name -> its floor folder
        self.wall_s = 0.0
        self.cpu_s = 0.0
        self.walk_s = 0.0
        self.steps = 0
        self.warm = False

    def _plan(self, trace: Path) -> tuple[SitePlan, int]:
        from pdr.site.ms import ms_floor_number, site_from_ms_floor
        from pdr.site.plan import SitePlan
        floor_dir = trace.parent.parent if trace.parent.name == "path_data_files" else trace.parent
        if floor_dir not in self.plans:
            self.plans[floor_dir] = SitePlan.from_dict(site_from_ms_floor(floor_dir), source=str(floor_dir))
        return self.plans[floor_dir], ms_floor_number(floor_dir.name)

    def score(self, trace: Path, rows: list[dict[str, Any]], truth_t: np.ndarray, truth_xy: np.ndarray
              ) -> dict[str, Any]:
        import time

        from pdr.mapmatch.rows import match_rows
        plan, floor = self._plan(trace)
        self.floor_of[trace.name] = _ms_floor(trace)
        after = [r for r in rows if r["t_s"] > truth_t[0]]
        start = (float(truth_xy[0, 0]), float(truth_xy[0, 1]))
        t = np.array([r["t_s"] for r in rows])
        xy = np.array([[r["east_m"], r["north_m"]] for r in rows])
        at0 = np.array([np.interp(truth_t[0], t, xy[:, 0]), np.interp(truth_t[0], t, xy[:, 1])])
        tracks = {"pdr": (t, xy - at0 + truth_xy[0])}
        if not self.warm:       # load the compiled kernels and build the wall grid outside the timing
            match_rows(after[:3], plan, start, floor, self.config)
            self.warm = True
        tic, cpu = time.perf_counter(), time.process_time()
        online, notices = match_rows(after, plan, start, floor, self.config, source=f"{trace.name} first waypoint")
        self.wall_s += time.perf_counter() - tic
        self.cpu_s += time.process_time() - cpu
        self.steps += len(after)
        self.walk_s += (after[-1]["t_s"] - float(truth_t[0])) if after else 0.0
        smoothed, _ = match_rows(after, plan, start, floor, self.config, smooth=True)
        for name, track in (("online", online), ("smoothed", smoothed)):
            tracks[name] = (np.array([r["t_s"] for r in track]),
                            np.array([[r["east_m"], r["north_m"]] for r in track]).reshape(-1, 2))
        out: dict[str, Any] = {"notices": notices}
        for name, (tt, txy) in tracks.items():
            e = (absolute_waypoint_errors(tt, txy, truth_t, truth_xy) if name == "pdr" or len(tt) else
                 np.linalg.norm(truth_xy[1:] - truth_xy[0], axis=1))     # no step after the start: still there
            self.errors[name].append((trace.name, e))
            out[name] = {"median_m": _pct(e, 50), "p75_m": _pct(e, 75)}
        e = waypoint_errors(t, xy, truth_t, truth_xy, scale=True)
        self.errors[self.HINDSIGHT].append((trace.name, e))
        out[self.HINDSIGHT] = {"median_m": _pct(e, 50), "p75_m": _pct(e, 75)}
        return out

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {"traces": len(self.errors["pdr"])}
        for name, per in self.errors.items():
            a = np.concatenate([e for _, e in per]) if per else np.zeros(0)
            p75 = [(_pct(e, 75), f) for f, e in per]
            worst = max(p75) if p75 else (math.nan, "")
            out[name] = {"median_m": _pct(a, 50), "p75_m": _pct(a, 75), "worst_p75_m": worst[0],
                         "worst_file": worst[1], "traces_over_5m": sum(1 for v, _ in p75 if v > 5.0),
                         "floors": {}}
            for floor in sorted(set(self.floor_of.values())):
                mine = [e for f, e in per if self.floor_of[f] == floor]
                b = np.concatenate(mine) if mine else np.zeros(0)
                out[name]["floors"][floor] = {"traces": len(mine), "median_m": _pct(b, 50), "p75_m": _pct(b, 75),
                                              "traces_over_5m": sum(1 for e in mine if _pct(e, 75) > 5.0)}
        out["speed"] = {"particles": self.config.particles, "steps": self.steps, "wall_s": self.wall_s,
                        "steps_per_s": self.steps / self.wall_s if self.wall_s else math.nan,
                        "times_real_time": self.walk_s / self.wall_s if self.wall_s else math.nan,
                        "cpu_s": self.cpu_s,
                        "times_real_time_cpu": self.walk_s / self.cpu_s if self.cpu_s else math.nan}
        return out


#: A walk folder named by its truth: ``<carriage>-<N>-steps-<walker>`` (the sensor_logger_walks dataset).
_STEPS_IN_NAME = re.compile(r"^(?P<carriage>[a-z]+)-(?P<n>\d+)-steps-")


def _step_config(text: str) -> StepConfig:
    """``--step JSON`` as a :class:`StepConfig` (unknown fields and bad JSON are refused naming them)."""
    return _json_config(text, StepConfig, "step")


def _unmatched_text(u: dict[str, int]) -> str:
    """``pdr eval steps``' summary of :func:`pdr.evaluation.scoring.unmatched_by_phase`: unmatched steps (+) and
    contacts (-) in the walk's first and last :data:`WALK_EDGE_S` s and between.
    """
    edge = f"{WALK_EDGE_S:g} s"
    return "unmatched steps/contacts " + ", ".join(
        f"{name} +{u['extra_' + p]}/-{u['missed_' + p]}"
        for name, p in ((f"first {edge}", "first"), ("middle", "mid"), (f"last {edge}", "last")))


#: The files ``pdr eval steps`` looks for. Each belongs to a folder-format log (its folder: an Oxford trial, a Sensor
#: Logger export, a Tyrex logger folder of ``attitude_smartphones``) or is a log itself (a MobiFall trial's acc file).
_STEP_LOG_FILES = ("accelerometer.csv", "accelerometer.csv.gz", "Accelerometer.csv", "Accelerometer.csv.gz",
                   "accelerometer.txt", "accelerometer.txt.gz", "*_acc_*.txt", "*_acc_*.txt.gz")


def _distinct_logs(logs: list[Path]) -> tuple[list[Path], dict[str, str]]:
    """``logs`` less every log whose content is byte-identical to an earlier one's, and {left out: kept} by name: a
    dataset that ships one recording under two names (``../shared/data/sensor_logger_walks``: ``inhand-30-steps-Zyf``
    and ``texting-30-steps-Zyf``) would count it twice.
    """
    kept: dict[str, Path] = {}
    out: list[Path] = []
    identical: dict[str, str] = {}
    for log in logs:
        key = _content_digest(log)
        if key in kept:
            identical[log.name] = kept[key].name
        else:
            kept[key] = log
            out.append(log)
    return out, identical


def _content_digest(log: Path) -> str:
    """SHA-256 of a log's content: a file's bytes, or a folder's files (relative names and bytes, in name order)."""
    h = hashlib.sha256()
    files = sorted(f for f in log.rglob("*") if f.is_file()) if log.is_dir() else [log]
    for f in files:
        h.update(f.relative_to(log).as_posix().encode() if log.is_dir() else b"")
        h.update(b"\0")
        with f.open("rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        h.update(b"\0")
    return h.hexdigest()


def _step_log(f: Path) -> Path:
    """The log ``pdr eval steps`` reads for one of :data:`_STEP_LOG_FILES`: the file when it is a log of its own (a
    MobiFall trial's acc file, :func:`pdr.io.mobifall.sniff`), else its folder.
    """
    return f if mobifall.sniff(f) else f.parent


def _mocap_step_row(rec: Recording, starts_s: np.ndarray, trajectory: tuple[np.ndarray, np.ndarray]
                    ) -> dict[str, Any]:
    """``pdr eval steps``' motion-capture figures of a walk: how many detected steps (the pipeline's start times,
    s since the sensors' epoch: ``t0_ns / 1e9`` past the recording's ``t_s`` axis, the capture's) pair one to one
    with the true steps of the capture (:mod:`pdr.evaluation.mocap_steps`).
    """
    matched, _ = matched_steps(starts_s - rec.origin_ns / 1e9, mocap_step_times(*trajectory))
    return {"true_from": "motion capture", "matched": matched}


def _no_truth_row(rec: Recording, name: str, n: int, plain: int) -> dict[str, Any]:
    """``pdr eval steps``' row of a walk with no step truth (MobiFall: activity labels only): the counts alone."""
    code = str(rec.meta.get("activity_code", ""))
    modes = rec.truth.modes
    return {"walk": name, "placement": rec.device.placement or "unknown", "activity": code,
            "mode": modes.label[0] if modes is not None and len(modes.label) == 1 else "unknown",
            "walking": code in MOBIFALL_WALKING, "true": None, "detected": n, "plain_detected": plain,
            "duration_s": rec.duration_s}


def _no_truth_summary(per: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per activity code, the walks with no step truth: how many, how long (s), steps detected, plain count."""
    out: dict[str, dict[str, Any]] = {}
    for p in per:
        if "error" in p or p.get("true", 0) is not None:
            continue
        a = out.setdefault(p["activity"], {"walking": p["walking"], "mode": p["mode"], "walks": 0, "duration_s": 0.0,
                                           "detected": 0, "plain_detected": 0})
        a["walks"] += 1
        a["duration_s"] += p["duration_s"]
        a["detected"] += p["detected"]
        a["plain_detected"] += p["plain_detected"]
    return out


def _no_truth_lines(summary: dict[str, dict[str, Any]]) -> Iterator[str]:
    """``pdr eval steps``' text for the walks with no step truth (MobiFall)."""
    for code, a in summary.items():
        what = ("" if a["walking"] else
                " (not walking: every step found is a false one)" if code in MOBIFALL_NOT_WALKING else "")
        minutes = a["duration_s"] / 60.0
        yield (f"{code} {a['mode']}{what}: {a['walks']} recordings, {minutes:.1f} min, detected {a['detected']} "
               f"steps ({a['detected'] / minutes:.0f}/min), plain peak detector {a['plain_detected']} "
               f"({a['plain_detected'] / minutes:.0f}/min)")
    yield ("MobiFall counts no steps (its SOURCE.md: one activity label per recording), so these recordings "
           "have no count error; steps per minute are a cadence check only")


def _mean_abs(v: Sequence[float]) -> float:
    return float(np.mean(np.abs(v))) if len(v) else math.nan


def eval_steps(args: argparse.Namespace) -> int:
    """Step-count error per walk, a plain peak detector's count beside each. The truth: counted steps (Oxford step
    counter: in the recording; Sensor Logger folders named ``<carriage>-<N>-steps-<walker>``: the name) or the steps
    of the phone's motion capture (``attitude_smartphones``: :mod:`pdr.evaluation.mocap_steps`, with the detected
    steps that pair with them). MobiFall trials count no steps: their counts are printed per activity, with no error.
    """
    step = _step_config(args.step)
    logs, identical = _distinct_logs(sorted({_step_log(p) for p in _files(args.dir, _STEP_LOG_FILES,
                                                                           log_of=_step_log)}))
    if args.limit:
        logs = logs[:args.limit]
    per: list[dict[str, Any]] = []
    by_place: dict[str, list[float]] = {}
    by_place_bf: dict[str, list[float]] = {}
    by_place_alt: dict[str, list[float]] = {}
    for d, rec in progress.each_recording(logs, "eval steps", per, key="walk"):
        true = rec.truth.step_count
        named = _STEPS_IN_NAME.match(d.name)
        if true is None and named:
            true = int(named["n"])
        trajectory = mocap_trajectory(rec) if true is None else None
        if trajectory is not None:
            true = mocap_step_count(*trajectory)
        counts_only = true is None and rec.format == "mobifall"
        if not counts_only and (true is None or true < 10):
            per.append({"walk": d.name, "error": f"no usable step truth ({true} steps)"})
            continue
        events = PdrPipeline(PipelineConfig(step=step)).run(rec)
        starts_s = np.array([e["t_start_s"] for e in events if e.get("type") == "step"], dtype=np.float64)
        n = int(starts_s.size)
        acc = rec.stream("acc")
        plain = plain_step_count(acc.t_ns / 1e9, np.asarray(acc.values)) if rec.has("acc") else 0
        if true is None:
            per.append(_no_truth_row(rec, d.name, n, plain))
            continue
        err = step_count_error_pct(n, int(true))
        place = rec.device.placement or (named["carriage"] if named else str(rec.meta.get("carriage", "unknown")))
        by_place.setdefault(place, []).append(err)
        row: dict[str, Any] = {"walk": d.name, "placement": place, "true": int(true), "detected": n, "error_pct": err,
                               "count_error": n - int(true), "plain_detected": plain,
                               "plain_count_error": plain - int(true)}
        if trajectory is not None:
            row.update(_mocap_step_row(rec, starts_s, trajectory))
        feet = [rec.truth.extra.get(k) for k in ("step_times_chan1_s", "step_times_chan2_s")]
        if all(f is not None for f in feet):
            # Secondary figure: the same truth with contact-switch bounces removed (pdr.evaluation.scoring).
            row["true_bounce_free"] = bounce_free_step_count(feet)  # type: ignore[arg-type]
            row["error_pct_bounce_free"] = step_count_error_pct(n, row["true_bounce_free"])
            by_place_bf.setdefault(place, []).append(row["error_pct_bounce_free"])
            # The main figure: bounce-free and with one switch's drop-outs filled (the feet alternate).
            contacts = alternating_contacts(*feet)  # type: ignore[arg-type]
            row["true_alternating"] = int(contacts.size)
            row["error_pct_alternating"] = step_count_error_pct(n, row["true_alternating"])
            by_place_alt.setdefault(place, []).append(row["error_pct_alternating"])
            # Where the errors are: steps and contacts that match nothing, at the walk's start, middle and end.
            row["unmatched"] = unmatched_by_phase(starts_s - rec.origin_ns / 1e9, contacts)
        per.append(row)
    targets = ("trouser_pocket_front", "trouser_pocket_back", "trouser_pocket", "hand", "bag", "armband")
    target = [e for p, v in by_place.items() if p in targets for e in v]
    target_bf = [e for p, v in by_place_bf.items() if p in targets for e in v]
    target_alt = [e for p, v in by_place_alt.items() if p in targets for e in v]
    every = [e for v in by_place.values() for e in v]
    unmatched: dict[str, int] = {}
    for p in per:
        if p.get("placement") in targets and "unmatched" in p:
            for k, v in p["unmatched"].items():
                unmatched[k] = unmatched.get(k, 0) + v
    summary: dict[str, Any] = {
               "walks": len(every), "mean_abs_error_pct": float(np.mean(np.abs(every))) if every else math.nan,
               "mean_abs_error_pct_pocket_hand_bag_armband": float(np.mean(np.abs(target))) if target else math.nan,
               "mean_abs_error_pct_pocket_hand_bag_armband_bounce_free":
                   float(np.mean(np.abs(target_bf))) if target_bf else math.nan,
               "mean_abs_error_pct_pocket_hand_bag_armband_alternating":
                   float(np.mean(np.abs(target_alt))) if target_alt else math.nan,
               "unmatched_pocket_hand_bag_armband": unmatched,
               "by_placement": {p: {"walks": len(v), "mean_abs_error_pct": float(np.mean(np.abs(v))),
                                    "mean_error_pct": float(np.mean(v)),
                                    "mean_abs_error_pct_bounce_free":
                                        float(np.mean(np.abs(by_place_bf[p]))) if by_place_bf.get(p) else math.nan,
                                    "mean_abs_error_pct_alternating":
                                        float(np.mean(np.abs(by_place_alt[p]))) if by_place_alt.get(p) else math.nan}
                                for p, v in sorted(by_place.items())}}
    # Motion-capture truth (attitude_smartphones): the steps that pair up, and the plain detector's error beside ours.
    mocap = [p for p in per if "matched" in p]
    for pl, m in summary["by_placement"].items():
        rows = [p for p in mocap if p["placement"] == pl]
        if rows:
            m.update(_mocap_summary(rows))
    if mocap:
        summary["motion_capture"] = _mocap_summary(mocap)
    no_truth = _no_truth_summary(per)
    if no_truth:
        summary["no_step_truth"] = no_truth
    if identical:
        summary["left_out_identical"] = identical

    def lines() -> Iterator[str]:
        for p in per:
            if "error" in p:
                yield f"{p['walk']}: {p['error']}"
            elif p["true"] is None:
                yield (f"{p['walk']}: {p['placement']}, {p['activity']} {p['mode']}, {p['duration_s']:.1f} s, "
                       f"no step truth, detected {p['detected']}; plain peak detector {p['plain_detected']}")
            else:
                bf = (f" (bounce-free truth {p['true_bounce_free']}: {p['error_pct_bounce_free']:+.1f} %; with "
                      f"drop-outs filled {p['true_alternating']}: {p['error_pct_alternating']:+.1f} %, "
                      + _unmatched_text(p["unmatched"]) + ")" if "true_bounce_free" in p else "")
                if "matched" in p:
                    bf = f", {p['matched']} matched within {MOCAP_MATCH_S:g} s of a true step"
                true = f"true {p['true']}" + (" (motion capture)" if "matched" in p else "")
                yield (f"{p['walk']}: {p['placement']}, {true}, detected {p['detected']} "
                       f"({p['count_error']:+d} steps, {p['error_pct']:+.1f} %){bf}; plain peak detector "
                       f"{p['plain_detected']} ({p['plain_count_error']:+d})")
        for pl, v in summary["by_placement"].items():
            bf, alt = v["mean_abs_error_pct_bounce_free"], v["mean_abs_error_pct_alternating"]
            yield (f"{pl}: {v['walks']} walks, mean |error| {v['mean_abs_error_pct']:.2f} %"
                   + (f" ({bf:.2f} % against bounce-free truth, {alt:.2f} % with drop-outs filled)"
                      if math.isfinite(bf) else "") + ("; motion capture" + _mocap_text(v) if "matched" in v else ""))
        if every:
            line = f"ALL: mean |error| {summary['mean_abs_error_pct']:.2f} % over {summary['walks']} walks"
        else:
            line = "ALL: no walk with a step truth"
        if target:
            line += f"; pocket/hand/bag/armband {summary['mean_abs_error_pct_pocket_hand_bag_armband']:.2f} %"
        if target_bf:
            line += (f" ({summary['mean_abs_error_pct_pocket_hand_bag_armband_bounce_free']:.2f} % against the "
                     "contact-switch truth without bounces, "
                     f"{summary['mean_abs_error_pct_pocket_hand_bag_armband_alternating']:.2f} % with one switch's "
                     "drop-outs filled as well)")
        if mocap:
            line += "; motion-capture truth" + _mocap_text(summary["motion_capture"])
        yield line
        if unmatched:
            yield "pocket/hand/bag/armband, against the filled truth: " + _unmatched_text(unmatched)
        if no_truth:
            yield from _no_truth_lines(no_truth)
        if identical:
            yield ("left out, byte-identical to another log (counted once): "
                   + ", ".join(f"{dup} (= {orig})" for dup, orig in identical.items()))
    _emit(summary, per, args.json, lines())
    return 0


def _mocap_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The motion-capture figures of ``pdr eval steps`` over ``rows``: walks, true and matched steps, and our and the
    plain peak detector's mean |count error| (%).
    """
    true = sum(p["true"] for p in rows)
    return {"mocap_walks": len(rows), "true": true, "detected": sum(p["detected"] for p in rows),
            "matched": sum(p["matched"] for p in rows),
            "mean_abs_error_pct": _mean_abs([p["error_pct"] for p in rows]),
            "plain_detected": sum(p["plain_detected"] for p in rows),
            "plain_mean_abs_error_pct": _mean_abs([step_count_error_pct(p["plain_detected"], p["true"])
                                                   for p in rows])}


def _mocap_text(m: dict[str, Any]) -> str:
    return (f": {m['matched']} of {m['true']} true steps matched ({100.0 * m['matched'] / m['true']:.1f} %), "
            f"{m['detected']} detected; plain peak detector {m['plain_detected']}, mean |error| "
            f"{m['plain_mean_abs_error_pct']:.2f} %")
