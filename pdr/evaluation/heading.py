"""Walking heading and device attitude against motion capture (Tyrex benchmark, :mod:`pdr.io.tyrex`).

Per recording, the phone pipeline runs as ``pdr track`` runs it (:func:`pdr.cli.track.run_pipeline`, the same
configuration from the same options; placement automatic unless told), and is scored against the mocap truth:

Walking direction (per step)
    The true direction of a step is that of the walking path (``truth.extra['walk_pos_m']``, the phone's
    horizontal position averaged over one stride) between the step's start (``t_start_s``) and end (``t_s``);
    steps whose true displacement is shorter than :data:`MIN_STEP_M` or undefined (hidden markers, the ends of
    the recording) are not scored. The estimate is the step's ``heading_deg`` (the direction the track moves),
    of the causal track and of the offline-smoothed one (``pdr track``'s default,
    :func:`pdr.phone.heading_smoother.smooth_track`). Figures: mean and median absolute error, share within 10 and
    20 degrees, steps scored.
Attitude (per mocap frame)
    The attitude filter's ``q_nb`` on the pipeline's grid (captured from the pipeline's own filter while it runs)
    and the phone's rotation vector (``orientation`` stream), each at the grid or stream sample nearest to every
    valid mocap frame (within :data:`MAX_MATCH_S`), against the mocap ``q_nb``. Error rotation
    ``q_e = q_est q_true^-1`` (navigation frame): yaw error = its twist about the vertical, tilt error = the angle
    between the estimated and true up directions in the device frame. Mean and median over frames.
Disturbed stretches (attitude yaw split)
    The field at each mocap frame is the calibrated magnetometer sample nearest to it rotated into the world by the
    mocap attitude, its magnitude and dip (seed 003 eq. 13's quantities) smoothed by a running median over
    :data:`FIELD_SMOOTH_S` (the sampling and alignment jitter of a fast-turning phone). The local reference is the
    median of both over the frames of the same walker's recordings without deliberate disturbance (``NoDist``; the
    room's field; the recording's own frames if the walker has none). A frame is in a disturbed stretch where its
    field departs from the reference by more than :data:`DISTURBED_FIELD_UT` or :data:`DISTURBED_DIP_DEG`. The
    attitude yaw errors of ours and of the rotation vector are reported inside (``*_yaw_dist``) and outside
    (``*_yaw_clean``) these stretches (:func:`split_disturbed`).
Rotation vector as walking direction
    The step's mean horizontal direction of the device +y axis by the rotation vector: the walking direction of
    a phone held in reading position (texting). Scored like the steps above. The same axis by the motion capture's
    own attitude (``walk_mocap_y``: a perfect attitude) is the floor of any heading taken from the device's
    attitude against this truth: the truth is the phone's path, and a phone held ahead of the body runs a wider
    circle than the body in a turn, so its path leads the body's heading there (the offset-and-lag split below
    gives this axis a lag of 0.26-0.60 s on the texting walks, and the rotation vector 0.30-0.74 s).

    How much of the texting error that geometry is, measured: a phone ``d`` ahead of the walker's vertical axis
    moves at ``v h + d w h_perp`` (``h`` the body's heading, ``v`` the speed, ``w`` the turn rate), so its path
    leads ``h`` by ``atan(d w / v)``. Adding that lead to the hand-held step headings (``w`` the central difference
    of the steps' mean gyro yaw, available when a step is output since the next step is then known; ``d`` chosen on
    the tuning walker: causal 15.4 / 14.3 / 13.9 / 14.2 / 14.7 deg at 0.15 / 0.25 / 0.35 / 0.45 / 0.55 m) took the
    texting walks from 16.3 to 11.4 deg causal and 16.1 to 11.4 smoothed at 0.35 m (the other walker 14.9 -> 9.9;
    all recordings 12.4 -> 11.7 causal, 11.2 -> 10.6 smoothed). Not adopted: the track it integrates is the phone's
    path, ``d (h(t) - h(0))`` from the walker's, up to ``2 d`` after a U-turn, and the IPIN landmarks are where the
    walker stands: ``pdr eval ipin`` causal p75 3.54 -> 3.79 m, smoothed 2.96 -> 3.07, 19 of 27 walks worse causal
    (18 smoothed). The product tracks the walker; this benchmark's texting truth is the phone.

Frames: the mocap world is X east, Y magnetic north, Z up; the rotation vector is referenced to magnetic north
and the pipeline applies no declination unless configured (``attitude.mag_declination_deg``, 0 by default), so
all three are compared in that frame as they are. A declination configured in the pipeline is reported in the
output (``declination_deg``) and removed from the estimates before scoring.

With a perfect attitude (``--perfect-attitude``; error set ``walk_perfect``)
    The same pipeline run on the motion capture's own attitude in place of its attitude filter's (the phone
    attitude path, ``attitude_source="phone"``, fed the mocap rotation as the orientation stream:
    :func:`mocap_attitude_recording`), its causal steps scored like ours: what the walking-direction methods leave
    when the attitude is exact, against what ours leave with our attitude. Where the two are close, the attitude is
    not what limits the walking direction.

Gyro against the motion capture (per recording)
    The calibrated gyro stream's residual bias (deg/s, device frame): the median of the gyro, interpolated to the
    middle of each pair of consecutive valid mocap frames, less the motion capture's body rate between them
    (:func:`gyro_residual_bias`); and its component about the mean up direction of the device, the yaw drift an
    attitude filter carries until it learns the bias. Phone operating systems estimate and remove the gyro's bias;
    what they leave is learnt by our attitude filter at stands, or from the magnetometer in a steady field, so a walk
    with neither keeps it as a steady yaw error (about ``bias * tau`` with the magnetometer rows' time constant
    ``tau``).

Placement (per step)
    The placement the pipeline used for each step (detected online unless ``--placement`` names one) against the
    carriage: :data:`EXPECTED_PLACEMENT` (a trouser pocket front, back or running is ``pocket``, a swinging hand
    ``swinging``, texting ``hand``). Confusion matrix in steps, per carriage and per walker, and the share right
    (:func:`placement_confusion`).

Protocol: the recordings of Guillaume are the tuning half, Jakob's the confirmation half (per-walker
aggregates); aggregates over steps (walking direction) and frames (attitude) per carriage, per walker,
disturbed against clean, and over all.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import heading_deg_to_yaw, wrap_angle, yaw_to_heading_deg
from pdr.io.registry import read_recording
from pdr.phone.pipeline import PLACEMENT_GROUPS, PdrPipeline, PipelineConfig, track_rows
from pdr.phone.walking_direction import body_angular_rate
from pdr.recording import Recording, SensorStream

FloatArray = NDArray[np.float64]

#: Shortest true step displacement (m) whose direction is scored: below it the walker stands or turns on the spot.
MIN_STEP_M = 0.15
#: Largest time (s) between a mocap frame and the estimate sample compared with it.
MAX_MATCH_S = 0.05
#: Carriages in report order (the folder names' motion).
CARRIAGES = ("FrontPocket", "BackPocket", "Swinging", "Texting", "RunningPocket")
#: A frame's field departs from the reference by more than these to count as disturbed: magnitude (uT) and dip
#: (deg). 5 uT across the ~22 uT horizontal field of the room turns north by up to ~13 deg.
DISTURBED_FIELD_UT, DISTURBED_DIP_DEG = 5.0, 5.0
#: Running-median window (s) of the field's magnitude and dip at the mocap frames.
FIELD_SMOOTH_S = 1.0
#: The pipeline placement each carriage should be detected as.
EXPECTED_PLACEMENT = {"FrontPocket": "pocket", "BackPocket": "pocket", "RunningPocket": "pocket",
                      "Swinging": "swinging", "Texting": "hand"}
#: The tracks whose error :func:`offset_and_turn_lag` splits: (name, step-table column).
DECOMPOSED = (("causal", "heading_deg"), ("smoothed", "smoothed_heading_deg"), ("rv_y", "rv_y_heading_deg"),
              ("mocap_y", "mocap_y_heading_deg"))
#: Walker of each protocol half.
TUNING_WALKER, CONFIRMATION_WALKER = "Guillaume", "Jakob"


@dataclass
class ErrorSet:
    """Absolute errors (deg) of one quantity, pooled over steps or frames."""

    deg: FloatArray = field(default_factory=lambda: np.zeros(0))

    def add(self, other: ErrorSet) -> None:
        self.deg = np.concatenate([self.deg, other.deg])

    def summary(self) -> dict[str, float]:
        e = self.deg
        if e.size == 0:
            return {"n": 0, "mean_deg": math.nan, "median_deg": math.nan, "within_10_deg": math.nan,
                    "within_20_deg": math.nan}
        return {"n": int(e.size), "mean_deg": float(e.mean()), "median_deg": float(np.median(e)),
                "within_10_deg": float(np.mean(e <= 10.0)), "within_20_deg": float(np.mean(e <= 20.0))}


#: Error sets kept per recording: walking direction (causal, smoothed, rotation vector +y, motion capture +y, the
#: pipeline on a perfect attitude) and attitude.
ERROR_SETS = ("walk_causal", "walk_smoothed", "walk_rv_y", "walk_mocap_y", "walk_perfect", "att_yaw", "att_tilt",
              "rv_yaw", "rv_tilt", "att_yaw_dist", "att_yaw_clean", "rv_yaw_dist", "rv_yaw_clean")


@dataclass
class RecordingScore:
    """Figures of one recording; ``errors`` by :data:`ERROR_SETS` name."""

    name: str
    walker: str
    carriage: str
    disturbed: bool
    placement: str
    steps: int
    errors: dict[str, ErrorSet]
    notices: list[str]
    #: Per step (columns of equal length): ``t_start_s``, ``t_s`` (log clock, s), ``placement``, and the compass
    #: headings (deg, magnetic north) ``true_heading_deg``, ``heading_deg`` (causal), ``smoothed_heading_deg``,
    #: ``rv_y_heading_deg``, ``mocap_y_heading_deg``; NaN where undefined.
    step_table: dict[str, Any] = field(default_factory=dict)
    #: Azimuth (deg) of magnetic north from the mocap Y axis (:func:`pdr.io.tyrex.field_azimuth_deg`), if known.
    field_azimuth_deg: float | None = None
    #: Per mocap frame: the smoothed field magnitude (uT) and dip (deg) (:func:`frame_field`), and the attitude yaw
    #: errors (deg) of ours and of the rotation vector (:func:`frame_yaw_errors`); NaN where undefined.
    frames: dict[str, FloatArray] = field(default_factory=dict)
    #: The gyro's residual bias against the motion capture (deg/s, device frame) and its component about the mean up
    #: direction (:func:`gyro_residual_bias`); None without a gyro or valid frames.
    gyro_bias_dps: list[float] | None = None
    gyro_bias_up_dps: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"recording": self.name, "walker": self.walker, "carriage": self.carriage,
                "disturbed": self.disturbed, "placement": self.placement, "steps": self.steps,
                **{k: self.errors[k].summary() for k in ERROR_SETS},
                "offset_and_lag": {name: offset_and_turn_lag(self.step_table, col) for name, col in DECOMPOSED},
                "field_azimuth_mocap_deg": self.field_azimuth_deg, "gyro_bias_dps": self.gyro_bias_dps,
                "gyro_bias_up_dps": self.gyro_bias_up_dps, "notices": self.notices}


# -- truth ------------------------------------------------------------------------------------------------
def true_step_yaw(rec: Recording, t_start_s: FloatArray, t_end_s: FloatArray,
                  min_step_m: float = MIN_STEP_M) -> FloatArray:
    """ENU yaw (rad) of the walking path between each step's start and end times (log clock, s); NaN where the
    path is undefined at either end or the true displacement is shorter than ``min_step_m``.
    """
    ex = rec.truth.extra
    if "walk_pos_m" not in ex or "trajectory_t_s" not in ex:
        raise InputError("the recording has no walking-path truth (truth.extra['walk_pos_m'])",
                         source=rec.source or None)
    t = rec.origin_ns / 1e9 + np.asarray(ex["trajectory_t_s"], dtype=np.float64)
    walk = np.asarray(ex["walk_pos_m"], dtype=np.float64)

    def at(tq: FloatArray) -> FloatArray:
        # Linear interpolation that stays NaN next to a NaN frame (np.interp would bridge it).
        i = np.clip(np.searchsorted(t, tq) - 1, 0, t.size - 2)
        w = ((tq - t[i]) / (t[i + 1] - t[i]))[:, None]
        out = walk[i] * (1 - w) + walk[i + 1] * w
        out[(tq < t[0]) | (tq > t[-1])] = np.nan
        return out

    d = at(np.asarray(t_end_s, dtype=np.float64)) - at(np.asarray(t_start_s, dtype=np.float64))
    yaw = np.arctan2(d[:, 1], d[:, 0])
    yaw[~(np.hypot(d[:, 0], d[:, 1]) >= min_step_m)] = np.nan
    return yaw


def _step_times(rows: list[dict[str, Any]]) -> tuple[FloatArray, FloatArray]:
    """(N,) start and end times (log clock, s) of a track's steps."""
    return (np.array([r["t_start_s"] for r in rows], dtype=np.float64),
            np.array([r["t_s"] for r in rows], dtype=np.float64))


