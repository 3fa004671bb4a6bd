"""``pdr track LOG``: the phone PDR track of a log as CSV, GeoJSON and PNG."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pdr.cli.one_shot import one_shot_process
from pdr.cli.outputs import check_writable, in_made_folder, plot_path, print_warnings
from pdr.errors import InputError
from pdr.io import read_recording
from pdr.phone.configure import pipeline_config
from pdr.phone.heading_smoother import smoothed_rows
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.phone.stage import StepStage
from pdr.phone.step_length import StepLengthModel
from pdr.phone.track_geojson import require_origin, track_geojson
from pdr.phone.track_schema import write_csv
from pdr.recording import Recording, geo_origin

if TYPE_CHECKING:
    # The map matcher (its compiled kernels, the site's plans) is imported where a command line asks for it.
    from pdr.site.plan import SitePlan


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("track", help="phone PDR: one row per step (position, floor, heading, length)")
    p.add_argument("log", help="log file or folder (any supported format)")
    common_options(p)
    p.add_argument("--out", required=True, help="track CSV (t_s,east_m,north_m,up_m,floor,heading_deg,"
                                               "step_length_m,mode) on the log's clock (its folder is made)")
    p.add_argument("--geojson", help="also write the track as GeoJSON (RFC 7946: lon/lat; only for a geo-referenced "
                                     "log: a GPS fix or a surveyed origin)")
    p.add_argument("--plot", help="also write a PNG plot of the track")
    p.add_argument("--start", metavar="E,N[,FLOOR]",
                   help="known start (m, the site's frame) and its floor (default: the site's only floor): with a "
                        "--site that has floor plans, the track is map-matched (particle filter, pdr.mapmatch; "
                        "unknown heading, the magnetometer's as a prior) and the CSV is in the site's frame")
    p.add_argument("--smoother", default="on", choices=("on", "off"),
                   help="OFFLINE: smooth the step headings over the whole walk (gyro yaw with its "
                        "bias learnt from the magnetometer, pdr.phone.heading_smoother); off: the causal track the "
                        "server streams")
    p.set_defaults(func=run_track)


def common_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--placement", default="auto", choices=("auto", "detect", "pocket", "torso", "hand", "swinging"),
                   help="where the phone is carried (swinging: in a hand swinging with the arm; auto: from the "
                        "log's metadata, else detected stride by stride from the carriage's motion; detect: "
                        "detected even where the log's format names one, e.g. GetSensorData logs, read as hand-held "
                        "as the IPIN competition's are)")
    p.add_argument("--site", help="site description JSON (landmarks that correct heading and position; optional "
                                  "declination_deg and grid_deg, the compass bearing of a main axis of the building)")
    p.add_argument("--calibration", help="step-length calibration JSON from `pdr calibrate`")
    p.add_argument("--method", default="ukf", choices=("ukf", "ekf"), help="attitude filter")
    p.add_argument("--floor-height", type=float, default=None, help="floor height in m (default 4)")
    p.add_argument("--use-phone-orientation", action="store_true",
                   help="use the phone's own fused attitude (rotation vector / AHRS in the log) as an extra, gated "
                        "measurement of yaw in our attitude filter")


def config_from_args(args: argparse.Namespace, initial_floor: float = 0.0) -> PipelineConfig:
    calibration = getattr(args, "calibration", None)
    return pipeline_config(args.placement, attitude_method=args.method, initial_floor=initial_floor,
                           step_length=StepLengthModel.load(calibration) if calibration else None,
                           floor_height_m=getattr(args, "floor_height", None) or None,
                           use_phone_orientation=bool(getattr(args, "use_phone_orientation", False)))


def run_pipeline(rec: Recording, cfg: PipelineConfig, site: Site | None = None,
                 stages: Sequence[StepStage] = ()) -> tuple[list[dict[str, Any]], list[str]]:
    """Track rows and notices of a whole recording (``stages``: plugged-in step stages, e.g. the map matcher); says
    first when the kernels will be compiled, and compiles them in two processes (:func:`compile_ahead`).
    """
    compile_ahead(cfg.attitude_method)
    return rows_notices(PdrPipeline(cfg, site, stages=stages).run(rec))


def rows_notices(events: list[dict[str, Any]]) -> tuple[list[dict[str, Any]], list[str]]:
    """The step rows and the notices' messages of a pipeline's events."""
    notices = [str(e["message"]) for e in events if e.get("type") == "notice"]
    return track_rows(events), notices


def reference_rows(rec: Recording, cfg: PipelineConfig, site: Site | None = None) -> list[dict[str, Any]] | None:
    """Track rows of the same pipeline with the phone's own attitude in place of ours (``attitude_source="phone"``):
    the reference of the evaluations; None when the log has no ``orientation`` stream.
    """
    from dataclasses import replace

    if not rec.has("orientation"):
        return None
    return run_pipeline(rec, replace(cfg, attitude_source="phone", use_phone_orientation=False), site)[0]


def write_geojson(rows: list[dict[str, Any]], path: str | Path, origin: tuple[float, float] | None) -> None:
    """The track as RFC 7946 GeoJSON (:mod:`pdr.phone.track_geojson`); :class:`InputError` when not geo-referenced."""
    Path(path).write_text(json.dumps(track_geojson(rows, origin, source=f"--geojson {path}")))


def write_plot(rows: list[dict[str, Any]], path: str | Path, rec: Recording, title: str) -> None:
    """The track's PNG (:mod:`pdr.cli.plots`): start and end marked, the truth when the log has it, with the track
    moved to start at the first truth point as ``pdr eval`` scores it.
    """
    from pdr.cli.plots import plot_track, truth_of

    t = np.array([r["t_s"] for r in rows], dtype=np.float64)
    en = np.array([[r["east_m"], r["north_m"]] for r in rows], dtype=np.float64).reshape(-1, 2)
    plot_track(path, t, en, title, truth_of(rec), label="PDR track")


#: Whether this process has said that it compiles and started compiling alongside (:func:`compile_ahead`): once.
_compiling_ahead = False


def compile_ahead(method: str) -> None:
    """On the first run of an installed version (the attitude filter's kernel, ``method`` ``ukf`` or ``ekf``, is not
    in numba's cache): say on stderr, before the work, that the kernels will be compiled (half a minute to a minute,
    silently otherwise), and compile the other kernels in a second process meanwhile
    (:func:`pdr.phone.warm_up.compile_alongside`), waited for when the command ends. Once per process, and nothing
    once they are cached.
    """
    global _compiling_ahead
    import atexit

    from pdr.phone.warm_up import compile_alongside, filter_kernel_cached, wait_alongside

    if _compiling_ahead or filter_kernel_cached(method):
        return
    _compiling_ahead = True
    print("note: first run of this version: compiling the processing code (about half a minute to a minute, "
          "once; it is kept for the next runs)", file=sys.stderr, flush=True)
    child = compile_alongside()
    if child is not None:
        atexit.register(wait_alongside, child)


def run_track(args: argparse.Namespace) -> int:
    with one_shot_process():    # pdr.cli.one_shot
        return _track(args)


def _track(args: argparse.Namespace) -> int:
    """``pdr track``: read, track, smooth, write (:func:`run_track`)."""
    args.plot = plot_path(args.plot)    # the file written: '.png' added to a name without an extension
    check_writable(args.out, args.geojson, args.plot)     # before the work, not after it
    rec = read_recording(args.log)
    print_warnings(rec.warnings)        # what the reader dropped (a cut-off last line, repeated samples, ...)
    if not rec.has("acc"):
        # No specific force with gravity: no attitude and no steps, so a track would be empty (never exit 0).
        why = "; ".join(w for w in rec.warnings if "acc" in w)
        raise InputError("no accelerometer stream with gravity ('acc'): cannot track" + (f" ({why})" if why else ""),
                         source=str(args.log))
    if args.geojson:  # refused before the work, not after it
        require_origin(geo_origin(rec), source=f"--geojson {args.geojson}")
    site = Site.load(args.site) if args.site else None
    floor0 = 0.0
    cfg = config_from_args(args, floor0)
    plan = _site_plan(args)
    if plan is not None:
        start, floor = parse_start(args.start, plan)
        plan.check_walkable(start, floor, "--start")
    if plan is not None and args.smoother == "off":
        # Online: the map matcher is a stage of the pipeline, as in a live session.
        from pdr.mapmatch.stage import MapMatchStage
        rows, notices = run_pipeline(rec, cfg, site, [MapMatchStage(plan, start, floor, source="--start")])
    else:
        rows, notices = run_pipeline(rec, cfg, site)
    if args.smoother == "on":
        rows = smoothed_rows(rows, notices)
        if plan is not None:
            # Offline: the smoothed track matched with the matcher's own smoother over the whole walk.
            from pdr.mapmatch.particles import MapMatchConfig
            from pdr.mapmatch.rows import match_rows
            rows, more = match_rows(rows, plan, start, floor, MapMatchConfig(), smooth=True, source="--start")
            notices = [*notices, *more]
    if args.placement in ("auto", "detect") and rows:
        notices = [*notices, placement_note(rows, None if args.placement == "detect" else rec.device.placement)]
    for n in notices:
        print(f"note: {n}", file=sys.stderr)
    write_csv(rows, in_made_folder(args.out))     # the folders of the outputs are made (pdr.cli.outputs)
    if args.geojson:
        write_geojson(rows, in_made_folder(args.geojson), geo_origin(rec))
    dist = sum(r["step_length_m"] for r in rows)
    if args.plot:
        write_plot(rows, in_made_folder(args.plot), rec,
                   f"pdr track {Path(args.log).name}: {len(rows)} steps, {dist:.1f} m, "
                   f"heading {'smoothed' if args.smoother == 'on' else 'causal'}")
    print(f"{len(rows)} steps, {dist:.1f} m walked -> {args.out}")
    return 0


#: Most placement spans :func:`placement_note` lists.
PLACEMENT_SPANS_LISTED = 6


def placement_note(rows: list[dict[str, Any]], log_placement: str | None) -> str:
    """Where the track took the phone to be, for a user who did not say (``--placement auto`` or ``detect``): the
    log's own placement (``log_placement``, the device's; None: not given or not used) or the carriage detected
    stride by stride, as spans of the step rows' ``placement`` (times in s on the log's clock).
    """
    if log_placement is not None:
        return (f"placement {rows[0].get('placement')} from the log (its device: {log_placement}); "
                "--placement detect detects it from the motion instead")
    spans: list[list[Any]] = []
    for r in rows:
        if spans and spans[-1][0] == r.get("placement"):
            spans[-1][2], spans[-1][3] = r["t_s"], spans[-1][3] + 1
        else:
            spans.append([r.get("placement"), r.get("t_start_s", r["t_s"]), r["t_s"], 1])
    listed = ", ".join(f"{p} {t0:.1f}-{t1:.1f} s ({n} step{'s' if n > 1 else ''})"
                       for p, t0, t1, n in spans[:PLACEMENT_SPANS_LISTED])
    more = len(spans) - PLACEMENT_SPANS_LISTED
    return ("placement detected stride by stride (--placement to set it): " + listed
            + (f", and {more} more changes" if more > 0 else ""))


def _site_plan(args: argparse.Namespace) -> SitePlan | None:
    """The site's floor plans when ``--start`` asks for map matching (refused without a site that has them)."""
    if args.start is None:
        return None
    if not args.site:
        raise InputError("--start needs --site SITE.json with floor plans", source="command line", field="start")
    from pdr.site.plan import SitePlan
    return SitePlan.load(args.site)


def parse_start(text: str, plan: SitePlan) -> tuple[tuple[float, float], int]:
    """``E,N[,FLOOR]`` (m, site frame): the start and its floor (default: the site's only floor)."""
    parts = text.split(",")
    try:
        vals = [float(v) for v in parts]
    except ValueError:
        vals = []
    if len(vals) not in (2, 3) or not all(math.isfinite(v) for v in vals):
        raise InputError(f"--start must be E,N or E,N,FLOOR in metres, not {text!r}", source="command line",
                         field="start")
    if len(vals) == 3:
        if not vals[2].is_integer():
            raise InputError(f"--start floor must be an integer, not {vals[2]}", source="command line",
                             field="start")
    floor = plan.start_floor(int(vals[2]) if len(vals) == 3 else None, "--start")
    return (vals[0], vals[1]), floor
