"""Accuracy figures of a track against reference positions, as the datasets' scorers define them.

The conventions of ``../shared/data/README.md`` and its independent reference ``tools/score_tracks.py``:

* landmark error (IPIN): the track is interpolated at the landmark times, translated so it starts at the
  first landmark, and the error at every later landmark is reported; ``align="none"`` keeps the absolute
  heading, ``align="first-segment"`` also rotates the track about the first landmark so its displacement
  over the first landmark interval points along the true first segment;
* waypoint error (MS traces, map frame not north-aligned): start at the first waypoint and one rotation
  about it fitted in least squares to all waypoints;
* distance ratio: path length of the track between the first and last landmark times over the true path
  length through the landmarks; :func:`distance_ratio_same_floor` keeps only the landmark intervals on one
  floor (the straight line across a floor change is not the walked path);
* leg direction error (IPIN, :func:`leg_direction_errors`): the bearing of the track's displacement between two
  consecutive landmarks less the true bearing, leg by leg;
* step-count error: ``100 (detected - true) / true`` percent;
* floors right (IPIN multi-floor walks): the landmarks whose true floor is the track's floor at the landmark time,
  the floor in effect then (the start floor and the floor changes up to that time, :func:`floors_at`), not the floor
  of the next step, which after a stop (an elevator ride, waiting at a door) may be minutes later.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]


def _interp(track_t: FloatArray, track_en: FloatArray, t: FloatArray) -> FloatArray:
    if track_t.size < 2:
        raise InputError("track has fewer than two positions", source="scoring")
    return np.column_stack([np.interp(t, track_t, track_en[:, 0]), np.interp(t, track_t, track_en[:, 1])])


def start_offset(track_t: FloatArray, track_en: FloatArray, truth_t0: float, truth_en0: FloatArray) -> FloatArray:
    """(2,) translation (east, north, m) that moves the track to start at the first truth point, as the scorers do:
    the track interpolated at the first truth time ``truth_t0`` (s, the track's clock) lands on ``truth_en0``.
    Add it to every track position to draw the track as it is scored.
    """
    at = _interp(np.asarray(track_t, dtype=np.float64), np.asarray(track_en, dtype=np.float64)[:, :2],
                 np.array([float(truth_t0)]))[0]
    return np.asarray(np.asarray(truth_en0, dtype=np.float64)[:2] - at)


def landmark_errors(track_t: FloatArray, track_en: FloatArray, truth_t: FloatArray, truth_en: FloatArray,
                    align: str = "none") -> FloatArray:
    """Horizontal errors (m) at landmarks 2..K (see the module doc); ``align`` is ``none`` or ``first-segment``."""
    if align not in ("none", "first-segment"):
        raise InputError("align must be 'none' or 'first-segment'", field="align", source="scoring")
    gt = np.asarray(truth_en, dtype=np.float64)[:, :2]
    est = _interp(np.asarray(track_t), np.asarray(track_en)[:, :2], np.asarray(truth_t))
    est = est + start_offset(track_t, track_en, float(truth_t[0]), gt[0])
    if align == "first-segment" and gt.shape[0] > 1:
        d_est, d_gt = est[1] - est[0], gt[1] - gt[0]
        a = math.atan2(d_gt[1], d_gt[0]) - math.atan2(d_est[1], d_est[0])
        c, s = math.cos(a), math.sin(a)
        est = gt[0] + (est - est[0]) @ np.array([[c, s], [-s, c]])
    return np.asarray(np.linalg.norm(est[1:] - gt[1:], axis=1))


def straight_legs(truth_en: FloatArray, floors: FloatArray | None = None, min_leg_m: float = 3.0
                  ) -> list[tuple[int, float, float]]:
    """The legs of a landmark truth: ``(i, bearing_deg, length_m)`` for each pair of consecutive landmarks ``i``,
    ``i + 1`` (``truth_en`` (L, 2+) east/north, m) on one floor (``floors`` (L,), or None) at least ``min_leg_m``
    apart; the bearing of the straight line between them in (-180, 180] deg clockwise from north.
    """
    en = np.asarray(truth_en, dtype=np.float64)[:, :2]
    legs = []
    for i in range(en.shape[0] - 1):
        d = en[i + 1] - en[i]
        length = float(np.hypot(*d))
        if length >= min_leg_m and (floors is None or floors[i] == floors[i + 1]):
            legs.append((i, float(np.degrees(np.arctan2(d[0], d[1]))), length))
    return legs


def leg_direction_errors(track_t: FloatArray, track_en: FloatArray, truth_t: FloatArray, truth_en: FloatArray,
                         floors: FloatArray | None = None, min_leg_m: float = 3.0) -> list[dict[str, float]]:
    """Per leg of the landmark truth (:func:`straight_legs`): how far the track's direction over the leg is from the
    true one.

    Per leg: its start and end times ``t0_s``/``t1_s`` (the track's clock), length ``length_m``, the true bearing
    ``true_deg`` in [0, 360) (clockwise from north) of the straight line, and ``error_deg``: the bearing of the
    track's displacement between the two landmark times less the true one, in [-180, 180) (positive: the track
    walked clockwise of the truth). This is the heading part of the landmark error, leg by leg, free of the errors
    accumulated before the leg.
    """
    tt = np.asarray(truth_t, dtype=np.float64)
    est = _interp(np.asarray(track_t, dtype=np.float64), np.asarray(track_en, dtype=np.float64)[:, :2], tt)
    out: list[dict[str, float]] = []
    for i, bearing, length in straight_legs(truth_en, floors, min_leg_m):
        d_est = est[i + 1] - est[i]
        true_deg = bearing % 360.0
        est_deg = math.degrees(math.atan2(d_est[0], d_est[1]))
        out.append({"t0_s": float(tt[i]), "t1_s": float(tt[i + 1]), "length_m": length, "true_deg": true_deg,
                    "error_deg": (est_deg - true_deg + 180.0) % 360.0 - 180.0})
    return out


def waypoint_errors(track_t: FloatArray, track_xy: FloatArray, truth_t: FloatArray, truth_xy: FloatArray,
                    scale: bool = False) -> FloatArray:
    """Errors (m) at waypoints 2..K after starting at the first and one least-squares rotation about it.

    ``scale``: a least-squares rotation and scale (the track's points at the waypoint times times the complex
    factor ``sum(conj(z) w) / sum(|z|^2)``): what a constant heading offset and step-length scale, known with
    hindsight, leave of the error.
    """
    gt = np.asarray(truth_xy, dtype=np.float64)[:, :2]
    est = _interp(np.asarray(track_t), np.asarray(track_xy)[:, :2], np.asarray(truth_t))
    rel, g = est - est[0], gt - gt[0]
    im = float(np.sum(rel[:, 0] * g[:, 1] - rel[:, 1] * g[:, 0]))
    re = float(np.sum(rel[:, 0] * g[:, 0] + rel[:, 1] * g[:, 1]))
    a = math.atan2(im, re)
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    turned = rel @ r.T
    if scale:
        norm = float(np.sum(rel * rel))
        turned = turned * (math.hypot(re, im) / norm if norm > 0 else 1.0)
    est = gt[0] + turned
    return np.asarray(np.linalg.norm(est[1:] - gt[1:], axis=1))


def absolute_waypoint_errors(track_t: FloatArray, track_xy: FloatArray, truth_t: FloatArray, truth_xy: FloatArray
                             ) -> FloatArray:
    """Errors (m) at waypoints 2..K of a track that starts at the first waypoint (its time and position are
    prepended to the track), without any alignment.
    """
    gt = np.asarray(truth_xy, dtype=np.float64)[:, :2]
    t = np.r_[float(truth_t[0]), np.asarray(track_t, dtype=np.float64)]
    xy = np.vstack([gt[:1], np.asarray(track_xy, dtype=np.float64)[:, :2]])
    est = _interp(t, xy, np.asarray(truth_t, dtype=np.float64))
    return np.asarray(np.linalg.norm(est[1:] - gt[1:], axis=1))


def distance_ratio(track_t: FloatArray, track_en: FloatArray, truth_t: FloatArray, truth_en: FloatArray) -> float:
    """Track path length between the first and last landmark times over the true path length."""
    t = np.asarray(track_t)
    en = np.asarray(track_en)[:, :2]
    sel = (t >= truth_t[0]) & (t <= truth_t[-1])
    est = float(np.sum(np.linalg.norm(np.diff(en[sel], axis=0), axis=1)))
    true = float(np.sum(np.linalg.norm(np.diff(np.asarray(truth_en)[:, :2], axis=0), axis=1)))
    if true <= 0:
        raise InputError("true path has zero length", source="scoring")
    return est / true


def distance_ratio_same_floor(track_t: FloatArray, track_en: FloatArray, truth_t: FloatArray, truth_en: FloatArray,
                              truth_floor: FloatArray) -> float:
    """Distance ratio over the landmark intervals that start and end on the same floor.

    The true path between two landmarks is known only as the straight line between them; across a floor
    change that line is not the walked path (a flight of stairs winds: IPIN trial 52 descends two floors
    in a full turn whose ends are 3.5 m apart; its whole-route ratio is about 2 for that reason), so those
    intervals are left out. Trial 52's same-floor ratio (0.90-0.92 with the default step length) is then not a
    truth artefact: it is the SM-G930F walker's longer stride, as on trials 21 and 26. Within each interval the
    track is interpolated at both landmark times, so no partial step is lost at a landmark. NaN if no
    interval is left.
    """
    t = np.asarray(track_t)
    en = np.asarray(track_en)[:, :2]
    gt = np.asarray(truth_en, dtype=np.float64)[:, :2]
    tt = np.asarray(truth_t, dtype=np.float64)
    fl = np.asarray(truth_floor, dtype=np.float64)
    ends = _interp(t, en, tt)
    est = true = 0.0
    for k in range(tt.size - 1):
        if not fl[k] == fl[k + 1]:
            continue
        inside = (t > tt[k]) & (t < tt[k + 1])
        pts = np.vstack([ends[k:k + 1], en[inside], ends[k + 1:k + 2]])
        est += float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
        true += float(np.linalg.norm(gt[k + 1] - gt[k]))
    return est / true if true > 0 else math.nan


def floors_at(t: FloatArray, floor0: float, change_t: FloatArray, change_floor: FloatArray) -> FloatArray:
    """The floor in effect at times ``t`` (s): ``floor0`` until the first change, then the floor of the last change
    at or before each time (``change_t`` (K,) s, increasing; ``change_floor`` (K,) the floor after each change).
    """
    levels = np.concatenate([[float(floor0)], np.asarray(change_floor, dtype=np.float64)])
    return levels[np.searchsorted(np.asarray(change_t, dtype=np.float64), np.asarray(t, dtype=np.float64),
                                  side="right")]


def _bounce_free(edges: FloatArray, min_fraction: float) -> FloatArray:
    """One foot's rising-edge times (s) without bounces (:func:`bounce_free_step_count`)."""
    t = np.asarray(edges, dtype=np.float64)
    if t.size < 3:
        return t
    shortest = min_fraction * float(np.median(np.diff(t)))
    kept = [float(t[0])]
    for x in t[1:].tolist():
        if x - kept[-1] >= shortest:
            kept.append(x)
    return np.array(kept)


def bounce_free_step_count(edges_per_foot: list[FloatArray], min_fraction: float = 0.5) -> int:
    """Number of foot contacts after removing contact-switch bounces.

    A rising edge of one foot's switch that follows that foot's previous kept edge by less than
    ``min_fraction`` times the foot's median edge interval (about one stride, 1 s) is a bounce: a foot
    cannot strike twice within half a stride. The Oxford step-counter switches bounce 0.1-0.3 s after a
    contact on some walks (13-20 times on some armband and swinging-arm walks).

    Parameters
    ----------
    edges_per_foot
        Per foot, the sorted rising-edge times (s).
    min_fraction
        Shortest kept interval as a fraction of the foot's median interval.
    """
    return sum(int(_bounce_free(e, min_fraction).size) for e in edges_per_foot)


def alternating_contacts(left: FloatArray, right: FloatArray, min_fraction: float = 0.5) -> FloatArray:
    """Sorted foot-contact times (s) of a two-switch truth, without bounces and with one switch's drop-outs filled.

    The feet alternate: between two successive contacts of one foot the other foot lands once. When one foot's
    switch misses contacts (the Oxford step counter's drop-outs: one switch silent for one or two strides while the
    other goes on at the walk's rhythm, e.g. 15 times on Samsung_Dario_Hard_FrontPocket_1), ``k > 1`` contacts of
    the other foot between two of its kept contacts mean ``k - 1`` were missed; each is put midway between two
    successive contacts of the other foot. Bounces are removed first (:func:`bounce_free_step_count`); nothing is added
    before a foot's first or after its last contact, nor when both switches drop out together.

    Parameters
    ----------
    left, right
        Each foot's sorted rising-edge times (s).
    min_fraction
        Bounce limit, as in :func:`bounce_free_step_count`.
    """
    feet = [_bounce_free(left, min_fraction), _bounce_free(right, min_fraction)]
    fills: list[FloatArray] = []
    for own, other in ((feet[0], feet[1]), (feet[1], feet[0])):
        idx = np.searchsorted(other, own)           # the other foot's contacts before each of this foot's
        for a, b in zip(idx[:-1].tolist(), idx[1:].tolist(), strict=True):
            between = other[a:b]
            fills.append(0.5 * (between[:-1] + between[1:]))
    return np.sort(np.concatenate(feet + fills))


def alternating_step_count(left: FloatArray, right: FloatArray, min_fraction: float = 0.5) -> int:
    """Number of foot contacts of a two-switch truth, without bounces and with one switch's drop-outs filled
    (:func:`alternating_contacts`).
    """
    return int(alternating_contacts(left, right, min_fraction).size)


def match_steps(detected_s: FloatArray, true_s: FloatArray, tol_s: float) -> tuple[NDArray[np.bool_],
                                                                                   NDArray[np.bool_], float]:
    """One-to-one matching of detected step times with true step times.

    Each detected time (sorted), shifted by the median lag (s) from it to the nearest true step (a detected start is
    the acceleration's upward crossing, before the contact or the top of the vault), takes the nearest unmatched true
    step within ``tol_s`` (s), in time order. Returns which detected (sorted) and which true (sorted) times are
    matched, and the lag.
    """
    det = np.sort(np.asarray(detected_s, dtype=np.float64))
    true = np.sort(np.asarray(true_s, dtype=np.float64))
    hit = np.zeros(det.size, dtype=bool)
    used = np.zeros(true.size, dtype=bool)
    if det.size == 0 or true.size == 0:
        return hit, used, 0.0
    idx = np.searchsorted(true, det)
    after, before = true[np.clip(idx, 0, true.size - 1)], true[np.clip(idx - 1, 0, true.size - 1)]
    nearest = np.where(np.abs(after - det) < np.abs(before - det), after, before)
    lag = float(np.median(nearest - det))
    for i, x in enumerate((det + lag).tolist()):
        free = np.flatnonzero(~used & (np.abs(true - x) <= tol_s))
        if free.size:
            used[free[np.argmin(np.abs(true[free] - x))]] = True
            hit[i] = True
    return hit, used, lag


#: Part of a walk (s) at each end where :func:`unmatched_by_phase` counts apart: gait initiation and termination.
WALK_EDGE_S = 3.0
#: Largest distance (s) between a detected step start and the foot contact it matches in :func:`unmatched_by_phase`.
CONTACT_MATCH_S = 0.35


def unmatched_by_phase(detected_s: FloatArray, true_s: FloatArray, tol_s: float = CONTACT_MATCH_S,
                       edge_s: float = WALK_EDGE_S) -> dict[str, int]:
    """Where a step count's errors are: detected steps with no true step (``extra_*``) and true steps with none
    detected (``missed_*``) after one-to-one matching (:func:`match_steps`), in the walk's first ``edge_s`` (s,
    ``*_first``: gait initiation), its last ``edge_s`` (``*_last``: the stop) and between (``*_mid``). The walk spans
    the true steps; a detected step before it counts as first, after it as last. Times in s on one clock.
    """
    det = np.sort(np.asarray(detected_s, dtype=np.float64))
    true = np.sort(np.asarray(true_s, dtype=np.float64))
    hit, used, lag = match_steps(det, true, tol_s)
    out = {f"{k}_{p}": 0 for k in ("extra", "missed") for p in ("first", "mid", "last")}
    if true.size == 0:
        out["extra_mid"] = int(det.size)
        return out
    lo, hi = true[0] + edge_s, true[-1] - edge_s
    for kind, times in (("extra", det[~hit] + lag), ("missed", true[~used])):
        for x in times.tolist():
            out[f"{kind}_{'first' if x < lo else 'last' if x > hi else 'mid'}"] += 1
    return out


def step_count_error_pct(detected: int, true: int) -> float:
    """``100 (detected - true) / true``."""
    if true <= 0:
        raise InputError("true step count must be positive", source="scoring")
    return 100.0 * (detected - true) / true


def plain_step_count(t_s: FloatArray, acc_b: FloatArray, rate_hz: float = 50.0, cutoff_hz: float = 3.0,
                     min_step_s: float = 0.3) -> int:
    """Steps counted by a plain peak detector, the reference put beside the product's detector.

    ``|acc|`` is resampled to ``rate_hz`` (linear interpolation), low-passed without phase lag (2nd-order
    Butterworth at ``cutoff_hz``, forward and backward), and its peaks above mean + 0.5 standard deviations, at
    least ``min_step_s`` apart, are counted (``scipy.signal.find_peaks``). No walking-bout logic.

    Parameters
    ----------
    t_s
        (N,) sample times (s), increasing.
    acc_b
        (N, 3) specific force (m/s^2), any frame.
    """
    from scipy import signal

    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return 0
    grid = np.arange(t[0], t[-1], 1.0 / rate_hz)
    norm = np.interp(grid, t, np.linalg.norm(np.asarray(acc_b, dtype=np.float64), axis=1))
    b, a = signal.butter(2, cutoff_hz / (0.5 * rate_hz))
    if norm.size <= 3 * max(a.size, b.size):
        return 0
    x = signal.filtfilt(b, a, norm)
    peaks, _ = signal.find_peaks(x, height=float(x.mean() + 0.5 * x.std()), distance=max(1, int(min_step_s * rate_hz)))
    return int(peaks.size)