def track_yaw(rows: list[dict[str, Any]], declination_deg: float = 0.0) -> FloatArray:
    """(N,) ENU yaw (rad) of a track's steps, referenced to magnetic north (``declination_deg`` removed)."""
    return heading_deg_to_yaw(np.array([r["heading_deg"] for r in rows], dtype=np.float64) - declination_deg)


def abs_errors(est_yaw: FloatArray, true_yaw: FloatArray) -> ErrorSet:
    """Absolute angle errors (deg) where both yaws (rad) are defined."""
    e = np.degrees(np.abs(wrap_angle(est_yaw - true_yaw)))
    return ErrorSet(e[np.isfinite(e)])


def step_errors(rows: list[dict[str, Any]], rec: Recording, declination_deg: float = 0.0) -> ErrorSet:
    """Absolute walking-direction errors (deg) of a track's steps against the walking path."""
    if not rows:
        return ErrorSet()
    return abs_errors(track_yaw(rows, declination_deg), true_step_yaw(rec, *_step_times(rows)))


def attitude_errors(t_est_s: FloatArray, q_est: FloatArray, rec: Recording, declination_deg: float = 0.0,
                    max_match_s: float = MAX_MATCH_S) -> tuple[ErrorSet, ErrorSet]:
    """Yaw and tilt errors (deg) of attitude estimates ``q_est`` (N, 4) at log-clock times ``t_est_s`` (N,)
    against the mocap ``q_nb``, at every valid frame with an estimate within ``max_match_s``.
    """
    ex = rec.truth.extra
    if "q_nb" not in ex:
        raise InputError("the recording has no attitude truth (truth.extra['q_nb'])", source=rec.source or None)
    tt = rec.origin_ns / 1e9 + np.asarray(ex["trajectory_t_s"], dtype=np.float64)
    qt = np.asarray(ex["q_nb"], dtype=np.float64)
    ok_est = np.all(np.isfinite(q_est), axis=1)
    te, qe = np.asarray(t_est_s, dtype=np.float64)[ok_est], np.asarray(q_est, dtype=np.float64)[ok_est]
    if te.size == 0:
        return ErrorSet(), ErrorSet()
    j = np.clip(np.searchsorted(te, tt), 1, max(te.size - 1, 1))
    j = np.where(np.abs(te[j - 1] - tt) < np.abs(te[np.minimum(j, te.size - 1)] - tt), j - 1, j)
    j = np.minimum(j, te.size - 1)
    use = np.all(np.isfinite(qt), axis=1) & (np.abs(te[j] - tt) <= max_match_s)
    qe_m, qt_m = qe[j[use]], qt[use]
    if declination_deg:
        # Estimates referenced to true north: rotate them back to magnetic north (about up by +declination).
        half = math.radians(declination_deg) / 2
        qe_m = quat.multiply(np.array([math.cos(half), 0.0, 0.0, math.sin(half)]), qe_m)
    yaw, tilt = yaw_tilt_error(qe_m, qt_m)
    return ErrorSet(np.degrees(yaw)), ErrorSet(np.degrees(tilt))


