"""Steps the phone pipeline's detector finds on every walking recording of a data folder, and on the non-walking ones.

``python tools/walking_steps.py ../shared/data`` runs :class:`pdr.phone.steps.StepDetector` on the pipeline's grid
(the streams and rate ``pdr track`` uses, :class:`pdr.phone.grid.OnlineGrid`: the same step events as the pipeline,
without its attitude and heading stages) for each phone recording of the datasets below, and prints per recording
the steps found, the plain peak detector's count (:func:`pdr.evaluation.scoring.plain_step_count`) and the true count
where the dataset has one. ``pdr track`` gives an empty track ("no walking detected") exactly when no step is found:
the recordings with none are listed at the end, and the exit code is 1 if a walking recording is among them.

Where a recording has a motion-capture trajectory of the phone and no counted steps (``attitude_smartphones``), the
true count is :func:`pdr.evaluation.mocap_steps.mocap_step_count`: the phone's vertical oscillation, one rise and
fall per step (the truth ``pdr eval steps`` uses there too).

Walking: ``sensor_logger_walks`` (every walk), ``oxford_step_counter`` (every trial), ``mobifall_v2_pocket`` WAL,
STU and STN (walking, stairs up and down), ``ms_indoor_location`` (every trace), ``ipin2023_t3`` (every log),
``attitude_smartphones`` (every recording; RunningPocket is running). Not walking, where every step is a false
one: MobiFall CSI and CSO (getting into and out of a car), SCH (sitting down on a chair), STD (standing) and JUM
(jumping). Foot-mounted IMU data (``pyshoe_vicon``, ``foot_stride_gcp``, ``xio_gait_loop``) is ``pdr foot``'s.

``--cut S`` cuts each recording's first S seconds first, as a recording started later would be: counts should fall
by about the steps of those seconds and never rise (the detector's decisions depend on what it has seen, so a walk's
counting must not hinge on where the recording starts).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.evaluation.mocap_steps import (
    MOCAP_MATCH_S,
    matched_steps,
    mocap_step_times,
    mocap_trajectory,
    true_step_count,
)
from pdr.evaluation.scoring import plain_step_count
from pdr.evaluation.walking_recordings import recordings
from pdr.io import read_recording
from pdr.phone.grid import OnlineGrid
from pdr.phone.pipeline import PipelineConfig
from pdr.phone.steps import StepConfig, StepDetector


def pipeline_steps(rec: Any, config: StepConfig, rate_hz: float) -> tuple[int, float]:
    """Steps the pipeline's detector finds on ``rec`` (its grid: acc and the gyro, mag and baro it has) and the
    grid's duration (s).
    """
    times, dur = pipeline_step_times(rec, config, rate_hz)
    return int(times.size), dur


def grid_acc(rec: Any, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The pipeline's grid of the recording: times (s, the recording's ``t_s`` axis: the grid's times less
    ``t0_ns / 1e9``, as the motion capture's) and the specific force (N, 3; m/s^2, device frame).
    """
    kinds = ("acc",) + tuple(k for k in ("gyro", "mag", "baro") if rec.has(k))
    grid = OnlineGrid(rate_hz, kinds)
    grid.push(rec)
    t1, v1 = grid.pull()
    t2, v2 = grid.flush()
    t = np.concatenate([t1, t2])
    acc = np.concatenate([v1["acc"] if t1.size else np.zeros((0, 3)), v2["acc"] if t2.size else np.zeros((0, 3))])
    return t - rec.origin_ns / 1e9, acc


def pipeline_step_times(rec: Any, config: StepConfig, rate_hz: float) -> tuple[np.ndarray, float]:
    """Start times (s, the recording's ``t_s`` axis, :func:`grid_acc`) of the steps of :func:`pipeline_steps`, and the
    grid's duration (s).
    """
    t, acc = grid_acc(rec, rate_hz)
    steps, _ = StepDetector(rate_hz, config).update(acc, final=True)
    return t[steps.start_idx], (float(t[-1] - t[0]) if t.size else 0.0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="the shared data folder (../shared/data)")
    ap.add_argument("--step", metavar="JSON", default="{}", help="StepConfig fields as a JSON object")
    ap.add_argument("--only", default="", help="only datasets whose name contains this")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON to FILE")
    ap.add_argument("--cut", type=float, default=0.0, metavar="S",
                    help="first cut each recording's first S seconds, as a recording started later (mid-walk, or while "
                         "the phone is put away) would be: a count should fall by about the steps of those seconds, "
                         "never rise, and nothing after them should be lost (no true count is printed then)")
    args = ap.parse_args(argv)
    config = StepConfig(**json.loads(args.step))
    rate = PipelineConfig().rate_hz
    rows: list[dict[str, Any]] = []
    for dataset, path, walking in recordings(Path(args.data)):
        if args.only not in dataset:
            continue
        try:
            rec = read_recording(path)
        except InputError as exc:
            rows.append({"dataset": dataset, "path": str(path), "walking": walking, "error": str(exc)})
            print(f"{dataset}: {path.name}: {exc}", flush=True)
            continue
        if args.cut > 0.0:
            t0, t1 = rec.time_span_s()
            rec = rec.slice_time(t0 + args.cut, t1 + 1.0)
        n, dur = pipeline_steps(rec, config, rate)
        acc = rec.stream("acc")
        plain = plain_step_count(acc.t_ns / 1e9, np.asarray(acc.values))
        true, origin = true_step_count(rec)
        if args.cut > 0.0 and origin != "mocap":
            true = None                 # a count of the whole walk (the motion capture's is of the recording's span)
        row = {"dataset": dataset, "path": str(path), "walking": walking, "duration_s": dur, "steps": n,
               "plain": plain, "true": true, "true_from": origin}
        note = f", true {true}" if true is not None else ""
        trajectory = mocap_trajectory(rec) if origin == "mocap" else None
        if trajectory is not None:
            times, _ = pipeline_step_times(rec, config, rate)
            row["matched"], _ = matched_steps(times, mocap_step_times(*trajectory))
            note += f" from motion capture, {row['matched']} matched within {MOCAP_MATCH_S} s"
        rows.append(row)
        print(f"{dataset}: {path.name}: {dur:.1f} s, {n} steps (plain peak detector {plain}{note})", flush=True)
    empty = [r for r in rows if r["walking"] and r.get("steps") == 0]
    unread = [r for r in rows if "error" in r]
    false = [r for r in rows if not r["walking"] and r.get("steps")]
    print(f"walking recordings: {sum(r['walking'] for r in rows)}, with no step (empty track): {len(empty)}")
    for r in empty:
        print(f"  EMPTY {r['path']} ({r['duration_s']:.1f} s, plain peak detector {r['plain']})")
    for r in unread:
        print(f"  UNREAD {r['path']}: {r['error']}")
    not_walking = [r for r in rows if not r["walking"] and "steps" in r]
    print(f"non-walking recordings: {len(not_walking)}, with steps: {len(false)}, "
          f"{sum(r['steps'] for r in false)} steps in all")
    for r in false:
        print(f"  STEPS {r['path']}: {r['steps']}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 1 if empty else 0


if __name__ == "__main__":
    sys.exit(main())
