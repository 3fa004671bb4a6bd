"""Simulated training and test logs for classes real data lacks (elevator, escalator), via :mod:`pdr.sim`.

:func:`landmark_scenarios` draws scenario documents that string together standing, level walking, stairs,
elevator and escalator rides in random order, placement (trouser pocket, hand, torso), speeds and floor
counts; :func:`simulated_recordings` runs the simulator on them. The simulator labels ``truth.modes``
(``standing``, ``walking``, ``stairs_up``, ``elevator_down``, ...), so the windows are labelled like any other
log. Each recording is its own group in cross-validation.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from pdr.recording import Recording
from pdr.sim import simulate

PLACEMENTS = ("trouser_pocket", "hand", "torso")
VERTICAL = ("stairs", "elevator", "escalator")


def landmark_scenarios(n: int, seed: int = 0) -> list[dict[str, Any]]:
    """``n`` random scenario documents with every vertical mode (module docstring)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        floor = 2
        segs: list[dict[str, Any]] = [{"type": "stand", "duration_s": float(rng.uniform(3, 8))}]
        for kind in rng.permutation(VERTICAL):
            segs.append({"type": "walk", "duration_s": float(rng.uniform(4, 10)),
                         "speed_mps": float(rng.uniform(0.9, 1.5))})
            if kind == "elevator":
                segs.append({"type": "stand", "duration_s": float(rng.uniform(3, 8))})
            direction = "up" if rng.random() < 0.5 or floor <= 1 else "down"
            floors = int(rng.integers(1, 3))
            floor += floors if direction == "up" else -floors
            segs.append({"type": str(kind), "direction": direction, "floors": floors})
            segs.append({"type": "stand", "duration_s": float(rng.uniform(2, 6))})
        segs.append({"type": "walk", "duration_s": float(rng.uniform(4, 10))})
        out.append({"name": f"sim_landmark_{seed}_{i}", "placement": str(rng.choice(PLACEMENTS)),
                    "start": {"position_m": [0, 0, 6], "heading_deg": float(rng.uniform(0, 360)), "floor": 2},
                    "sensors": {"grade": "consumer"}, "segments": segs})
    return out


def simulated_recordings(n: int, seed: int = 0) -> list[Recording]:
    """Simulate :func:`landmark_scenarios` (``n`` logs); each recording's source names its scenario."""
    recs = []
    for i, sc in enumerate(landmark_scenarios(n, seed)):
        rec = simulate(sc, seed=seed * 1000 + i)
        recs.append(replace(rec, source=str(sc["name"]), format=rec.format or "sim"))
    return recs