def frame_yaw_errors(t_est_s: FloatArray, q_est: FloatArray, rec: Recording, declination_deg: float = 0.0,
                     max_match_s: float = MAX_MATCH_S) -> FloatArray:
    """(frames,) yaw errors (deg) of ``q_est`` at every mocap frame as :func:`attitude_errors` scores them; NaN at
    frames it does not score.
    """
    ex = rec.truth.extra
    tt = rec.origin_ns / 1e9 + np.asarray(ex["trajectory_t_s"], dtype=np.float64)
    out = np.full(tt.size, np.nan)
    ok_est = np.all(np.isfinite(q_est), axis=1)
    te, qe = np.asarray(t_est_s, dtype=np.float64)[ok_est], np.asarray(q_est, dtype=np.float64)[ok_est]
    if te.size == 0:
        return out
    qt = np.asarray(ex["q_nb"], dtype=np.float64)
    j = np.clip(np.searchsorted(te, tt), 1, max(te.size - 1, 1))
    j = np.where(np.abs(te[j - 1] - tt) < np.abs(te[np.minimum(j, te.size - 1)] - tt), j - 1, j)
    j = np.minimum(j, te.size - 1)
    use = np.all(np.isfinite(qt), axis=1) & (np.abs(te[j] - tt) <= max_match_s)
    qe_m = qe[j[use]]
    if declination_deg:
        half = math.radians(declination_deg) / 2
        qe_m = quat.multiply(np.array([math.cos(half), 0.0, 0.0, math.sin(half)]), qe_m)
    out[use] = np.degrees(yaw_tilt_error(qe_m, qt[use])[0])
    return out


def frame_field(rec: Recording, max_match_s: float = MAX_MATCH_S) -> tuple[FloatArray, FloatArray]:
    """(frames,) magnitude (uT) and dip (deg, down positive) of the measured field in the world at each mocap frame
    (nearest calibrated magnetometer sample rotated by the mocap attitude), each smoothed by a running median over
    :data:`FIELD_SMOOTH_S`; NaN where the field or the attitude is unknown.
    """
    ex = rec.truth.extra
    tt = rec.origin_ns / 1e9 + np.asarray(ex["trajectory_t_s"], dtype=np.float64)
    qt = np.asarray(ex["q_nb"], dtype=np.float64)
    mag, dip = np.full(tt.size, np.nan), np.full(tt.size, np.nan)
    if not rec.has("mag") or rec.t_s("mag").size < 2:
        return mag, dip
    tm = rec.origin_ns / 1e9 + rec.t_s("mag")
    j = np.clip(np.searchsorted(tm, tt), 1, tm.size - 1)
    j = np.where(np.abs(tm[j - 1] - tt) < np.abs(tm[j] - tt), j - 1, j)
    ok = np.all(np.isfinite(qt), axis=1) & (np.abs(tm[j] - tt) <= max_match_s)
    if not ok.any():
        return mag, dip
    h = quat.rotate(qt[ok], rec.values("mag")[j[ok]])
    rate = (tt.size - 1) / max(tt[-1] - tt[0], 1e-9)
    win = max(1, int(round(FIELD_SMOOTH_S * rate)) | 1)
    mag[ok] = median_filter(np.linalg.norm(h, axis=1), win, mode="nearest")
    dip[ok] = median_filter(np.degrees(np.arctan2(-h[:, 2], np.hypot(h[:, 0], h[:, 1]))), win, mode="nearest")
    return mag, dip


