"""``pdr foot LOG --out TRACK.csv`` (foot-mounted navigation; ``--format foot-steps`` writes the step-summary
payload) and ``pdr eval foot`` (the three foot datasets).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pdr.cli import progress
from pdr.cli.outputs import check_writable, in_made_folder, plot_path, print_warnings
from pdr.errors import InputError
from pdr.evaluation.foot_metrics import (
    PYSHOE_EXCLUDED,
    loop_closure_error,
    path_length,
    pyshoe_armse,
    stride_errors,
    stride_summary,
)
from pdr.foot.bc import BCTrack
from pdr.foot.detectors import DETECTORS, DetectorConfig
from pdr.foot.dual import DualFootConfig, DualFootTrack, navigate_feet
from pdr.foot.filterbank import FilterBankTrack
from pdr.foot.navigate import METHODS, FootImu, navigate, unsupported_options
from pdr.foot.zupt import ZuptConfig, ZuptTrack
from pdr.frames import yaw_to_heading_deg
from pdr.fusion.constraints import SeparationConfig
from pdr.io.pyshoe import VICON_TO_RIGHT_HANDED


def _detector_config(args: argparse.Namespace) -> DetectorConfig:
    kw: dict[str, Any] = {"method": args.detector, "adaptive": not args.fixed_threshold}
    if args.threshold is not None:
        kw["threshold"] = args.threshold
    if args.run_gain is not None:
        kw["run_gain"] = args.run_gain
    return DetectorConfig(**kw)


def _zupt_config(args: argparse.Namespace) -> ZuptConfig:
    """The ZUPT-INS settings of ``--zaru`` and ``--imu-samples``."""
    return ZuptConfig(zaru=args.zaru == "on", interval_samples=args.imu_samples == "interval")


#: The command-line flag of each setting of :data:`pdr.foot.navigate.METHOD_OPTIONS`.
OPTION_FLAGS = {"zaru": "--zaru on", "interval_samples": "--imu-samples interval", "gyro_bias": "--gyro-bias on",
                "smooth": "--smoother on"}


def _refuse_unsupported(method: str, args: argparse.Namespace) -> None:
    """InputError naming the flags that ``method`` does not have (instead of ignoring them)."""
    bad = unsupported_options(method, _zupt_config(args), gyro_bias=args.gyro_bias == "on")
    if bad:
        flags = ", ".join(OPTION_FLAGS[b] for b in bad)
        them = "them" if len(bad) > 1 else "it"
        raise InputError(f"--method {method} does not have {flags}; leave {them} out or choose a method that has "
                         f"{them} (pdr foot --help)", field=OPTION_FLAGS[bad[0]].split()[0])


def _method_zupt_config(method: str, args: argparse.Namespace) -> tuple[ZuptConfig, list[str]]:
    """For the evaluation of several methods: ``--zaru``/``--imu-samples`` where ``method`` has them, and the
    flags it runs without (``--gyro-bias on`` too, which :func:`~pdr.foot.navigate.navigate` applies to zupt only).
    """
    zupt = _zupt_config(args)
    bad = unsupported_options(method, zupt, gyro_bias=args.gyro_bias == "on")
    settings = {b: False for b in bad if b in ("zaru", "interval_samples")}
    return replace(zupt, **settings), [OPTION_FLAGS[b] for b in bad]


def _add_options(p: argparse.ArgumentParser, evaluation: bool = False) -> None:
    p.add_argument("--method", choices=METHODS + (("all",) if evaluation else ()),
                   default="all" if evaluation else "zupt",
                   help="zupt: ZUPT-aided INS; stepwise: with step segmentation and step-wise dead reckoning; "
                        "filterbank, filterbank-height: jump Markov filter bank (seed 002 eqs. 12, 13); "
                        "bc: belief condensation (seed 000)"
                        + ("; all: every method of EVAL_METHODS (default)" if evaluation else ""))
    p.add_argument("--detector", choices=DETECTORS, default="shoe", help="zero-velocity detector (default shoe)")
    p.add_argument("--threshold", type=float, help="detector threshold gamma_z (default 3e4)")
    p.add_argument("--fixed-threshold", action="store_true", help="disable the gait-adaptive threshold")
    p.add_argument("--run-gain", type=float, help="factor of the gait-adaptive threshold (default "
                                                  f"{DetectorConfig().run_gain:g})")
    p.add_argument("--gyro-bias", choices=("on", "off"), default="off",
                   help="OFFLINE ONLY, method zupt only: remove the gyroscope bias measured over the still samples of "
                        "the whole recording (default off: PyShoe gains on median but 5 of 18 trials lose, "
                        "foot_stride_gcp walks without a long rest lose, xio_gait_loop loses; see "
                        "pdr.foot.detectors.stationary_gyro_bias; --zaru is the causal form)")
    p.add_argument("--zaru", choices=("on", "off"), default="off",
                   help="methods zupt and stepwise: zero angular-rate updates of a gyroscope-bias filter while the "
                        "foot is still (pdr.foot.zupt, ZuptConfig.zaru; causal, as online processing does it; "
                        "default off)")
    p.add_argument("--imu-samples", choices=("instant", "interval"), default="instant",
                   help="methods zupt, stepwise and filterbank: each IMU sample is the value at its instant (default: "
                        "second-order mechanization between samples) or the mean over the interval that ends at it "
                        "(ZuptConfig.interval_samples, for IMUs that average or integrate between outputs)")
    smoother = ("on", "off", "both") if evaluation else ("on", "off")
    p.add_argument("--smoother", choices=smoother, default="on",
                   help="OFFLINE ONLY, method zupt only: Rauch-Tung-Striebel fixed-interval smoother over the whole "
                        "recording (pdr.filters.rts) on top of the causal ZUPT-EKF (default on; off gives the "
                        "causal filter's track, what online processing produces)"
                        + ("; both: smoothed rows named by the method and filtered rows named METHOD"
                           + NO_SMOOTHER if evaluation else ""))


def track_rows(imu: FootImu, track: ZuptTrack | FilterBankTrack | BCTrack) -> dict[str, np.ndarray]:
    """Columns of the per-sample track CSV, time on the log's own clock."""
    return {
        "t_s": track.t_s + imu.clock_offset_s,
        "east_m": track.pos_n[:, 0], "north_m": track.pos_n[:, 1], "up_m": track.pos_n[:, 2],
        "heading_deg": yaw_to_heading_deg(track.yaw),
        "zero_velocity": track.zero_velocity.astype(np.int64),
        "pos_sd_m": np.sqrt(np.maximum(track.pos_var[:, 0] + track.pos_var[:, 1], 0.0)),
    }


