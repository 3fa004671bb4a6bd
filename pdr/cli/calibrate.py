"""``pdr calibrate LOG [--distance M]``: per-user step-length scale from a walk of known length (seed 004 eq. 19).

The length is ``--distance`` or, for a log with landmark truth, the straight lines between consecutive
landmarks on one floor (:func:`landmark_walk`); ``pdr eval ipin --calibrate`` uses the same code on other logs.
"""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from pdr.cli.outputs import in_made_folder
from pdr.errors import InputError
from pdr.io import read_recording
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.phone.step_length import EXPONENTS, PATTERNS, StepLengthModel, calibrate_k, fit_model, step_sums, turn_factor


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("calibrate", help="fit the step-length scale K to a walk of known length")
    p.add_argument("log", help="log of the calibration walk (any supported format), or with --fit a folder of "
                               "logs with landmark truth")
    p.add_argument("--distance", type=float,
                   help="length of the walk in metres (default: the log's landmark truth, intervals on one floor)")
    p.add_argument("--fit", action="store_true",
                   help="fit K and q of every pattern p1-p6 (eq. 19) on the landmark segments of all logs in the "
                        "folder LOG, print the table and save the best model")
    p.add_argument("--placement", default="auto", choices=("auto", "pocket", "torso", "hand"))
    p.add_argument("--base", help="calibration JSON to start from (pattern, exponent, offset); default model")
    p.add_argument("--out", required=True, help="calibration JSON for `pdr track --calibration`")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.fit:
        return run_fit(args)
    rec = read_recording(args.log)
    base = StepLengthModel.load(args.base) if args.base else StepLengthModel()
    rows = track_rows(PdrPipeline(PipelineConfig(placement=args.placement, step_length=base)).run(rec))
    if not rows:
        raise InputError("no steps detected in the calibration walk", source=str(args.log))
    if args.distance is not None:
        walk = CalibrationWalk(np.array([r["patterns"] for r in rows]), stairs_flags(rows), float(args.distance),
                               turns_rad(rows))
        what = f"{args.distance:.1f} m"
    else:
        pt = rec.truth.positions
        found = None if pt is None or len(pt) < 2 else landmark_walk(
            rows, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m, pt.floor)
        if found is None:
            raise InputError("--distance is required: the log has no landmark truth with steps between landmarks "
                             "on one floor (or use --fit with a folder of logs with landmarks)", field="distance")
        walk = found
        what = f"{walk.length_m:.1f} m between landmarks on one floor"
    model = calibrate_on_walks(base, [walk])
    model.save(in_made_folder(args.out))
    print(f"{walk.patterns.shape[0]} steps over {what}: K = {model.k:.4f} ({model.pattern}^{model.q:g} "
          f"+ {model.b:.3f}) -> {args.out}")
    return 0


@dataclass(frozen=True)
class CalibrationWalk:
    """A walk of known length: the patterns (K, 6) of its steps, which were on stairs (K,), its length in m, and
    the steps' turns (K,) in rad (None: straight; :func:`pdr.phone.step_length.turn_factor`).
    """

    patterns: np.ndarray
    on_stairs: np.ndarray
    length_m: float
    turn_rad: np.ndarray | None = None

    def turns(self) -> np.ndarray:
        """(K,) turns in rad (zeros for a walk without them)."""
        return np.zeros(self.on_stairs.size) if self.turn_rad is None else self.turn_rad

    def factors(self, turn: str = StepLengthModel().turn) -> np.ndarray:
        """(K,) the steps' turn factors under the turn model ``turn`` (default: the default model's)."""
        return turn_factor(self.turns(), turn)


def turns_rad(rows: list[dict[str, Any]]) -> np.ndarray:
    """(K,) the step rows' turns in rad (``turn_deg``; 0 for rows written before it existed)."""
    return np.radians([float(r.get("turn_deg", 0.0)) for r in rows])


def stairs_flags(rows: list[dict[str, Any]]) -> np.ndarray:
    """(K,) bool: the step rows labelled stairs up or down."""
    return np.array([r["mode"] in ("stairs_up", "stairs_down") for r in rows], dtype=bool)


def landmark_walk(rows: list[dict[str, Any]], t_truth: np.ndarray, pos: np.ndarray,
                  floor: np.ndarray | None = None) -> CalibrationWalk | None:
    """The walk between landmarks on one floor: steps ending inside those intervals, straight-line length.

    The intervals are those :func:`pdr.evaluation.scoring.distance_ratio_same_floor` scores: across a floor change the
    straight line between two landmarks is not the walked path (winding stairs). ``floor`` (N,) is the
    landmarks' floor (None: all on one floor); ``t_truth`` (N,) s on the rows' clock; ``pos`` (N, >=2) m.
    None if fewer than 5 steps or 5 m remain.
    """
    t_end = np.array([r["t_s"] for r in rows])
    fl = np.zeros(len(t_truth)) if floor is None else np.asarray(floor, dtype=np.float64)
    sel = np.zeros(t_end.size, dtype=bool)
    length = 0.0
    for k in range(len(t_truth) - 1):
        if fl[k] == fl[k + 1]:
            sel |= (t_end > t_truth[k]) & (t_end <= t_truth[k + 1])
            length += float(np.linalg.norm(pos[k + 1, :2] - pos[k, :2]))
    if sel.sum() < 5 or length <= 5.0:
        return None
    return CalibrationWalk(np.array([r["patterns"] for r in rows])[sel], stairs_flags(rows)[sel], length,
                           turns_rad(rows)[sel])