def split_disturbed(scores: list[RecordingScore]) -> None:
    """Fill each score's ``*_yaw_dist`` and ``*_yaw_clean`` error sets (module doc), in place: the reference field
    of a walker is the median over the frames of the walker's ``NoDist`` recordings.
    """
    refs: dict[str, tuple[float, float]] = {}
    for w in {s.walker for s in scores}:
        clean = [s for s in scores if s.walker == w and not s.disturbed and s.frames]
        if clean:
            refs[w] = (float(np.nanmedian(np.concatenate([s.frames["field_uT"] for s in clean]))),
                       float(np.nanmedian(np.concatenate([s.frames["dip_deg"] for s in clean]))))
    for s in scores:
        if not s.frames or not np.isfinite(s.frames["field_uT"]).any():
            for k in ("att_yaw_dist", "att_yaw_clean", "rv_yaw_dist", "rv_yaw_clean"):
                s.errors[k] = ErrorSet()
            continue
        f, d = s.frames["field_uT"], s.frames["dip_deg"]
        ref_f, ref_d = refs.get(s.walker, (float(np.nanmedian(f)), float(np.nanmedian(d))))
        known = np.isfinite(f)
        dist = known & ((np.abs(f - ref_f) > DISTURBED_FIELD_UT) | (np.abs(d - ref_d) > DISTURBED_DIP_DEG))
        clean_frames = known & ~dist
        for who in ("att", "rv"):
            e = s.frames[f"{who}_yaw_deg"]
            s.errors[f"{who}_yaw_dist"] = ErrorSet(e[dist & np.isfinite(e)])
            s.errors[f"{who}_yaw_clean"] = ErrorSet(e[clean_frames & np.isfinite(e)])