def step_rows(imu: FootImu, track: ZuptTrack) -> dict[str, np.ndarray]:
    """Columns of the per-step CSV (one row per reset of the step-wise navigation). ``stride`` 1: the reset closes a
    stride; 0: a reset while the foot stands (one every ``c_max_s``), kept for its increment (a turn on the spot) but
    no stride, as the session's track marks it ``standing`` and leaves it out of its step count.
    """
    idx = np.array([s.index for s in track.steps], dtype=np.int64)
    return {
        "t_s": track.t_s[idx] + imu.clock_offset_s,
        "east_m": track.pos_n[idx, 0], "north_m": track.pos_n[idx, 1], "up_m": track.pos_n[idx, 2],
        "heading_deg": yaw_to_heading_deg(track.yaw[idx]),
        "dp_x_m": np.array([s.dp[0] for s in track.steps]), "dp_y_m": np.array([s.dp[1] for s in track.steps]),
        "dp_z_m": np.array([s.dp[2] for s in track.steps]),
        "dpsi_deg": np.degrees([s.dpsi for s in track.steps]),
        "stride": np.array(track.step_strides, dtype=np.int64),
    }


def write_foot_steps(path: str | Path, imu: FootImu, track: ZuptTrack, role: str, batch_id: str) -> None:
    """The steps as a ``pdr-foot-steps/1`` payload (:mod:`pdr.foot.summaries`): what a shoe unit's low-rate
    interface sends (seed 001), each step's increment with its covariance (eq. 8) and whether it closes a stride,
    times on the log's clock as in the per-step CSV; ``POST /api/v1/sessions/{id}/steps`` takes it.
    """
    from pdr.foot.summaries import steps_to_json

    steps = [replace(s, t_s=float(s.t_s) + imu.clock_offset_s) for s in track.steps]
    Path(path).write_text(json.dumps(steps_to_json(steps, role, batch_id)) + "\n")