def calibrate_on_walks(base: StepLengthModel, walks: list[CalibrationWalk]) -> StepLengthModel:
    """``base`` with ``K`` rescaled (:func:`pdr.phone.step_length.calibrate_k`) so the walks' steps add up to their
    length.
    """
    if not walks:
        raise InputError("no calibration walk", source="calibration")
    return calibrate_k(base, np.vstack([w.patterns for w in walks]), sum(w.length_m for w in walks),
                       np.concatenate([w.on_stairs for w in walks]), np.concatenate([w.turns() for w in walks]))


def trial_key(path: str | Path) -> str:
    """The route a log walks: ``TrialNN`` of an IPIN logfile name (its repetitions share it), else the file stem."""
    m = re.search(r"Trial(\d+)", Path(path).name)
    return f"Trial{m.group(1)}" if m else Path(path).name


def calibration_partners(i: int, routes: list[str], phones: list[str], usable: list[bool], mode: str) -> list[int]:
    """Indices of the logs that calibrate log ``i``: same phone, never ``i`` itself, and a usable walk.

    ``mode`` ``cross``: logs of the other routes; ``cross-rep``: the other repetitions of the same route.
    """
    if mode not in ("cross", "cross-rep"):
        raise InputError("mode must be 'cross' or 'cross-rep'", field="calibrate")
    return [k for k in range(len(routes)) if k != i and usable[k] and phones[k] == phones[i]
            and (routes[k] != routes[i]) == (mode == "cross")]


def _fit_rel_errors(walks: list[CalibrationWalk], groups: list[str], phones: list[str], pattern: str, q: float,
                    fit_offset: bool) -> tuple[np.ndarray, np.ndarray]:
    """Relative distance errors of every walk, leaving its route out of the fit.

    First: ``K`` (and ``b``) of eq. 19 fitted on the walks of the other routes (:func:`fit_model`). Second: that
    model with ``K`` recalibrated (:func:`calibrate_on_walks`) on the other routes walked with the same phone.
    """
    pooled, per_phone = [], []
    for i, w in enumerate(walks):
        train = [k for k in range(len(walks)) if groups[k] != groups[i]]
        m = fit_model([(walks[k].patterns, walks[k].length_m) for k in train], pattern, q, fit_offset,
                      [walks[k].factors() for k in train]).model
        sp, n = step_sums(w.patterns, pattern, q, w.factors())
        pooled.append((m.k * sp + m.b * n) / w.length_m - 1.0)
        # Like fit_model, every step counts as a step on the flat here.
        same = [replace(walks[k], on_stairs=np.zeros_like(walks[k].on_stairs)) for k in train
                if phones[k] == phones[i]]
        try:
            mc = calibrate_on_walks(m, same)
            per_phone.append((mc.k * sp + mc.b * n) / w.length_m - 1.0)
        except InputError:
            per_phone.append(np.nan)
    return np.array(pooled), np.array(per_phone)


def run_fit(args: argparse.Namespace) -> int:
    root = Path(args.log)
    files = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in (".txt", ".gz", ".mat"))
    walks: list[CalibrationWalk] = []
    groups: list[str] = []
    phones: list[str] = []
    for f in files:
        try:
            rec = read_recording(f)
        except InputError:
            continue
        pt = rec.truth.positions
        if pt is None or len(pt) < 3:
            continue
        rows = track_rows(PdrPipeline(PipelineConfig(placement=args.placement)).run(rec))
        w = landmark_walk(rows, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m, pt.floor) if rows else None
        if w is not None:
            walks.append(w)
            groups.append(trial_key(f))
            phones.append(rec.device.model)
    if len({*groups}) < 2:
        raise InputError("need logs of at least two routes with landmarks on one floor", source=str(root))
    print(f"{len(walks)} logs of {len({*groups})} routes, {sum(w.patterns.shape[0] for w in walks)} steps between "
          f"landmarks on one floor; phones {sorted({*phones})}")
    print("errors: |estimated / true distance - 1| per log, the log's route (all its repetitions) left out of the fit;")
    print("'per phone': the same model with K recalibrated on the phone's other routes (pdr calibrate); a failed "
          "recalibration (K <= 0) counts as outside 3 %")
    print("pattern  q      b?  K (all)   b (all) | left out: median  max   >3%  | per phone: median  max   >3%")
    table = []
    for pat in PATTERNS:
        for q in EXPONENTS:
            for off in (False, True):
                full = fit_model([(w.patterns, w.length_m) for w in walks], pat, q, off,
                                 [w.factors() for w in walks]).model
                e_pool, e_phone = (np.abs(e) for e in _fit_rel_errors(walks, groups, phones, pat, q, off))
                table.append((int(np.sum(e_pool > 0.03)), float(np.median(e_pool)), full))
                bad = ~(e_phone <= 0.03)   # NaN: recalibration failed (non-positive K)
                nan = int(np.sum(np.isnan(e_phone)))
                ph = (f"{np.nanmedian(e_phone):6.3f} {np.nanmax(e_phone):6.3f} {np.sum(bad):3d}" if nan < e_phone.size
                      else "   n/a    n/a") + (f" ({nan} failed)" if nan else "")
                print(f"{pat:7s} {q:5.3f}  {'b' if off else '-'}  {full.k:8.4f} {full.b:8.3f} |"
                      f"         {np.median(e_pool):6.3f} {e_pool.max():6.3f} {np.sum(e_pool > 0.03):3d}  |"
                      f"         {ph}")
    _, med, best = min(table, key=lambda r: (r[0], r[1]))
    model = StepLengthModel(pattern=best.pattern, k=best.k, q=best.q, b=best.b)
    model.save(in_made_folder(args.out))
    print(f"best (fewest logs outside 3 % with their route left out, then median): {model.pattern}^{model.q:g}, "
          f"K = {model.k:.4f}, b = {model.b:.3f} (left-out median error {med:.3f}) -> {args.out}")
    return 0
