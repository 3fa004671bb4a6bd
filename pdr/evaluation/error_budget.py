"""Error budget of a phone track against landmark truth: how much of its landmark error heading and walk-level step
length explain (``pdr eval ipin --budget``).

The track's steps are walked again (:func:`pdr.phone.track.redo_steps`) with part of the truth put in, and scored like
the track itself:

* ``truth_heading``: each step between two consecutive landmarks on one floor at least ``min_leg_m`` apart takes
  the direction of the straight line between them (the walker is taken to walk straight from landmark to
  landmark); the other steps (turns at a landmark, short legs, stairs) keep the track's heading.
* ``truth_scale``: every step length divided by the track's distance ratio over the landmark intervals on one
  floor (:func:`pdr.evaluation.scoring.distance_ratio_same_floor`; between floors the truth has no path), so the walk's
  length on the flat is the true one.
* ``truth_heading_and_scale``: both.

What is left with both is what neither a better heading nor a better step-length scale for the walk would remove:
step length varying within the walk, steps detected where the walker stood or missed, the turns, and the truth's
own timing (a landmark is stamped when the walker presses a button, often in stride).

Measured on the 25 IPIN 2023 hand-held logs (``pdr eval ipin DIR --placement hand --budget``), landmark error
median / 75th percentile with absolute heading: smoothed track 1.97 / 3.13 m; with the true leg headings
1.75 / 2.84 m; scaled to the true length 1.65 / 2.84 m; both 1.80 / 2.61 m. The straight legs' length varies
about the walk's own scale by 9.5 % (standard deviation over the legs of at least 5 m), and no step pattern of
:mod:`pdr.phone.step_length` follows that variation much better than a constant step (7.9 % at best against 8.6 %,
measured ad hoc over the same legs).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.evaluation.scoring import distance_ratio, distance_ratio_same_floor, straight_legs
from pdr.frames import heading_deg_to_yaw
from pdr.phone.track import redo_steps

FloatArray = NDArray[np.float64]

#: Names of the re-walked tracks, in the order :func:`budget_tracks` returns them.
BUDGET_TRACKS: tuple[str, ...] = ("truth_heading", "truth_scale", "truth_heading_and_scale")


def leg_headings(t_steps: FloatArray, t_truth: FloatArray, en_truth: FloatArray, floors: FloatArray | None = None,
                 min_leg_m: float = 3.0) -> FloatArray:
    """Heading (deg clockwise from north) of the straight line between the landmarks each step's end time falls
    between, for steps on a leg of at least ``min_leg_m`` on one floor; NaN for the others.

    ``t_steps`` (K,) and ``t_truth`` (L,) in s on one clock, ``en_truth`` (L, 2) east/north in m, ``floors`` (L,).
    A step belongs to the leg ``(t_truth[i], t_truth[i + 1]]``.
    """
    t = np.asarray(t_steps, dtype=np.float64)
    out = np.full(t.size, np.nan)
    leg = np.searchsorted(np.asarray(t_truth, dtype=np.float64), t, side="left") - 1   # step in (tt[leg], tt[leg + 1]]
    for i, bearing, _ in straight_legs(en_truth, floors, min_leg_m):
        out[leg == i] = bearing
    return out


def budget_tracks(steps: list[dict[str, Any]], t_truth: FloatArray, en_truth: FloatArray,
                  floors: FloatArray | None = None, min_leg_m: float = 3.0) -> dict[str, list[dict[str, Any]]]:
    """The re-walked tracks of :data:`BUDGET_TRACKS` (module doc) of a track's step rows (``t_s``, ``east_m``,
    ``north_m``, ``heading_deg``, ``step_length_m``); an empty dict when the track has fewer than two steps.
    """
    if len(steps) < 2:
        return {}
    t = np.array([s["t_s"] for s in steps], dtype=np.float64)
    heading = np.array([s["heading_deg"] for s in steps], dtype=np.float64)
    truth = leg_headings(t, t_truth, en_truth, floors, min_leg_m)
    yaw_true = np.asarray(heading_deg_to_yaw(np.where(np.isfinite(truth), truth, heading)), dtype=np.float64)
    yaw_own = np.asarray(heading_deg_to_yaw(heading), dtype=np.float64)
    en = np.array([[s["east_m"], s["north_m"]] for s in steps], dtype=np.float64)
    tt, pos = np.asarray(t_truth, dtype=np.float64), np.asarray(en_truth, dtype=np.float64)
    ratio = (distance_ratio(t, en, tt, pos) if floors is None
             else distance_ratio_same_floor(t, en, tt, pos, np.asarray(floors, dtype=np.float64)))
    length = np.array([s["step_length_m"] for s in steps], dtype=np.float64)
    scaled = length / ratio if np.isfinite(ratio) and ratio > 0 else length
    by_heading = redo_steps(steps, yaw_true)
    return {"truth_heading": by_heading, "truth_scale": redo_steps(steps, yaw_own, scaled),
            "truth_heading_and_scale": redo_steps(steps, yaw_true, scaled)}