def write_csv(path: str | Path, columns: dict[str, np.ndarray]) -> None:
    """Write equal-length columns as CSV (integers as integers, floats with 9 significant digits)."""
    names = list(columns)
    arrays = [np.asarray(columns[n]) for n in names]
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(names) + "\n")
        for row in zip(*arrays, strict=True):
            fh.write(",".join(str(int(v)) if isinstance(v, np.integer) else f"{float(v):.9g}" for v in row) + "\n")


def _method_name(method: str, args: argparse.Namespace) -> str:
    """The method as run: ``zupt`` says whether the RTS smoother was on."""
    if method == "zupt":
        return "zupt (RTS-smoothed)" if args.smoother == "on" else "zupt (causal)"
    return method


def _summary(t_s: np.ndarray, pos_n: np.ndarray, zero_velocity: np.ndarray, method: str, out: str) -> str:
    """``N strides, D m walked in T s (method M) -> OUT``, as ``pdr track`` prints its steps and distance."""
    strides, dist, duration = stride_summary(t_s, pos_n, zero_velocity)
    return f"{strides} strides, {dist:.1f} m walked in {duration:.1f} s, method {method} -> {out}"


def dual_rows(left: FootImu, track: DualFootTrack) -> dict[str, np.ndarray]:
    """Columns of the dual-foot CSV: on the left foot's samples, the midpoint of the two feet and each foot."""
    lf, rf = track.left, track.right
    right_pos = np.stack([np.interp(lf.t_s, rf.t_s, rf.pos_n[:, i]) for i in range(3)], axis=1)
    right_yaw = np.interp(lf.t_s, rf.t_s, np.unwrap(rf.yaw))
    mid = 0.5 * (lf.pos_n + right_pos)
    yaw = np.arctan2(np.sin(lf.yaw) + np.sin(right_yaw), np.cos(lf.yaw) + np.cos(right_yaw))
    return {
        "t_s": lf.t_s, "east_m": mid[:, 0], "north_m": mid[:, 1], "up_m": mid[:, 2],
        "heading_deg": yaw_to_heading_deg(yaw), "zero_velocity": lf.zero_velocity.astype(np.int64),
        "left_east_m": lf.pos_n[:, 0], "left_north_m": lf.pos_n[:, 1], "left_up_m": lf.pos_n[:, 2],
        "right_east_m": right_pos[:, 0], "right_north_m": right_pos[:, 1], "right_up_m": right_pos[:, 2],
    }


def dual_step_rows(track: DualFootTrack) -> dict[str, np.ndarray]:
    """Columns of the per-step dual-foot CSV: one row per reset of either foot, in time order; ``stride`` as in
    the one-foot CSV (:func:`step_rows`: 0 for a reset while the foot stands).
    """
    t = np.concatenate([track.left.step_t_s, track.right.step_t_s])
    pos = np.concatenate([track.left.step_pos_n, track.right.step_pos_n])
    foot = np.concatenate([np.zeros(track.left.step_t_s.size, np.int64), np.ones(track.right.step_t_s.size,
                                                                                 np.int64)])
    stride = np.concatenate([track.left.step_strides, track.right.step_strides]).astype(np.int64)
    order = np.argsort(t, kind="stable")
    return {"t_s": t[order], "east_m": pos[order, 0], "north_m": pos[order, 1], "up_m": pos[order, 2],
            "right_foot": foot[order], "stride": stride[order]}