def yaw_tilt_error(q_est: FloatArray, q_true: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(N,) yaw and tilt errors (rad, >= 0) between attitudes ``q_nb`` (N, 4).

    Yaw: the twist about the navigation up axis of ``q_est q_true^-1``. Tilt: the angle between the up direction
    each attitude puts in the device frame. Both are free of the gimbal lock of Euler angles (a phone upright
    in a pocket).
    """
    qe = quat.multiply(q_est, quat.conjugate(q_true))
    yaw = np.abs(wrap_angle(2.0 * np.arctan2(qe[:, 3], qe[:, 0])))
    up = np.array([0.0, 0.0, 1.0])
    ue = quat.rotate(quat.conjugate(q_est), np.broadcast_to(up, (q_est.shape[0], 3)))
    ut = quat.rotate(quat.conjugate(q_true), np.broadcast_to(up, (q_true.shape[0], 3)))
    tilt = np.arctan2(np.linalg.norm(np.cross(ue, ut), axis=1), np.sum(ue * ut, axis=1))
    return yaw, tilt


def device_y_yaw(rows: list[dict[str, Any]], rec: Recording) -> FloatArray:
    """(N,) ENU yaw (rad) of the rotation vector's device +y axis, its mean horizontal direction over each step of
    ``rows`` (NaN without an orientation sample in the step): the phone's own heading of a phone held in reading
    position.
    """
    t0, t1 = _step_times(rows)
    if not rows or not rec.has("orientation"):
        return np.full(t0.size, np.nan)
    return mean_y_yaw(rec.origin_ns / 1e9 + rec.t_s("orientation"), rec.values("orientation"), t0, t1)


def mocap_y_yaw(rows: list[dict[str, Any]], rec: Recording) -> FloatArray:
    """(N,) ENU yaw (rad) of the device +y axis by the motion capture's own attitude over each step of ``rows``: the
    heading of a phone in reading position with a perfect attitude, the floor of any method that takes the walking
    direction from the device's heading against this benchmark's truth (the phone's own path).
    """
    t0, t1 = _step_times(rows)
    if not rows or "q_nb" not in rec.truth.extra:
        return np.full(t0.size, np.nan)
    t, q = mocap_attitude(rec)
    return mean_y_yaw(rec.origin_ns / 1e9 + t, q, t0, t1)


def mocap_attitude(rec: Recording) -> tuple[FloatArray, FloatArray]:
    """The motion capture's frame times (s, relative to ``rec.origin_ns``) and attitudes ``q_nb`` (M, 4; ENU with
    magnetic north, device frame) at the frames where it is defined.
    """
    ex = rec.truth.extra
    q = np.asarray(ex["q_nb"], dtype=np.float64)
    ok = np.all(np.isfinite(q), axis=1)
    return np.asarray(ex["trajectory_t_s"], dtype=np.float64)[ok], q[ok]


def gyro_residual_bias(rec: Recording) -> tuple[FloatArray, float] | None:
    """The ``gyro`` stream's residual bias (deg/s, (3,), device frame) against the motion capture, and its component
    (deg/s) about the device's mean up direction (module doc); None without a gyro or two consecutive valid frames.
    """
    if not rec.has("gyro") or rec.t_s("gyro").size < 2:
        return None
    t, q = mocap_attitude(rec)
    if t.size < 3:
        return None
    dt = np.diff(t)
    rate = 1.0 / float(np.median(dt))
    consecutive = np.abs(dt * rate - 1.0) < 0.5            # frames one period apart (none hidden between)
    w_mocap = body_angular_rate(q, rate)
    tg = rec.t_s("gyro")
    mid = 0.5 * (t[1:] + t[:-1])
    inside = consecutive & (mid >= tg[0]) & (mid <= tg[-1])
    if not inside.any():
        return None
    g = rec.values("gyro")
    w_gyro = np.column_stack([np.interp(mid[inside], tg, g[:, i]) for i in range(3)])
    bias = np.median(w_gyro - w_mocap[inside], axis=0)
    up = quat.rotate(quat.conjugate(q), np.tile([0.0, 0.0, 1.0], (q.shape[0], 1))).mean(axis=0)
    up /= max(float(np.linalg.norm(up)), 1e-12)
    return np.degrees(bias), math.degrees(float(bias @ up))


def mean_y_yaw(t_s: FloatArray, q_nb: FloatArray, t_start_s: FloatArray, t_end_s: FloatArray) -> FloatArray:
    """(N,) ENU yaw (rad) of the mean horizontal direction of the device +y axis of attitudes ``q_nb`` (M, 4) at
    times ``t_s`` (M,) over each interval ``[t_start_s, t_end_s)`` (s); NaN for an interval without a sample.
    """
    y_n = quat.rotate(q_nb, np.broadcast_to([0.0, 1.0, 0.0], (t_s.size, 3)))[:, :2]
    unit = y_n / np.maximum(np.linalg.norm(y_n, axis=1), 1e-9)[:, None]
    c = np.concatenate([np.zeros((1, 2)), np.cumsum(unit, axis=0)])
    a, b = np.searchsorted(t_s, t_start_s), np.searchsorted(t_s, t_end_s)
    sums = c[b] - c[a]
    return np.where(b > a, np.arctan2(sums[:, 1], sums[:, 0]), np.nan)


#: Errors larger than this (deg) are left out of :func:`offset_and_turn_lag`'s fit: a reversed direction is no
#: Mean walking-direction error (deg) over which a recording is listed after the ALL line: the motion-capture
#: benchmark's bar for a recording (no recording over 15 deg, the walking-heading issue's target).
WORST_RECORDING_DEG = 15.0
#: offset or lag.
FIT_MAX_ERROR_DEG = 60.0
#: Largest time (s) between a step's two neighbours for the true turn rate at the step (longer: a pause).
TURN_RATE_MAX_SPAN_S = 3.0


def offset_and_turn_lag(table: dict[str, Any], column: str) -> dict[str, float]:
    """How much of a track's walking-direction error is a constant offset and how much a time lag through turns.

    ``table`` is a :attr:`RecordingScore.step_table`; ``column`` the estimate (``heading_deg`` or
    ``smoothed_heading_deg``). The true turn rate at a step ``w_k`` (deg/s, clockwise positive) is the change of the
    true direction between its two neighbours over their mid-times (not where they are more than
    :data:`TURN_RATE_MAX_SPAN_S` apart). The error ``e_k`` (estimate less truth, deg) is fitted by least squares as
    ``offset - lag * w_k``: an estimate that trails the path through turns by ``lag`` seconds (positive) and is
    turned by ``offset`` (clockwise positive) from it. Errors over :data:`FIT_MAX_ERROR_DEG` are left out
    (``excluded``). Returns ``n`` (steps fitted), ``offset_deg``, ``lag_s``, ``mean_abs_deg`` (their mean absolute
    error) and ``residual_mean_abs_deg`` (what is left once offset and lag are removed): where these two differ the
    error is the walker's, the carriage's or the filter's timing, not noise.
    """
    nan = {"n": 0, "excluded": 0, "offset_deg": math.nan, "lag_s": math.nan, "mean_abs_deg": math.nan,
           "residual_mean_abs_deg": math.nan}
    if not table or column not in table:
        return nan
    t = 0.5 * (np.asarray(table["t_start_s"], dtype=np.float64) + np.asarray(table["t_s"], dtype=np.float64))
    true = np.asarray(table["true_heading_deg"], dtype=np.float64)
    est = np.asarray(table[column], dtype=np.float64)
    w = np.full(t.size, np.nan)
    if t.size >= 3:
        span = t[2:] - t[:-2]
        turn = (true[2:] - true[:-2] + 180.0) % 360.0 - 180.0
        w[1:-1] = np.where(span <= TURN_RATE_MAX_SPAN_S, turn / np.maximum(span, 1e-9), np.nan)
    e = (est - true + 180.0) % 360.0 - 180.0
    ok = np.isfinite(w) & np.isfinite(e)
    fit = ok & (np.abs(e) <= FIT_MAX_ERROR_DEG)
    if fit.sum() < 3:
        return nan | {"n": int(fit.sum()), "excluded": int((ok & ~fit).sum())}
    a = np.column_stack([np.ones(int(fit.sum())), w[fit]])
    coef, *_ = np.linalg.lstsq(a, e[fit], rcond=None)
    return {"n": int(fit.sum()), "excluded": int((ok & ~fit).sum()), "offset_deg": float(coef[0]),
            "lag_s": float(-coef[1]), "mean_abs_deg": float(np.mean(np.abs(e[fit]))),
            "residual_mean_abs_deg": float(np.mean(np.abs(e[fit] - a @ coef)))}


# -- running the product ------------------------------------------------------------------------------------
def run_with_attitude(rec: Recording, cfg: PipelineConfig
                      ) -> tuple[list[dict[str, Any]], list[str], FloatArray, FloatArray]:
    """Causal track rows, notices, and the attitude filter's grid times (log clock, s) and ``q_nb`` (N, 4).

    The pipeline runs unchanged; its attitude filter's ``run`` and its sample history's ``append`` are wrapped on
    the instance to record what they compute (the grid samples in order).
    """
    pipe = PdrPipeline(cfg)
    times: list[FloatArray] = []
    qs: list[FloatArray] = []
    att_run, hist_append = pipe.attitude.run, pipe.history.append

    def recording_run(*args: Any, **kwargs: Any) -> Any:
        out = att_run(*args, **kwargs)
        qs.append(np.array(out[0], dtype=np.float64))
        return out

    def recording_append(start: int, t: FloatArray, *args: Any) -> None:
        times.append(np.array(t, dtype=np.float64))
        hist_append(start, t, *args)

    pipe.attitude.run = recording_run  # type: ignore[method-assign]
    pipe.history.append = recording_append  # type: ignore[method-assign,assignment]
    events = pipe.run(rec)
    notices = [str(e["message"]) for e in events if e.get("type") == "notice"]
    t = np.concatenate(times) if times else np.zeros(0)
    q = np.concatenate(qs) if qs else np.zeros((0, 4))
    if t.size != q.shape[0]:
        notices.append(f"attitude capture failed ({t.size} grid samples, {q.shape[0]} attitudes): not scored")
        t, q = np.zeros(0), np.zeros((0, 4))
    return track_rows(events), notices, t, q


def placement_for(rec: Recording, placement: str) -> str:
    """Pipeline placement for ``--placement``: ``auto``/``pocket``/``hand``/``torso``/``swinging`` as given,
    ``label``: the recording's carriage label (``meta['placement_label']``; a hand swinging at the walker's side,
    carriage ``Swinging``, is the pipeline's ``swinging``).
    """
    if placement != "label":
        return placement
    if rec.meta.get("carriage") == "Swinging":
        return "swinging"
    label = rec.meta.get("placement_label")
    group = PLACEMENT_GROUPS.get(str(label)) if label else None
    if group is None:
        raise InputError(f"no placement label for this recording (carriage {rec.meta.get('carriage')!r})",
                         source=rec.source or None, field="placement")
    return group


def mocap_attitude_recording(rec: Recording) -> Recording:
    """A copy of ``rec`` whose ``orientation`` stream is the motion capture's attitude ``q_nb`` at its frames (where
    defined): the phone attitude path of the pipeline then runs on a perfect attitude.
    """
    t, q = mocap_attitude(rec)
    t_ns = rec.origin_ns + np.round(t * 1e9).astype(np.int64)
    return rec.with_streams({"orientation": SensorStream("orientation", t_ns, q)})


def perfect_attitude_errors(rec: Recording, cfg: PipelineConfig) -> ErrorSet:
    """Causal walking-direction errors (deg) of the pipeline on the motion capture's attitude (module doc)."""
    rows = track_rows(PdrPipeline(replace(cfg, attitude_source="phone", use_phone_orientation=False))
                      .run(mocap_attitude_recording(rec)))
    if not rows:
        return ErrorSet()
    decl = float(cfg.attitude.mag_declination_deg)
    return abs_errors(track_yaw(rows, decl), true_step_yaw(rec, *_step_times(rows)))


