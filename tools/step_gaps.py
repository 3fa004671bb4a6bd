"""Gaps between the pipeline's detected steps while the truth walks: missed steps or stops the truth does not show?

``python tools/step_gaps.py ../shared/data/ms_indoor_location/site2`` runs the pipeline's step detector on each
trace (its grid, :func:`walking_steps.pipeline_step_times`) and lists every gap longer than ``--gap`` s between two step
starts over which the truth, its waypoints interpolated linearly, moves faster than ``--speed`` m/s. Per gap it prints
the waypoints marked inside it and the largest ``|a_n - reference|`` (m/s^2, the detector's own low-passed norm and
reference, :meth:`pdr.phone.steps.StepDetector.filtered_norm`) inside it, beside the 95th percentile of the 3 s before
it. A gap whose signal stays near the reference while a waypoint is marked in it is a stop at that waypoint: linear
interpolation between waypoints walks the truth through the stop (issue 33). Exit code 0.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pdr.errors import InputError
from pdr.io import read_recording
from pdr.phone.pipeline import PipelineConfig
from pdr.phone.steps import StepConfig, StepDetector
from pdr.recording import Recording

sys.path.insert(0, str(Path(__file__).resolve().parent))
from walking_steps import grid_acc, pipeline_step_times  # noqa: E402

#: Seconds before a gap over which the walking signal's 95th percentile is taken.
BEFORE_S = 3.0


def norm_deviation(rec: Recording, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid times (s, the recording's ``t_s`` axis) and ``|a_n - reference|`` (m/s^2) of the step detector."""
    t, acc = grid_acc(rec, rate_hz)
    an, ref = StepDetector(rate_hz).filtered_norm(acc)
    return t, np.abs(an - ref)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", help="a folder searched for *.txt and *.txt.gz logs with truth positions")
    ap.add_argument("--gap", type=float, default=2.0, help="shortest gap between step starts listed (s)")
    ap.add_argument("--speed", type=float, default=0.6, help="slowest truth speed over the gap listed (m/s)")
    args = ap.parse_args(argv)
    rate = PipelineConfig().rate_hz
    files = sorted(p for pat in ("*.txt", "*.txt.gz") for p in Path(args.dir).rglob(pat))
    n_gaps = n_stops = 0
    for f in files:
        try:
            rec = read_recording(f)
        except InputError as exc:
            print(f"{f.name}: {exc}")
            continue
        pt = rec.truth.positions
        if pt is None or len(pt) < 3:
            continue
        starts, _ = pipeline_step_times(rec, StepConfig(), rate)
        t, dev = norm_deviation(rec, rate)
        wt, wxy = np.asarray(pt.t_s), np.asarray(pt.pos_m)[:, :2]
        for a, b in zip(starts[:-1], starts[1:], strict=True):
            if b - a <= args.gap or a < wt[0] or b > wt[-1]:
                continue
            g = np.linspace(a, b, 50)
            path = np.column_stack([np.interp(g, wt, wxy[:, 0]), np.interp(g, wt, wxy[:, 1])])
            dist = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
            if dist / (b - a) <= args.speed:
                continue
            step = float(np.median(np.diff(starts)))
            inside = (t > a + step) & (t < b - 0.2)     # after the last step's own hump, before the next step's rise
            before = (t > a - BEFORE_S) & (t < a)
            peak = float(dev[inside].max()) if inside.any() else float("nan")
            walk = float(np.percentile(dev[before], 95)) if before.any() else float("nan")
            marked = wt[(wt > a) & (wt < b)]
            n_gaps += 1
            n_stops += int(marked.size > 0 and peak < 0.25 * walk)
            print(f"{f.name} ({f.parent.parent.name}): no step {a:.1f}-{b:.1f} s ({b - a:.1f} s), truth {dist:.1f} m; "
                  f"waypoints marked in it at {' '.join(f'{x:.1f}' for x in marked) or '-'} s; max |a_n - ref| inside "
                  f"{peak:.2f} m/s^2, walking before p95 {walk:.2f} m/s^2")
    print(f"{n_gaps} gaps; {n_stops} of them with a waypoint marked inside and the signal below a quarter of the "
          "walking one (a stop at the waypoint)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