def run_dual(args: argparse.Namespace) -> int:
    from pdr.io import read_recording

    if not (args.left and args.right):
        raise InputError("dual-foot fusion needs both --left and --right logs", field="--right" if args.left
                         else "--left")
    if args.log:
        raise InputError("give either one LOG or --left and --right, not both", field="log")
    if args.method not in ("zupt", "stepwise"):
        raise InputError(f"dual-foot fusion uses the step-wise navigation; --method {args.method} is not "
                         "available with --left/--right", field="--method")
    _refuse_unsupported("stepwise", args)
    check_writable(args.out, args.plot)         # before the work, not after it
    cfg = DualFootConfig(separation=SeparationConfig(gamma_xy=args.gamma_xy, gamma_z=args.gamma_z))
    imu_l, imu_r, track = navigate_feet(read_recording(args.left), read_recording(args.right),
                                        _detector_config(args), zupt=_zupt_config(args), config=cfg)
    for side, imu in (("left", imu_l), ("right", imu_r)):
        print_warnings(imu.warnings, side)
    write_csv(in_made_folder(args.out), dual_step_rows(track) if args.per_step else dual_rows(imu_l, track))
    print(f"{track.updates} steps fused, separation constraint active at {track.constraint_active}; right foot "
          f"frame turned by {math.degrees(track.heading_offset_rad):.1f} deg", file=sys.stderr)
    mid = dual_rows(imu_l, track)
    mid_en = np.column_stack([mid["east_m"], mid["north_m"]])
    line = _summary(mid["t_s"], mid_en, mid["zero_velocity"].astype(bool), "stepwise, dual-foot", args.out)
    if args.plot:
        from pdr.cli.plots import plot_track, truth_of

        title = f"pdr foot {Path(args.left).name} + {Path(args.right).name}: " + line.split(" ->")[0]
        plot_track(in_made_folder(args.plot), mid["t_s"], mid_en, title, truth_of(read_recording(args.left)),
                   label="midpoint of the feet",
                   extra={"left foot": track.left.pos_n[:, :2], "right foot": track.right.pos_n[:, :2]}, turn=True)
    print(line)
    return 0


def run_foot(args: argparse.Namespace) -> int:
    from pdr.io import read_recording

    args.plot = plot_path(args.plot)    # the file written: '.png' added to a name without an extension
    if args.left or args.right:
        return run_dual(args)
    if not args.log:
        raise InputError("give a foot IMU LOG (or --left and --right for dual-foot fusion)", field="log")
    _refuse_unsupported(args.method, args)
    check_writable(args.out, args.plot)         # before the work, not after it
    rec = read_recording(args.log)
    imu, track = navigate(rec, args.method, _detector_config(args), zupt=_zupt_config(args),
                          smooth=args.smoother == "on", gyro_bias=args.gyro_bias == "on")
    print_warnings(track.warnings)
    if args.format == "foot-steps":
        if not (args.per_step and args.method == "stepwise"):
            raise InputError("--format foot-steps needs --per-step and --method stepwise", field="--format")
        write_foot_steps(in_made_folder(args.out), imu, track, args.role or rec.device.role, Path(args.log).name)
    elif args.per_step:
        if args.method != "stepwise":
            raise InputError("--per-step needs --method stepwise", field="--per-step")
        write_csv(in_made_folder(args.out), step_rows(imu, track))
    else:
        write_csv(in_made_folder(args.out), track_rows(imu, track))
    t = track.t_s + imu.clock_offset_s
    line = _summary(t, track.pos_n, track.zero_velocity, _method_name(args.method, args), args.out)
    if args.plot:
        from pdr.cli.plots import plot_track, truth_of

        title = f"pdr foot {Path(args.log).name}: " + line.split(" ->")[0]
        plot_track(in_made_folder(args.plot), t, track.pos_n[:, :2], title, truth_of(rec), label="foot track",
                   turn=True)
    print(line)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("foot", help="foot-mounted navigation (ZUPT-aided INS) of a foot IMU log")
    p.add_argument("log", nargs="?", help="foot IMU log (any supported format)")
    p.add_argument("--out", required=True, help="track CSV: t_s,east_m,north_m,up_m,heading_deg,zero_velocity")
    p.add_argument("--per-step", action="store_true",
                   help="one row per step (with --method stepwise or dual-foot); one foot: column stride is 0 for a "
                        "reset while the foot stands, which is no stride")
    p.add_argument("--format", choices=("csv", "foot-steps"), default="csv",
                   help="csv (default), or foot-steps: with --per-step --method stepwise, the pdr-foot-steps/1 JSON "
                        "payload of step summaries a shoe unit sends (POST /api/v1/sessions/{id}/steps)")
    p.add_argument("--role", choices=("left_foot", "right_foot"),
                   help="foot named in a foot-steps payload (default: the log's; the session's pairing must match)")
    p.add_argument("--plot", help="PNG of the horizontal track")
    p.add_argument("--left", help="left-foot log for dual-foot fusion (seed 001 Sec. 4.2), with --right")
    p.add_argument("--right", help="right-foot log for dual-foot fusion, with --left")
    p.add_argument("--gamma-xy", type=float, default=1.0, help="dual-foot: largest horizontal separation, m")
    p.add_argument("--gamma-z", type=float, default=0.3, help="dual-foot: largest vertical separation, m")
    _add_options(p)
    p.set_defaults(func=run_foot)