def score_recording(rec: Recording, cfg: PipelineConfig,
                    smooth: Callable[[list[dict[str, Any]], list[str]], list[dict[str, Any]]],
                    perfect_attitude: bool = False) -> RecordingScore:
    """Every figure of one recording (module doc); ``smooth`` makes the offline-smoothed track (the same steps);
    ``perfect_attitude``: also the pipeline on the motion capture's attitude (``walk_perfect``).
    """
    decl = float(cfg.attitude.mag_declination_deg)
    rows, notices, t_att, q_att = run_with_attitude(rec, cfg)
    smoothed = smooth(rows, notices)
    t0, t1 = _step_times(rows)
    truth = true_step_yaw(rec, t0, t1)
    causal, smooth_yaw, rv_y = track_yaw(rows, decl), track_yaw(smoothed, decl), device_y_yaw(rows, rec)
    mocap_y = mocap_y_yaw(rows, rec)
    errors = {"walk_causal": abs_errors(causal, truth), "walk_smoothed": abs_errors(smooth_yaw, truth),
              "walk_rv_y": abs_errors(rv_y, truth), "walk_mocap_y": abs_errors(mocap_y, truth),
              "walk_perfect": perfect_attitude_errors(rec, cfg) if perfect_attitude else ErrorSet()}
    errors["att_yaw"], errors["att_tilt"] = attitude_errors(t_att, q_att, rec, decl)
    field_ut, dip_deg = frame_field(rec)
    frames = {"field_uT": field_ut, "dip_deg": dip_deg, "att_yaw_deg": frame_yaw_errors(t_att, q_att, rec, decl),
              "rv_yaw_deg": np.full(field_ut.size, np.nan)}
    if rec.has("orientation"):
        t_rv, q_rv = rec.origin_ns / 1e9 + rec.t_s("orientation"), rec.values("orientation")
        errors["rv_yaw"], errors["rv_tilt"] = attitude_errors(t_rv, q_rv, rec)
        frames["rv_yaw_deg"] = frame_yaw_errors(t_rv, q_rv, rec)
    else:
        errors["rv_yaw"], errors["rv_tilt"] = ErrorSet(), ErrorSet()
    for k in ("att_yaw_dist", "att_yaw_clean", "rv_yaw_dist", "rv_yaw_clean"):
        errors[k] = ErrorSet()                  # filled by split_disturbed over all the recordings
    placements = Counter(str(r.get("placement")) for r in rows)
    used = placements.most_common(1)[0][0] if placements else str(cfg.placement)
    table = {"t_start_s": t0, "t_s": t1, "placement": [str(r.get("placement")) for r in rows],
             "true_heading_deg": yaw_to_heading_deg(truth), "heading_deg": yaw_to_heading_deg(causal),
             "smoothed_heading_deg": yaw_to_heading_deg(smooth_yaw), "rv_y_heading_deg": yaw_to_heading_deg(rv_y),
             "mocap_y_heading_deg": yaw_to_heading_deg(mocap_y)}
    m = rec.meta
    gyro = gyro_residual_bias(rec)
    return RecordingScore(name=Path(rec.source).name.removesuffix(".zip"), walker=str(m.get("walker", "")),
                          carriage=str(m.get("carriage", "")), disturbed=bool(m.get("disturbed", False)),
                          placement=used, steps=len(rows), errors=errors, notices=notices, step_table=table,
                          field_azimuth_deg=m.get("field_azimuth_mocap_deg"), frames=frames,
                          gyro_bias_dps=None if gyro is None else gyro[0].tolist(),
                          gyro_bias_up_dps=None if gyro is None else gyro[1])


def recordings_in(root: str | Path) -> list[Path]:
    """Recordings under ``root``: Tyrex logger folders (a dataset root, its ``android`` folder, or one recording),
    and native recordings (zip or folder, :mod:`pdr.io.native`) converted from them, which keep the truth and the
    ``meta`` (walker, carriage, field) the evaluation needs.
    """
    from pdr.io import native, tyrex

    p = Path(root)
    if not p.exists():
        raise InputError("no such file or folder", source=str(p))
    if tyrex.sniff(p) or native.sniff(p):
        return [p]
    found = {f.parent for f in p.rglob("record.properties") if tyrex.sniff(f.parent)}
    found |= {f for f in p.rglob("*.zip") if native.sniff(f)}
    found |= {f.parent for f in p.rglob("meta.json") if native.sniff(f.parent)}
    if not found:
        raise InputError("no Tyrex logger recording (folder with record.properties and accelerometer.txt) or native "
                         "recording here", source=str(p))
    return sorted(found)


def aggregate(scores: Iterable[RecordingScore]) -> dict[str, Any]:
    """Pooled figures of several recordings (each :data:`ERROR_SETS` entry) and how many recordings."""
    pooled = {k: ErrorSet() for k in ERROR_SETS}
    n = 0
    for s in scores:
        n += 1
        for k in ERROR_SETS:
            pooled[k].add(s.errors[k])
    return {"recordings": n, **{k: pooled[k].summary() for k in ERROR_SETS}}


def _half(walker: str) -> str:
    return "tuning" if walker == TUNING_WALKER else "confirmation" if walker == CONFIRMATION_WALKER else "other"


def protocol(scores: list[RecordingScore]) -> dict[str, Any]:
    """Aggregates: per carriage (and field), per walker (tuning / confirmation half; and carriage), disturbed
    against clean, and all.
    """
    carriages = [c for c in CARRIAGES if any(s.carriage == c for s in scores)]
    carriages += sorted({s.carriage for s in scores} - set(carriages))
    return {
        "by_carriage": {c: aggregate(s for s in scores if s.carriage == c) for c in carriages},
        "by_carriage_and_field": {f"{c} {'Dist' if d else 'NoDist'}": aggregate(
            s for s in scores if s.carriage == c and s.disturbed == d)
            for c in carriages for d in (False, True) if any(s.carriage == c and s.disturbed == d for s in scores)},
        "by_walker": {w: {"half": _half(w), **aggregate(s for s in scores if s.walker == w)}
                      for w in sorted({s.walker for s in scores})},
        "by_walker_and_carriage": {f"{w} {c}": {"half": _half(w), **aggregate(
            s for s in scores if s.walker == w and s.carriage == c)}
            for w in sorted({s.walker for s in scores}) for c in carriages
            if any(s.walker == w and s.carriage == c for s in scores)},
        "by_field": {"NoDist": aggregate(s for s in scores if not s.disturbed),
                     "Dist": aggregate(s for s in scores if s.disturbed)},
        "all": aggregate(scores),
        "placement_confusion": placement_confusion(scores),
    }


