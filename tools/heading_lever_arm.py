"""How much of a held phone's walking-direction error on the motion-capture benchmark is the truth's lever arm.

The benchmark's walking-direction truth is the path of the phone itself (``../shared/data/attitude_smartphones``,
SOURCE.md). A phone held in front of the body (texting) sits a lever arm ``r`` ahead of the walker's vertical axis, so
when the walker turns at ``Omega`` while walking at ``V`` its path leans into the turn by ``atan(r Omega / V)`` against
the body's heading, which is what a device heading measures. In the benchmark's 5 x 5 m room (texting at 0.4-0.7 m/s,
turning about 23 deg/s) that is 10-20 deg in every turn, for the phone's own rotation vector as for ours.

``python tools/heading_lever_arm.py STEPS_DIR`` (``STEPS_DIR`` from ``pdr eval heading DATA --steps STEPS_DIR``) scores
the per-step headings of the texting walks, ours and the rotation vector's device +y, against the path of a body
point ``r`` behind the phone (``r`` 0, 0.2, 0.3 and 0.4 m along the phone's horizontal -y, from the motion-capture
attitude), smoothed over one stride as the truth's path is.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from pdr import quaternion as quat
from pdr.evaluation.heading import recordings_in
from pdr.io import read_recording
from pdr.recording import Recording

LEVER_ARMS_M = (0.0, 0.2, 0.3, 0.4)
MOCAP_HZ = 60


def body_point_heading_deg(rec: Recording, t_start_s: np.ndarray, t_end_s: np.ndarray, lever_m: float
                           ) -> np.ndarray:
    """Compass heading (deg) of the displacement of a point ``lever_m`` behind the phone (along its horizontal -y)
    between each step's start and end (log clock, s), the point's path averaged over one second (one stride).
    """
    ex = rec.truth.extra
    t = rec.origin_ns / 1e9 + np.asarray(ex["trajectory_t_s"], dtype=np.float64)
    q = np.asarray(ex["q_nb"], dtype=np.float64)
    walk = np.asarray(ex["walk_pos_m"], dtype=np.float64)[:, :2]
    hidden = ~np.isfinite(q).all(axis=1)
    y = quat.rotate(np.where(hidden[:, None], [1.0, 0.0, 0.0, 0.0], q), np.broadcast_to([0.0, 1.0, 0.0], (t.size, 3)))
    y_h = y[:, :2] / np.maximum(np.linalg.norm(y[:, :2], axis=1), 1e-9)[:, None]
    kernel = np.ones(MOCAP_HZ) / MOCAP_HZ
    back = np.column_stack([np.convolve(y_h[:, i], kernel, mode="same") for i in range(2)]) * lever_m
    body = walk - back
    d = np.column_stack([np.interp(t_end_s, t, body[:, i]) - np.interp(t_start_s, t, body[:, i]) for i in range(2)])
    return np.asarray(90.0 - np.degrees(np.arctan2(d[:, 1], d[:, 0])))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("steps_dir", type=Path, help="per-step CSVs of pdr eval heading --steps")
    ap.add_argument("--data", type=Path, default=Path("../shared/data/attitude_smartphones"))
    args = ap.parse_args(argv)
    print(f"{'texting walk':36s} " + " | ".join(f"r={r:.1f} m: ours   RV" for r in LEVER_ARMS_M))
    for path in recordings_in(args.data):
        if "Texting" not in path.name or not (args.steps_dir / f"{path.name}.csv").is_file():
            continue
        steps = pd.read_csv(args.steps_dir / f"{path.name}.csv")
        rec = read_recording(path)
        scored = np.isfinite(steps.true_heading_deg.to_numpy()) & np.isfinite(steps.heading_deg.to_numpy())
        cells = []
        for lever in LEVER_ARMS_M:
            truth = body_point_heading_deg(rec, steps.t_start_s.to_numpy(), steps.t_s.to_numpy(), lever)
            errs = [np.abs((steps[col].to_numpy() - truth + 180.0) % 360.0 - 180.0)[scored]
                    for col in ("heading_deg", "rv_y_heading_deg")]
            cells.append(f"{np.nanmean(errs[0]):10.1f} {np.nanmean(errs[1]):5.1f}")
        print(f"{path.name:36s} " + " | ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
