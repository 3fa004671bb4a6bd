"""Steps the phone pipeline's detector finds on every walking recording of a data folder, and on the non-walking ones.

``python tools/walking_steps.py ../shared/data`` runs :class:`pdr.phone.steps.StepDetector` on the pipeline's grid
(the streams and rate ``pdr track`` uses, :class:`pdr.phone.grid.OnlineGrid`: the same step events as the pipeline,
without its attitude and heading stages) for each phone recording of the datasets below, and prints per recording
the steps found, the plain peak detector's count (:func:`pdr.evaluation.scoring.plain_step_count`) and the true count
where the dataset has one. ``pdr track`` gives an empty track ("no walking detected") exactly when no step is found:
the recordings with none are listed at the end, and the exit code is 1 if a walking recording is among them.

Where a recording has a motion-capture trajectory of the phone and no counted steps (``attitude_smartphones``), the
true count is :func:`mocap_step_count`: the phone's vertical oscillation, one rise and fall per step.

Walking: ``sensor_logger_walks`` (every walk), ``oxford_step_counter`` (every trial), ``mobifall_v2_pocket`` WAL,
STU and STN (walking, stairs up and down), ``ms_indoor_location`` (every trace), ``ipin2023_t3`` (every log),
``attitude_smartphones`` (every recording; RunningPocket is running). Not walking, where every step is a false
one: MobiFall CSI and CSO (getting into and out of a car), SCH (sitting down on a chair), STD (standing) and JUM
(jumping). Foot-mounted IMU data (``pyshoe_vicon``, ``foot_stride_gcp``, ``xio_gait_loop``) is ``pdr foot``'s.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.evaluation.scoring import match_steps, plain_step_count
from pdr.evaluation.walking_recordings import recordings
from pdr.io import read_recording
from pdr.phone.grid import OnlineGrid
from pdr.phone.pipeline import PipelineConfig
from pdr.phone.steps import StepConfig, StepDetector

#: Band (Hz) of the phone's vertical oscillation at the step frequency: walking (0.8-2.2 steps/s) and running.
MOCAP_STEP_BAND_HZ = (0.7, 3.0)
#: Rise of the phone (m) that makes a step in :func:`mocap_step_count`: above the motion capture's sub-millimetre noise,
#: below the 1-5 cm vault of a walk.
MOCAP_STEP_RISE_M = 0.002
#: Shortest step (s) of :func:`mocap_step_count` (the plain detector's too).
MOCAP_MIN_STEP_S = 0.3

#: Largest distance (s) between a detected step and the true step it matches (:func:`matched_steps`).
MOCAP_MATCH_S = 0.3

def mocap_step_count(t_s: np.ndarray, pos_m: np.ndarray, rise_m: float = MOCAP_STEP_RISE_M) -> int:
    """True step count from a motion-capture trajectory of the phone: the size of :func:`mocap_step_times`."""
    return int(mocap_step_times(t_s, pos_m, rise_m).size)


def mocap_step_times(t_s: np.ndarray, pos_m: np.ndarray, rise_m: float = MOCAP_STEP_RISE_M) -> np.ndarray:
    """Times (s) of the true steps in a motion-capture trajectory of the phone: the walker's body vaults over the
    stance leg once per step (inverted pendulum), so the phone, on the thigh or in the hand, rises and falls once per
    step; a step's time is the top of its rise.

    The height ``pos_m[:, 2]`` (m, z up) is put on a uniform grid at the capture's median frame rate (hidden frames
    interpolated), band-passed to :data:`MOCAP_STEP_BAND_HZ` (2nd-order Butterworth, forward and backward), and its
    peaks of prominence at least ``rise_m`` (m), at least :data:`MOCAP_MIN_STEP_S` apart, are counted. Standing moves
    the phone by less than ``rise_m`` (no step). Independent of the accelerometer. Checked against the detector where
    it is right (Jakob_Nexus5_NoDist_Texting: 179 of its 186 steps pair up with the 184 found here; the front-pocket
    walks: 167-183 of 175-190); in a back pocket it is looser (107-209 of 172-228 pair up).

    Parameters
    ----------
    t_s
        (K,) frame times (s), increasing.
    pos_m
        (K, 3) phone positions (m), z up; frames with a NaN are left out.
    """
    from scipy import signal

    t = np.asarray(t_s, dtype=np.float64)
    z = np.asarray(pos_m, dtype=np.float64)[:, 2]
    ok = np.isfinite(t) & np.isfinite(z)
    t, z = t[ok], z[ok]
    if t.size < 2:
        return np.zeros(0)
    rate = 1.0 / float(np.median(np.diff(t)))
    lo, hi = MOCAP_STEP_BAND_HZ
    if not hi < 0.5 * rate:
        raise InputError(f"motion capture at {rate:.1f} Hz is too slow for steps up to {hi} Hz",
                         field="t_s", source="motion-capture truth")
    grid = np.arange(t[0], t[-1], 1.0 / rate)
    b, a = signal.butter(2, [lo / (0.5 * rate), hi / (0.5 * rate)], "band")
    if grid.size <= 3 * max(a.size, b.size):
        return np.zeros(0)
    zb = signal.filtfilt(b, a, np.interp(grid, t, z))
    peaks, _ = signal.find_peaks(zb, prominence=rise_m, distance=max(1, int(MOCAP_MIN_STEP_S * rate)))
    return grid[peaks]


def matched_steps(detected_s: np.ndarray, true_s: np.ndarray, tol_s: float = MOCAP_MATCH_S) -> tuple[int, float]:
    """How many detected steps match a true step one to one, and the lag (s) applied
    (:func:`pdr.evaluation.scoring.match_steps`: each detected time, shifted by the median lag to the nearest true step,
    takes the nearest unmatched true step within ``tol_s``).
    """
    hit, _, lag = match_steps(detected_s, true_s, tol_s)
    return int(hit.sum()), lag


def true_step_count(rec: Any) -> tuple[int | None, str]:
    """The recording's true step count and where it comes from: counted steps (``''``) or, failing them, the
    phone's motion-capture trajectory within the phone's recording (``'mocap'``, :func:`mocap_step_count`);
    ``(None, '')`` if it has neither.
    """
    if rec.truth.step_count is not None:
        return int(rec.truth.step_count), ""
    trajectory = mocap_trajectory(rec)
    if trajectory is not None:
        return mocap_step_count(*trajectory), "mocap"
    return None, ""


def mocap_trajectory(rec: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """Frame times (K,) s and phone positions (K, 3) m of the recording's motion capture within the phone's
    recording (dense 3-D truth positions), or None if it has none.
    """
    pos = rec.truth.positions
    if pos is None or pos.kind != "dense" or pos.pos_m.ndim != 2 or pos.pos_m.shape[1] != 3:
        return None
    start, end = rec.time_span_s()
    inside = (pos.t_s >= start) & (pos.t_s <= end)
    return pos.t_s[inside], pos.pos_m[inside]


def pipeline_steps(rec: Any, config: StepConfig, rate_hz: float) -> tuple[int, float]:
    """Steps the pipeline's detector finds on ``rec`` (its grid: acc and the gyro, mag and baro it has) and the
    grid's duration (s).
    """
    times, dur = pipeline_step_times(rec, config, rate_hz)
    return int(times.size), dur


def pipeline_step_times(rec: Any, config: StepConfig, rate_hz: float) -> tuple[np.ndarray, float]:
    """Start times (s, the recording's ``t_s``) of the steps of :func:`pipeline_steps`, and the grid's duration (s)."""
    kinds = ("acc",) + tuple(k for k in ("gyro", "mag", "baro") if rec.has(k))
    grid = OnlineGrid(rate_hz, kinds)
    grid.push(rec)
    det = StepDetector(rate_hz, config)
    t1, v1 = grid.pull()
    t2, v2 = grid.flush()
    starts: list[np.ndarray] = []
    for t, vals, final in ((t1, v1, False), (t2, v2, True)):
        steps, _ = det.update(vals["acc"] if t.size else np.zeros((0, 3)), final=final)
        starts.append(steps.start_idx)
    t = np.concatenate([t1, t2])
    idx = np.concatenate(starts)
    return (t[idx] if t.size else np.zeros(0)), (float(t[-1] - t[0]) if t.size else 0.0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="the shared data folder (../shared/data)")
    ap.add_argument("--step", metavar="JSON", default="{}", help="StepConfig fields as a JSON object")
    ap.add_argument("--only", default="", help="only datasets whose name contains this")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON to FILE")
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
        n, dur = pipeline_steps(rec, config, rate)
        acc = rec.stream("acc")
        plain = plain_step_count(acc.t_ns / 1e9, np.asarray(acc.values))
        true, origin = true_step_count(rec)
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