def placement_confusion(scores: list[RecordingScore]) -> dict[str, Any]:
    """Steps per (carriage, placement used) over all recordings and per walker, and per walker the share of steps
    whose placement is the carriage's :data:`EXPECTED_PLACEMENT`.
    """
    def matrix(sel: list[RecordingScore]) -> dict[str, dict[str, int]]:
        m: dict[str, Counter[str]] = {}
        for s in sel:
            m.setdefault(s.carriage, Counter()).update(str(p) for p in s.step_table.get("placement", []))
        return {c: dict(sorted(n.items())) for c, n in m.items()}

    def right(sel: list[RecordingScore]) -> float:
        n = ok = 0
        for s in sel:
            want = EXPECTED_PLACEMENT.get(s.carriage)
            used = [str(p) for p in s.step_table.get("placement", [])]
            n += len(used) if want else 0
            ok += sum(p == want for p in used) if want else 0
        return ok / n if n else math.nan

    walkers = sorted({s.walker for s in scores})
    return {"all": {"matrix": matrix(scores), "right": right(scores)},
            **{w: {"half": _half(w), "matrix": matrix([s for s in scores if s.walker == w]),
                   "right": right([s for s in scores if s.walker == w])} for w in walkers}}


# -- text report --------------------------------------------------------------------------------------------
def _f(x: float, fmt: str = "5.1f") -> str:
    return "n/a".rjust(int(fmt.split(".")[0])) if not np.isfinite(x) else format(x, fmt)


def _walk(s: dict[str, Any]) -> str:
    return (f"{_f(s['mean_deg'])} {_f(s['median_deg'])} {_f(100 * s['within_10_deg'], '4.0f')}% "
            f"{_f(100 * s['within_20_deg'], '4.0f')}%")


def _line(label: str, d: dict[str, Any], steps: str, texting: bool) -> str:
    rv_y = _walk(d["walk_rv_y"]) if texting else "            -            "
    return (f"{label:<48} {steps:>9} | {_walk(d['walk_causal'])} | {_walk(d['walk_smoothed'])} | "
            f"{_f(d['att_yaw']['mean_deg'])} {_f(d['att_tilt']['mean_deg'])} | "
            f"{_f(d['rv_yaw']['mean_deg'])} {_f(d['rv_tilt']['mean_deg'])} | {rv_y}")


HEADER = (f"{'':<48} {'steps':>9} | {'causal walking direction':<25} | {'smoothed walking direction':<25} | "
          f"{'attitude':<11} | {'rot. vector':<11} | rot. vector +y (texting)\n"
          f"{'':<48} {'':>9} | {'mean   med  <=10  <=20':<25} | {'mean   med  <=10  <=20':<25} | "
          f"{'yaw  tilt':<11} | {'yaw  tilt':<11} | mean   med  <=10  <=20")


def report_lines(scores: list[RecordingScore], agg: dict[str, Any]) -> list[str]:
    """The text table: one line per recording, then the aggregates (degrees; shares in %)."""
    out = ["per recording (placement: what the pipeline used)", HEADER]
    figures = {s.name: s.to_dict() for s in scores}     # each computes its offset-and-lag fits
    for s in scores:
        d = figures[s.name]
        label = f"{s.name} [{s.placement}]"
        out.append(_line(label, d, f"{d['walk_causal']['n']}/{s.steps}", s.carriage == "Texting"))
    for title, key in (("per carriage", "by_carriage"), ("per carriage and field", "by_carriage_and_field")):
        out += ["", title, HEADER]
        for name, d in agg[key].items():
            out.append(_line(f"{name} ({d['recordings']} rec.)", d, str(d["walk_causal"]["n"]),
                             name.startswith("Texting")))
    out += ["", "per walker (Guillaume: tuning half, Jakob: confirmation half)", HEADER]
    for name, d in agg["by_walker"].items():
        out.append(_line(f"{name} ({d['half']}, {d['recordings']} rec.)", d, str(d["walk_causal"]["n"]), False))
    for name, d in agg["by_walker_and_carriage"].items():
        out.append(_line(f"{name} ({d['recordings']} rec.)", d, str(d["walk_causal"]["n"]), name.endswith("Texting")))
    out += ["", "disturbed against clean field", HEADER]
    for name, d in agg["by_field"].items():
        out.append(_line(f"{name} ({d['recordings']} rec.)", d, str(d["walk_causal"]["n"]), False))
    out += ["", "placement used (steps) per carriage: rows carriage, columns placement"]
    conf = agg["placement_confusion"]
    cols = sorted({p for m in conf["all"]["matrix"].values() for p in m})
    expected = ", ".join(f"{c} -> {p}" for c, p in EXPECTED_PLACEMENT.items())
    for name, d in conf.items():
        out.append(f"  {name}{'' if name == 'all' else ' (' + d['half'] + ')'}: "
                   f"{100 * d['right']:.1f} % of steps as expected ({expected})")
        out.append(f"    {'':<14}" + "".join(f"{c:>10}" for c in cols))
        for c, m in d["matrix"].items():
            out.append(f"    {c:<14}" + "".join(f"{m.get(p, 0):>10d}" for p in cols))
    out += ["", HEADER, _line(f"ALL ({agg['all']['recordings']} rec.)", agg["all"], str(agg["all"]["walk_causal"]["n"]),
                              False)]
    for column, what in (("walk_causal", "causal"), ("walk_smoothed", "smoothed")):
        worse = [f"{s.name} {figures[s.name][column]['mean_deg']:.1f}" for s in scores
                 if figures[s.name][column]["mean_deg"] > WORST_RECORDING_DEG]
        out.append(f"recordings whose {what} walking direction is off by more than {WORST_RECORDING_DEG:g} deg on "
                   f"average: {len(worse)} of {len(scores)}" + (f" ({', '.join(worse)})" if worse else ""))
    out += ["", f"walking-direction error split into a constant offset (deg, clockwise) and a lag through turns (s): "
            f"least squares on the true turn rate, errors over {FIT_MAX_ERROR_DEG:g} deg left out "
            f"(mean |error| of the fitted steps -> what is left without offset and lag); for texting also the "
            f"rotation vector's +y: the lag it shares is the truth's, the path of a phone held ahead of the body, "
            f"which leads the body's heading through a turn", DECOMPOSITION_HEADER]
    out += [_decomposition_line(s.name, figures[s.name]["offset_and_lag"], s.carriage == "Texting") for s in scores]
    if agg["all"]["walk_perfect"]["n"]:
        out += ["", "the same pipeline on the motion capture's own attitude (a perfect attitude) against ours: what "
                "the walking-direction methods leave when the attitude is exact (causal; mean, median, <=10, <=20 deg)",
                f"{'':<48} | {'ours':<25} | perfect attitude"]
        groups = [(s.name, figures[s.name]) for s in scores]
        groups += [(f"{name} ({d['recordings']} rec.)", d) for key in ("by_carriage", "by_walker")
                   for name, d in agg[key].items()]
        groups.append((f"ALL ({agg['all']['recordings']} rec.)", agg["all"]))
        out += [f"{label:<48} | {_walk(d['walk_causal'])} | {_walk(d['walk_perfect'])}" for label, d in groups]
    out += ["", "texting: the device +y axis by the motion capture's own attitude (a perfect attitude) against this "
            "truth, the floor of a heading taken from the phone's attitude (mean, median, <=10, <=20 deg)",
            f"{'':<48} | {'ours (causal)':<25} | {'rot. vector +y':<25} | motion-capture +y"]
    texting = [(s.name, figures[s.name]) for s in scores if s.carriage == "Texting"]
    texting += [(f"{name} ({d['recordings']} rec.)", d) for name, d in agg["by_walker_and_carriage"].items()
                if name.endswith("Texting")]
    texting += [(f"{name} ({d['recordings']} rec.)", d) for name, d in agg["by_carriage"].items()
                if name == "Texting"]
    out += [f"{label:<48} | {_walk(d['walk_causal'])} | {_walk(d['walk_rv_y'])} | {_walk(d['walk_mocap_y'])}"
            for label, d in texting]
    out += ["", "attitude yaw (mean, deg) inside and outside disturbed stretches (field off the walker's NoDist "
            f"median by > {DISTURBED_FIELD_UT:g} uT or > {DISTURBED_DIP_DEG:g} deg dip)", DIST_HEADER]
    out += [_dist_line(s.name, figures[s.name]) for s in scores]
    out += [_dist_line(f"{name} ({d['recordings']} rec.)", d) for name, d in agg["by_field"].items()]
    out += [_dist_line(f"{name} ({d['recordings']} rec.)", d) for name, d in agg["by_walker"].items()]
    out.append(_dist_line(f"ALL ({agg['all']['recordings']} rec.)", agg["all"]))
    out += ["", "the gyro stream's residual bias against the motion capture (deg/s; the OS removes its own estimate): "
            "device x, y, z and about the mean up direction, the yaw drift an attitude filter carries until it learns "
            "it; beside it our attitude's yaw error (mean, deg)",
            f"{'':<48} | {'x      y      z':<21} | {'up':>6} | attitude yaw"]
    out += [_gyro_line(s, figures[s.name]) for s in scores]
    return out