# ----------------------------------------------------------------------------------------------- evaluation

def _dataset_dirs(root: Path) -> dict[str, Path]:
    names = ("pyshoe_vicon", "xio_gait_loop", "foot_stride_gcp")
    if root.name in names:
        return {root.name: root}
    found = {n: root / n for n in names if (root / n).is_dir()}
    if not found:
        raise InputError(f"none of {names} found", source=str(root))
    return found


#: Suffix of the evaluated method names run without the heuristic drift elimination (:mod:`pdr.foot.drift`).
NO_HDE = "/no-hde"
#: Suffix of the evaluated ``zupt`` runs without the RTS smoother (the causal filter) when ``--smoother both``.
NO_SMOOTHER = "/filtered"
#: Methods that have an offline smoother.
SMOOTHED_METHODS: tuple[str, ...] = ("zupt",)
#: Suffix of the plain ZUPT-EKF baseline row: the causal filter with one fixed SHOE threshold (no gait adaptation,
#: no smoother), the detector that seeds 002 and 000 compare their navigators against.
PLAIN = "/plain"
#: Fixed SHOE threshold of the plain baseline: the best single threshold for these PyShoe trials. Each threshold of
#: 1e4, 3e4, 1e5, 2e5, 3e5, 5e5, 1e6, 3e6, 1e7 run as ``pdr eval foot DIR/pyshoe_vicon --method zupt
#: --fixed-threshold --threshold T --smoother off --hde on`` gives a median ARMSE of 0.185, 0.114, 0.105, 0.112,
#: 0.084, 0.088, 0.138, 0.507, 0.727 m. Choosing it on the evaluated trials favours the baseline.
PLAIN_THRESHOLD = 3.0e5


def eval_variants(methods: tuple[str, ...], hde: str, smoother: str = "off", plain: bool = False) -> tuple[str, ...]:
    """Names of the evaluated runs: each method with (its own name) and/or without (``+ NO_HDE``) drift
    elimination; with ``smoother == 'both'`` a smoothable method also without its smoother (``+ NO_SMOOTHER``);
    with ``plain`` the ZUPT-INS also as the plain baseline (``zupt + PLAIN``, :data:`PLAIN_THRESHOLD`).
    """
    out: list[str] = []
    for method in methods:
        forms = [method, method + NO_SMOOTHER] if smoother == "both" and method in SMOOTHED_METHODS else [method]
        forms += [method + PLAIN] if plain and method == "zupt" else []
        for form in forms:
            out += [form] if hde != "off" else []
            out += [form + NO_HDE] if hde != "on" else []
    return tuple(out)


