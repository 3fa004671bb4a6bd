"""``pdr calibrate LOG --distance M``: per-user step-length scale from a walk of known length (seed 004 eq. 19)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.io import read_recording
from pdr.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.step_length import EXPONENTS, PATTERNS, StepLengthModel, calibrate_k


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("calibrate", help="fit the step-length scale K to a walk of known length")
    p.add_argument("log", help="log of the calibration walk (any supported format), or with --fit a folder of "
                               "logs with landmark truth")
    p.add_argument("--distance", type=float, help="length of the walk in metres")
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
    if args.distance is None:
        raise InputError("--distance is required (or --fit with a folder of logs with landmarks)",
                         field="distance")
    rec = read_recording(args.log)
    base = StepLengthModel.load(args.base) if args.base else StepLengthModel()
    rows = track_rows(PdrPipeline(PipelineConfig(placement=args.placement, step_length=base)).run(rec))
    if not rows:
        raise InputError("no steps detected in the calibration walk", source=str(args.log))
    pats = np.array([r["patterns"] for r in rows])
    stairs = np.array([r["mode"] in ("stairs_up", "stairs_down") for r in rows])
    model = calibrate_k(base, pats, float(args.distance), stairs)
    model.save(args.out)
    print(f"{len(rows)} steps over {args.distance:.1f} m: K = {model.k:.4f} ({model.pattern}^{model.q:g} "
          f"+ {model.b:.3f}) -> {args.out}")
    return 0


def landmark_segments(rows: list[dict[str, Any]], t_truth: np.ndarray, pos: np.ndarray
                      ) -> list[tuple[np.ndarray, float]]:
    """(patterns of the steps between the first and last landmark, true path length through the landmarks).

    One segment per log: the landmark-to-landmark straight lines approximate the walked path well over a
    whole route, while single short segments suffer from the timing of the landmark clicks.
    """
    t_end = np.array([r["t_s"] for r in rows])
    pats = np.array([r["patterns"] for r in rows])
    sel = (t_end > t_truth[0]) & (t_end <= t_truth[-1])
    length = float(np.sum(np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1)))
    return [(pats[sel], length)] if sel.sum() >= 5 and length > 5.0 else []


def run_fit(args: argparse.Namespace) -> int:
    root = Path(args.log)
    files = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in (".txt", ".gz", ".mat"))
    per_file: list[list[tuple[np.ndarray, float]]] = []
    for f in files:
        try:
            rec = read_recording(f)
        except InputError:
            continue
        pt = rec.truth.positions
        if pt is None or len(pt) < 3:
            continue
        rows = track_rows(PdrPipeline(PipelineConfig(placement=args.placement)).run(rec))
        if rows:
            per_file.append(landmark_segments(rows, rec.origin_ns / 1e9 + pt.t_s, pt.pos_m))
    segs = [s for f in per_file for s in f]
    if not segs:
        raise InputError("no landmark segments with steps found", source=str(root))
    print(f"{len(per_file)} logs (one segment each: first to last landmark), {sum(len(p) for p, _ in segs)} steps")
    print("K is the median over logs of (true length / sum of p^q) (robust to logs whose steps were miscounted); "
          "errors are |estimated / true distance - 1| per log")
    print("pattern  q      K        median |err|  p90 |err|   leave-one-log-out median |err|")
    best: tuple[float, StepLengthModel] | None = None
    for pat in PATTERNS:
        j = PATTERNS.index(pat)
        for q in EXPONENTS:
            sums = np.array([float(np.sum(np.maximum(p[:, j], 0.0) ** q)) for p, _ in segs])
            lengths = np.array([length for _, length in segs])
            k_log = lengths / sums
            k = float(np.median(k_log))
            err = np.abs(k * sums / lengths - 1)
            lolo = np.array([abs(float(np.median(np.delete(k_log, i))) * sums[i] / lengths[i] - 1)
                             for i in range(len(segs))])
            print(f"{pat:7s} {q:5.3f} {k:8.4f}   {np.median(err):8.4f}   {np.percentile(err, 90):8.4f}"
                  f"     {np.median(lolo):8.4f}")
            if best is None or float(np.median(lolo)) < best[0]:
                best = (float(np.median(lolo)), StepLengthModel(pattern=pat, k=k, q=q, b=0.0))
    assert best is not None
    model = StepLengthModel(pattern=best[1].pattern, k=best[1].k, q=best[1].q, b=best[1].b)
    model.save(args.out)
    print(f"best (leave-one-log-out): {model.pattern}^{model.q:g}, K = {model.k:.4f}, b = {model.b:.3f} "
          f"-> {args.out}")
    return 0
