"""Accuracy figures of foot navigation against the three kinds of truth of the foot datasets.

* :func:`pyshoe_armse`: PyShoe's 2-D "ARMSE" against dense VICON positions, computed as the reference does
  (translate both to start at the origin; rotate the estimate about the vertical so that, at the first sample
  where it lies 0.8 m from the start, it points the same way as the truth; average ``sqrt((ex^2 + ey^2) / 2)``).
* :func:`loop_closure_error`: final displacement of a closed walk, m and percent of the distance walked.
* :func:`stride_errors`: errors at per-stride footprints (ground-control points), after aligning the first
  stride segment.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.foot.strides import stance_onsets

Array = NDArray[np.float64]

#: Distance from the start (m) at which the heading of the estimate is aligned on the truth.
ALIGN_DISTANCE_M = 0.8
#: Fallback alignment sample when the estimate never leaves the 0.8 m circle (as the reference scorer).
ALIGN_FALLBACK_SAMPLE = 300

#: PyShoe VICON trials that the source repository's ``training_data_tag`` marks 0 (non-bipedal / crawling;
#: see ``pyshoe_vicon/SOURCE.md``), mapped to names through the upstream file order.
PYSHOE_EXCLUDED: frozenset[str] = frozenset({
    "2017-11-22-11-22-46", "2017-11-22-11-23-25", "2017-11-22-11-25-20", "2017-11-22-11-26-05",
    "2017-11-22-11-26-46", "2017-11-22-11-27-30", "2017-11-22-11-28-03", "2017-11-22-11-28-39",
    "2017-11-22-11-30-14", "2017-11-22-11-37-47", "2017-11-27-11-12-44", "2017-11-27-11-19-16",
    "2017-11-27-11-22-22", "2017-11-27-11-23-18", "2018-02-09-11-18-04", "2018-02-09-11-19-39",
    "2018-02-09-11-22-01", "2018-02-09-11-29-43", "2018-02-22-10-09-36", "2018-02-22-10-10-29",
    "2018-02-22-10-10-56"})


def _rot2(a: float) -> Array:
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def pyshoe_turn(est_en: ArrayLike, truth_en: ArrayLike) -> float:
    """Angle (rad, counter-clockwise) that turns an estimate about its start onto the truth as PyShoe's scorer does:
    at the first sample 0.8 m from the start (sample 300 when it never gets there) both point the same way.

    ``est_en`` and ``truth_en``: (N, 2) horizontal positions (m) at the same instants, each relative to its start.
    """
    est = np.asarray(est_en, dtype=np.float64)[:, :2]
    gt = np.asarray(truth_en, dtype=np.float64)[:, :2]
    d = np.linalg.norm(est, axis=1)
    k = int(np.argmax(d >= ALIGN_DISTANCE_M)) if d.max() >= ALIGN_DISTANCE_M else min(ALIGN_FALLBACK_SAMPLE,
                                                                                         len(d) - 1)
    return float(np.arctan2(gt[k, 1], gt[k, 0]) - np.arctan2(est[k, 1], est[k, 0]))


def pyshoe_armse(est_en: ArrayLike, truth_en: ArrayLike) -> float:
    """PyShoe ARMSE in m of an estimate against truth sampled at the same instants.

    Parameters
    ----------
    est_en
        (N, 2) estimated horizontal positions (east, north), m.
    truth_en
        (N, 2) true horizontal positions, m (any horizontal frame: the estimate is rotated onto it).

    Returns
    -------
    Mean over samples of ``sqrt((ex^2 + ey^2) / 2)``, m.
    """
    est = np.asarray(est_en, dtype=np.float64)[:, :2]
    gt = np.asarray(truth_en, dtype=np.float64)[:, :2]
    if est.shape != gt.shape or est.shape[0] < 2:
        raise InputError(f"estimate {est.shape} and truth {gt.shape} must have the same (N>=2, 2) shape",
                         field="positions")
    est = est - est[0]
    gt = gt - gt[0]
    est = est @ _rot2(pyshoe_turn(est, gt)).T
    return float(np.mean(np.sqrt(np.mean((est - gt) ** 2, axis=1))))


def path_length(pos: ArrayLike) -> float:
    """Horizontal length in m of a polyline (N, >=2)."""
    p = np.asarray(pos, dtype=np.float64)[:, :2]
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def stride_summary(t_s: ArrayLike, pos_n: ArrayLike, zero_velocity: ArrayLike) -> tuple[int, float, float]:
    """Strides (stance onsets after a swing, :func:`pdr.foot.strides.stance_onsets`), horizontal distance (m)
    through the start, each stance onset and the end, and duration (s) of a foot track (``t_s`` (N,) s, ``pos_n``
    (N, >=2) m).
    """
    t = np.asarray(t_s, dtype=np.float64)
    pos = np.asarray(pos_n, dtype=np.float64)
    onsets = stance_onsets(zero_velocity, t)
    through = pos[np.r_[0, onsets, pos.shape[0] - 1]] if pos.shape[0] else pos
    distance = path_length(through) if through.shape[0] >= 2 else 0.0
    return int(onsets.size), distance, float(t[-1] - t[0]) if t.size else 0.0


def loop_closure_error(pos: ArrayLike, distance_m: float | None = None) -> tuple[float, float]:
    """Horizontal distance (m) between the end and the start of a closed walk, and that in % of its length.

    ``distance_m`` defaults to the length of the estimated path.
    """
    p = np.asarray(pos, dtype=np.float64)
    err = float(np.linalg.norm(p[-1, :2] - p[0, :2]))
    dist = path_length(p) if distance_m is None else float(distance_m)
    return err, 100.0 * err / dist if dist > 0 else float("nan")


def stride_errors(est_en: ArrayLike, truth_en: ArrayLike) -> Array:
    """Horizontal errors (m) at stride ends after aligning the first stride segment.

    Both are translated to start at their first point; the estimate is rotated about the vertical so that its
    first stride that lies at least 0.5 m from the start points the same way as the truth's.

    Parameters
    ----------
    est_en, truth_en
        (K, 2) estimated and true stride-end positions, m.

    Returns
    -------
    (K,) errors in m.
    """
    est = np.asarray(est_en, dtype=np.float64)[:, :2]
    gt = np.asarray(truth_en, dtype=np.float64)[:, :2]
    if est.shape != gt.shape or est.shape[0] < 2:
        raise InputError(f"estimate {est.shape} and truth {gt.shape} must have the same (K>=2, 2) shape",
                         field="strides")
    est = est - est[0]
    gt = gt - gt[0]
    far = np.flatnonzero(np.linalg.norm(gt, axis=1) >= 0.5)
    k = int(far[0]) if far.size else len(gt) - 1
    a = np.arctan2(gt[k, 1], gt[k, 0]) - np.arctan2(est[k, 1], est[k, 0])
    est = est @ _rot2(float(a)).T
    return np.asarray(np.linalg.norm(est - gt, axis=1))