def _gyro_line(s: RecordingScore, d: dict[str, Any]) -> str:
    if s.gyro_bias_dps is None or s.gyro_bias_up_dps is None:
        return f"{s.name:<48} | {'-':<21} | {'-':>6} | {_f(d['att_yaw']['mean_deg'])}"
    b = " ".join(f"{v:+.3f}" for v in s.gyro_bias_dps)
    return f"{s.name:<48} | {b:<21} | {s.gyro_bias_up_dps:+.3f} | {_f(d['att_yaw']['mean_deg'])}"


DECOMPOSITION_HEADER = (f"{'':<48} | {'causal':<38} | {'smoothed':<38} | rot. vector +y (texting)\n"
                        f"{'':<48} | {'offset   lag  |error| -> left (out)':<38} | "
                        f"{'offset   lag  |error| -> left (out)':<38} | offset   lag  |error| -> left (out)")


def _decomposition_line(label: str, d: dict[str, dict[str, float]], texting: bool) -> str:
    def part(m: dict[str, float]) -> str:
        return (f"{_f(m['offset_deg'], '+6.1f')} {_f(m['lag_s'], '+5.2f')}  {_f(m['mean_abs_deg'])} -> "
                f"{_f(m['residual_mean_abs_deg'])} ({m['excluded']:>3d})")
    rv = d.get("rv_y", {})
    return (f"{label:<48} | {part(d['causal']):<38} | {part(d['smoothed']):<38} | "
            + (part(rv) if texting and rv.get("n") else "-"))


DIST_HEADER = (f"{'':<48} | {'disturbed frames':<25} | clean frames\n"
               f"{'':<48} | {'share   ours  rot.vector':<25} | ours  rot.vector")


def _dist_line(label: str, d: dict[str, Any]) -> str:
    nd, nc = d["att_yaw_dist"]["n"], d["att_yaw_clean"]["n"]
    share = 100.0 * nd / (nd + nc) if nd + nc else math.nan
    return (f"{label:<48} | {_f(share, '4.0f')}% {_f(d['att_yaw_dist']['mean_deg'])} {_f(d['rv_yaw_dist']['mean_deg'])}"
            f"       | {_f(d['att_yaw_clean']['mean_deg'])} {_f(d['rv_yaw_clean']['mean_deg'])}")


def evaluate(root: str | Path, cfg_for: Callable[[Recording], PipelineConfig],
             smooth: Callable[[list[dict[str, Any]], list[str]], list[dict[str, Any]]],
             limit: int = 0, progress: Callable[[str], None] | None = None, perfect_attitude: bool = False
             ) -> tuple[list[RecordingScore], dict[str, Any]]:
    """Score every recording under ``root`` (``limit`` > 0: the first ``limit``); per-recording scores and
    :func:`protocol` aggregates. ``cfg_for`` gives each recording's pipeline configuration; ``perfect_attitude``:
    also the pipeline on the motion capture's attitude (module doc).
    """
    folders = recordings_in(root)
    if limit:
        folders = folders[:limit]
    scores = []
    for f in folders:
        rec = read_recording(f)
        if not {"walk_pos_m", "trajectory_t_s", "q_nb"} <= set(rec.truth.extra):
            if progress:
                progress(f"{f.name}: no motion-capture truth (walking path and attitude), skipped")
            continue
        scores.append(score_recording(rec, cfg_for(rec), smooth, perfect_attitude))
        if progress:
            progress(f"{f.name}: done")
    split_disturbed(scores)
    return scores, protocol(scores)