def _navigate_variant(rec: Any, variant: str, args: argparse.Namespace,
                      zero_velocity: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[FootImu, Any]:
    """Navigate ``rec`` by an evaluated run name of :func:`eval_variants` (``zero_velocity``: labels
    ``(t_s, flags)`` in place of the detector's, see :func:`~pdr.foot.navigate.navigate`).
    """
    name = variant.removesuffix(NO_HDE)
    method = name.removesuffix(NO_SMOOTHER).removesuffix(PLAIN)
    plain = name.endswith(PLAIN)
    smooth = args.smoother != "off" and not name.endswith(NO_SMOOTHER) and not plain
    detector = _detector_config(args)
    if plain:
        detector = replace(detector, adaptive=False, threshold=args.plain_threshold)
    zupt, _ = _method_zupt_config(method, args)
    if variant.endswith(NO_HDE):
        zupt = replace(zupt, hde_directions=0)
    return navigate(rec, method, detector, zupt=zupt, smooth=smooth, gyro_bias=args.gyro_bias == "on",
                    zero_velocity=zero_velocity)


#: ``pdr eval foot --zv-labels``: the detector's flags, or the PyShoe files' reference labels ``zv_<name>_opt``
#: (each detector with the threshold grid-searched per trial against the VICON truth; ``vicon``: from the truth).
#: The search ran PyShoe's first-order INS, so the labels favour ``--imu-samples interval`` (pdr.foot.zupt doc).
ZV_LABELS: tuple[str, ...] = ("detector", "shoe", "ared", "amvd", "mbgtd", "vicon")


def _reference_labels(rec: Any, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """``(t_s, flags)`` of a PyShoe recording's reference zero-velocity labels ``name`` (None for ``detector``)."""
    if name == "detector":
        return None
    ex = rec.truth.extra
    key = f"zero_velocity_{name}"
    if key not in ex or "zero_velocity_t_s" not in ex:
        raise InputError(f"the recording has no '{name}' zero-velocity labels", source=rec.source or None,
                         field="zv_labels")
    return np.asarray(ex["zero_velocity_t_s"]), np.asarray(ex[key])


def eval_pyshoe(d: Path, args: argparse.Namespace, tracks: Path | None, method: str) -> dict[str, Any]:
    """PyShoe ARMSE per trial (crawling trials excluded), against the VICON truth.

    Two figures per trial: ``armse_m`` against the recording's truth (the VICON positions in a right-handed
    z-up frame, see :mod:`pdr.io.pyshoe`), and ``armse_stored_frame_m`` against the positions as stored in the
    file, which is what ``tools/score_tracks.py pyshoe`` computes from the track CSVs: the stored frame is
    left-handed, so a correct ENU track matches it only as a mirror image and that figure is large.
    """
    from pdr.io import read_recording

    rows: list[dict[str, Any]] = []
    files = sorted(d.glob("*.mat"))
    if args.limit:
        files = files[: args.limit]
    for f in progress.each(files, "eval foot pyshoe"):
        if f.stem in PYSHOE_EXCLUDED:
            continue
        rec = read_recording(f)
        t0 = time.perf_counter()
        imu, track = _navigate_variant(rec, method, args, _reference_labels(rec, args.zv_labels))
        cpu = time.perf_counter() - t0
        truth = rec.truth.positions
        if truth is None:
            continue
        est = np.stack([np.interp(truth.t_s, track.t_s, track.pos_n[:, i]) for i in range(2)], axis=1)
        stored = truth.pos_m[:, :2] * VICON_TO_RIGHT_HANDED[:2]
        row: dict[str, Any] = {"file": f.name, "armse_m": pyshoe_armse(est, truth.pos_m[:, :2]),
               "armse_stored_frame_m": pyshoe_armse(est, stored),
               "reference_best_m": float(rec.meta.get("best_error_m", math.nan)),
               "reference_shoe_m": float(rec.meta.get("trial_error_m", {}).get("shoe", math.nan)),
               "realtime_factor": float((track.t_s[-1] - track.t_s[0]) / cpu)}
        rows.append(row)
        if tracks is not None:
            write_csv(tracks / f"{f.name}.csv", track_rows(imu, track))
    med = {k: float(np.median([r[k] for r in rows])) if rows else math.nan
           for k in ("armse_m", "armse_stored_frame_m", "reference_best_m", "reference_shoe_m", "realtime_factor")}
    return {"trials": len(rows), "median": med, "per_trial": rows}


def eval_xio(d: Path, args: argparse.Namespace, tracks: Path | None, method: str) -> dict[str, Any]:
    """Loop-closure error of the closed walks (start = end)."""
    from pdr.io import read_recording

    rows: list[dict[str, Any]] = []
    for f in sorted(d.glob("*.csv")):
        rec = read_recording(f)
        imu, track = _navigate_variant(rec, method, args)
        err, pct = loop_closure_error(track.pos_n)
        rows.append({"file": f.name, "loop_error_m": err, "loop_error_pct": pct,
                     "distance_m": path_length(track.pos_n)})
        if tracks is not None:
            write_csv(tracks / f"{f.name}.csv", track_rows(imu, track))
    return {"walks": len(rows), "per_walk": rows}


def eval_gcp(d: Path, args: argparse.Namespace, tracks: Path | None, method: str) -> dict[str, Any]:
    """Per-stride errors at the footprint ground-control points and the final error in % of distance."""
    rows: list[dict[str, Any]] = []
    files = sorted((d / "own").glob("*.csv")) if (d / "own").is_dir() else sorted(d.glob("*.csv"))
    if args.limit:
        files = files[: args.limit]
    for f, rec in progress.each_recording(files, "eval foot", rows):
        truth = rec.truth.positions
        if truth is None or truth.kind != "stride" or len(truth) < 2:
            continue
        imu, track = _navigate_variant(rec, method, args)
        est = np.stack([np.interp(truth.t_s, track.t_s, track.pos_n[:, i]) for i in range(2)], axis=1)
        e = stride_errors(est, truth.pos_m[:, :2])
        dist = path_length(truth.pos_m)
        rows.append({"file": f.name, "strides": int(len(e)), "mean_stride_error_m": float(np.mean(e)),
                     "final_error_m": float(e[-1]), "distance_m": dist,
                     "final_error_pct": float(100.0 * e[-1] / dist) if dist > 0 else math.nan})
        if tracks is not None:
            write_csv(tracks / f"{f.name}.csv", track_rows(imu, track))
    ok = [r for r in rows if "final_error_pct" in r]
    return {"walks": len(ok), "median_final_error_pct": float(np.median([r["final_error_pct"] for r in ok]))
            if ok else math.nan, "per_walk": rows}


def paired_against_zupt(results: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Each navigator against each ZUPT-INS row of the same drift-elimination setting, trial by trial (PyShoe).

    ``results`` maps a run name of :func:`eval_variants` to its :func:`eval_pyshoe` result. For every run that is
    not a ZUPT row and every ZUPT row (``zupt`` smoothed, ``zupt/filtered`` causal, ``zupt/plain`` the plain
    fixed-threshold baseline) with the same ``/no-hde`` suffix: on how many trials the run's ARMSE is lower, the
    median of the per-trial differences (run minus ZUPT, m) and the two-sided Wilcoxon signed-rank p-value of those
    differences (``nan`` with fewer than six trials or no nonzero difference). Keys ``"RUN vs ZUPT_ROW"``.
    """
    from scipy.stats import wilcoxon

    out: dict[str, dict[str, Any]] = {}
    for run, r in results.items():
        if run.startswith("zupt"):
            continue
        for base, b in results.items():
            if not base.startswith("zupt") or base.endswith(NO_HDE) != run.endswith(NO_HDE):
                continue
            a_err = {row["file"]: row["armse_m"] for row in r["per_trial"]}
            b_err = {row["file"]: row["armse_m"] for row in b["per_trial"]}
            files = sorted(set(a_err) & set(b_err))
            d = np.array([a_err[f] - b_err[f] for f in files])
            p = float(wilcoxon(d).pvalue) if d.size >= 6 and np.any(d != 0) else math.nan
            out[f"{run} vs {base}"] = {"trials": int(d.size), "better": int(np.sum(d < 0)),
                                      "median_difference_m": float(np.median(d)) if d.size else math.nan,
                                      "wilcoxon_p": p}
    return out


def _print_eval(out: dict[str, Any]) -> None:
    if out.get("zv_labels", "detector") != "detector":
        print(f"pyshoe trials navigated with the files' reference zero-velocity labels zv_{out['zv_labels']}_opt "
              "(an oracle), not the detector's")
    for method, flags in out.get("not_applied", {}).items():
        print(f"{method} runs without {', '.join(flags)} (it has no such setting)")
    for method in out["methods"]:
        if "pyshoe_vicon" in out:
            r = out["pyshoe_vicon"][method]
            for row in r["per_trial"]:
                print(f"[{method}] pyshoe {row['file']}: ARMSE {row['armse_m']:.3f} m (stored left-handed frame "
                      f"{row['armse_stored_frame_m']:.3f} m), reference {row['reference_best_m']:.3f} m")
            m = r["median"]
            print(f"[{method}] pyshoe ALL ({r['trials']} trials, crawling excluded): median ARMSE "
                  f"{m['armse_m']:.4f} m (stored left-handed frame, as score_tracks.py: "
                  f"{m['armse_stored_frame_m']:.3f} m); reference oracles (threshold grid-searched per trial): "
                  f"best of five detectors {m['reference_best_m']:.4f} m, SHOE {m['reference_shoe_m']:.4f} m; "
                  f"{m['realtime_factor']:.0f}x real time")
        if "xio_gait_loop" in out:
            for row in out["xio_gait_loop"][method]["per_walk"]:
                print(f"[{method}] xio {row['file']}: loop-closure error {row['loop_error_m'] * 1000:.0f} mm "
                      f"({row['loop_error_pct']:.2f} % of {row['distance_m']:.1f} m)")
        if "foot_stride_gcp" in out:
            r = out["foot_stride_gcp"][method]
            for row in r["per_walk"]:
                if "error" in row:
                    print(f"[{method}] gcp {row['file']}: skipped ({row['error']})")
                    continue
                print(f"[{method}] gcp {row['file']}: {row['strides']} strides, mean error "
                      f"{row['mean_stride_error_m']:.2f} m, final {row['final_error_m']:.2f} m = "
                      f"{row['final_error_pct']:.2f} % of {row['distance_m']:.1f} m")
            print(f"[{method}] gcp ALL ({r['walks']} walks): median final error {r['median_final_error_pct']:.2f} %")
    for pair, c in out.get("pyshoe_vicon_paired", {}).items():
        print(f"[{pair}] pyshoe: lower ARMSE on {c['better']} of {c['trials']} trials, median difference "
              f"{c['median_difference_m'] * 1000:+.1f} mm, Wilcoxon p = {c['wilcoxon_p']:.3f}")


#: Methods that ``pdr eval foot --method all`` compares.
EVAL_METHODS: tuple[str, ...] = ("zupt", "filterbank", "filterbank-height", "bc")


def run_eval(args: argparse.Namespace) -> int:
    root = Path(args.data or args.dir or ".")
    if not root.exists():
        raise InputError("no such folder", source=str(root))
    tracks = Path(args.tracks) if args.tracks else None
    evaluated = EVAL_METHODS if args.method == "all" else (args.method,)
    methods = eval_variants(evaluated, args.hde, args.smoother, plain=args.method == "all")
    out: dict[str, Any] = {"methods": list(methods), "detector": args.detector, "smoother": args.smoother,
                           "zv_labels": args.zv_labels}
    # --zaru / --imu-samples / --gyro-bias on a method without them: it runs without (pdr foot refuses them).
    not_applied = {m: _method_zupt_config(m, args)[1] for m in evaluated}
    out["not_applied"] = {m: flags for m, flags in not_applied.items() if flags}
    evaluators = {"pyshoe_vicon": eval_pyshoe, "xio_gait_loop": eval_xio, "foot_stride_gcp": eval_gcp}
    for name, d in _dataset_dirs(root).items():
        out[name] = {}
        for method in methods:
            sub = tracks / name / method.replace("/", "_") if tracks is not None else None
            if sub is not None:
                sub.mkdir(parents=True, exist_ok=True)
            out[name][method] = evaluators[name](d, args, sub, method)
    if "pyshoe_vicon" in out:
        out["pyshoe_vicon_paired"] = paired_against_zupt(out["pyshoe_vicon"])
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        _print_eval(out)
    return 0


def register_eval(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("foot", help="foot navigation: PyShoe VICON ARMSE, x-io loop closure, stride GCPs")
    p.add_argument("dir", nargs="?", help="shared data folder (or one of pyshoe_vicon, xio_gait_loop, "
                                          "foot_stride_gcp)")
    p.add_argument("--data", help="same as DIR")
    p.add_argument("--json", action="store_true", help="print figures as JSON")
    p.add_argument("--tracks", help="write each track CSV into this folder (for tools/score_tracks.py)")
    p.add_argument("--limit", type=int, default=0, help="only the first N files per dataset (0: all)")
    p.add_argument("--hde", choices=("on", "off", "both"), default="both",
                   help="heuristic heading drift elimination (pdr.foot.drift, the same for every method): with it "
                        "(rows named by the method), without it (rows named METHOD/no-hde), or both (default)")
    _add_options(p, evaluation=True)
    p.add_argument("--zv-labels", choices=ZV_LABELS, default="detector",
                   help="PyShoe only: navigate with the files' reference zero-velocity labels zv_NAME_opt (each "
                        "detector's threshold grid-searched per trial against the VICON truth, an oracle) instead "
                        "of the detector's, to see how much of the error is the detector's (default: detector)")
    p.add_argument("--plain-threshold", type=float, default=PLAIN_THRESHOLD,
                   help="with --method all, the fixed SHOE threshold of the plain ZUPT-EKF baseline (rows "
                        f"zupt{PLAIN}: causal, no gait adaptation; default {PLAIN_THRESHOLD:g}, the best single "
                        "threshold on the PyShoe trials)")
    p.set_defaults(func=run_eval)
