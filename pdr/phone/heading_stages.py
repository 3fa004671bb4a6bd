"""The heading stages of the phone pipeline: the per-step heading policy, one class per stage, composed by
:class:`pdr.phone.pipeline.PdrPipeline` (the estimators themselves are in :mod:`pdr.phone.heading`).

- :class:`DeviceHeading`: hand-held and torso, the device heading plus an offset (seed 004 eq. 21);
- :class:`PocketHeading`: trouser pocket and swinging hand, the walking axis of the stride (swing plane or
  improved RMPCA), carried from step to step by the device's rotation (the prior turn), the 180-degree vote, and
  the second UKF (seed 003 eq. 41);
- :class:`StairsLandmarkHeading`: a site's flight of stairs, matched at its first step (position fix), whose heading
  updates the attitude (first UKF row, eqs. 20, 32) and the step heading (second UKF, eq. 42) at every step of it;
- :class:`StepTurn`: the change of the walking direction since the previous step (the step length's turn factor);
- :class:`DriftElimination`: heuristic drift elimination of hand-held and torso headings.

Each stage has ``state()`` and ``from_state()`` (:mod:`pdr.phone.stage`); the keys of their states are those the
pipeline's saved state has always had, so states saved before the stages existed resume.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.filters.numpy_reductions import all_finite
from pdr.filters.ukf import SigmaPoints
from pdr.frames import wrap_angle_float
from pdr.phone.attitude import AttitudeConfig, AttitudeState
from pdr.phone.events import LandmarkEvent
from pdr.phone.heading import (
    DirectionVote,
    HeadingEstimate,
    OffsetEstimator,
    StepDriftElimination,
    fuse_landmark,
    improved_rmpca_ut,
    landmark_attitude_update,
    mean_yaw,
    pca_axis,
    scatter_in_frame,
    scatter_of,
    thigh_swing_evidence,
    yaw_variance,
)
from pdr.phone.landmarks import Site
from pdr.phone.stage import PendingStep, StepHeading, StepWindow
from pdr.phone.track import TrackState
from pdr.phone.walking_direction import (
    TURN_SPEED_MPS,
    DeviceFrameDirection,
    DeviceSwingAxis,
    PocketSide,
    WalkingLineFilter,
    axis_variance,
    step_frequency_axis,
    step_lead,
    swing_plane_axis,
    turn_evidence,
    yaw_rate,
)

FloatArray = NDArray[np.float64]

#: Placements whose walking direction is the device heading (plus an offset).
DEVICE_HEADING_PLACEMENTS = ("hand", "torso")
#: Placements whose walking direction comes from the stride's motion (swing plane or RMPCA, 180-degree vote).
STRIDE_HEADING_PLACEMENTS = ("pocket", "swinging")
#: Weight of the centripetal turn evidence (taken at walking to running speeds,
#: :data:`pdr.phone.walking_direction.TURN_SPEED_MPS`) in the pocket's vote beside the thigh-swing skewness
#: (pdr.phone.walking_direction module doc, "Trouser pocket: continuity").
POCKET_TURN_WEIGHT = 0.1
#: Shortest median stride (s) of a walking bout, whose step-frequency axis the pocket's walking-line filter takes:
#: a cadence of 2 steps/s. Faster bouts may be running, where the stance leg no longer vaults the body and the
#: axis does not follow the walking direction (pdr.phone.walking_direction module doc).
WALKING_MIN_STRIDE_S = 1.0
#: Strides whose median duration decides the gait (walking or running), and the relative departure from it of a
#: stride that still spans one gait cycle.
GAIT_STRIDES = 5
STRIDE_TOLERANCE = 0.25
#: Longest walk (s) away from the swinging placement after which a swinging hand's swing axis and its
#: forward/backward evidence are kept: a few strides read as another carriage and then as the swinging hand again
#: are the placement detector misreading irregular strides (a sharp turn, a stumble), not a new grip, which
#: :class:`pdr.phone.walking_direction.DeviceSwingAxis` would see by its axis moving (``regrip_deg``) anyway. Five
#: seconds is a few strides; a phone put in a pocket and taken out again takes longer.
SWING_GRIP_MEMORY_S = 5.0


def ut_points(config: AttitudeConfig) -> SigmaPoints:
    """Sigma points of the unscented transforms on ``q(t1)`` (eqs. 35-37), with the attitude UKF's parameters."""
    return SigmaPoints(4, alpha=config.alpha, beta=config.beta, kappa=config.kappa)


class DeviceHeading:
    """Hand-held and torso: the yaw of the device's forward axis averaged over the step (seed 004 eq. 21; the y axis
    of a hand-held phone, the z axis of one on the torso) plus an offset (``zero``, or ``pca``: the running offset of
    the RMPCA axis, :class:`pdr.phone.heading.OffsetEstimator`); variance from the attitude covariance plus the
    process noise ``process_var`` (rad^2) of eq. 41.

    What limits it: the yaw of ``y`` moves with the phone's roll in the screen plane when ``y`` is steep. On IPIN
    trial 03 the phone is held nearly upright (``y`` about 62 deg above the horizontal); it rolls by about 12 deg over
    the walk, which turns the gyro-only yaw of ``y`` against the walking direction by -0.17 and -0.12 deg/s (the two
    repetitions). The offline smoother fits that trend, with the route's magnetic deflection, as a residual gyro
    bias, and the smoothed track of both repetitions is worse than the causal one (``pdr eval ipin``: 3.26 ->
    8.97 m and 4.47 -> 8.21 m p75). The roll-free forward direction ``u x x`` (perpendicular to the screen's width
    axis ``x`` and to up) keeps the leg errors within a few degrees there. Taken for both this heading and the
    smoother's gyro yaw, it lowered the rms of the walks' leg errors (6.10 -> 5.99 deg) but moved most walks' mean
    heading by about +4 deg, and the smoothed p75 went 3.36 -> 3.51 m (repetition-01 walks), 2.43 -> 2.58 m
    (repetition-02), 2.96 -> 3.04 m (all 27). Not adopted; it would need the drift elimination retuned with it.
    """

    def __init__(self, heading_offset: str, process_var: float, offset: OffsetEstimator | None = None) -> None:
        self.heading_offset = heading_offset
        self.process_var = process_var
        self.offset = offset or OffsetEstimator()

    def estimate(self, win: StepWindow, placement: str, with_scatter: bool) -> StepHeading:
        """The step's heading; ``with_scatter``: also the scatter matrix (a site's landmark may use it)."""
        h = win.history
        sl = h.sl(win.s, win.e)
        dev = mean_yaw(h.yaw_z[sl] if placement == "torso" else h.yaw_y[sl])   # seed 004 eq. 21
        if self.heading_offset == "pca":
            off = self.offset.update(win.axis, dev)
        else:
            off = 0.0
        psi0 = wrap_angle_float(dev + off)
        m1 = scatter_of(win.f_n, win.att_q) if with_scatter else np.zeros((3, 3))
        var = yaw_variance(win.att_q, win.att_p) + self.process_var
        return StepHeading(HeadingEstimate(psi0, var), psi0, win.axis, m1)

    def state(self) -> dict[str, Any]:
        return {"offset": self.offset.state()}

    @classmethod
    def from_state(cls, d: dict[str, Any], heading_offset: str, process_var: float) -> DeviceHeading:
        return cls(heading_offset, process_var, OffsetEstimator.from_state(d["offset"]))


def direction_vote(placement: str | None) -> DirectionVote:
    """The trouser pocket's forward/backward vote (the swinging hand decides its sign in
    :class:`pdr.phone.walking_direction.DeviceSwingAxis`).
    """
    return DirectionVote()


class PocketHeading:
    """Trouser pocket and swinging hand: the walking line of the stride, its direction and the second UKF.

    A pocket phone moves with one thigh, whose stance and swing halves of the gait cycle differ: the walking axis and
    the 180-degree rule use the stride made of this step and the one before it (a step's length before it after a
    pause). In a pocket the axis is the swing plane's (:func:`pdr.phone.walking_direction.swing_plane_axis`) or seed
    003's RMPCA of the stride (``pocket_axis``: ``swing``, ``rmpca``, or ``auto``: RMPCA when the site has landmarks);
    the direction along it is carried from stride to stride in the device frame
    (:class:`pdr.phone.walking_direction.DeviceFrameDirection`) and reversed when the vote
    (:class:`pdr.phone.heading.DirectionVote`) refutes it: the thigh's fast swing
    (:func:`pdr.phone.heading.thigh_swing_evidence`) plus, at a small weight, the centripetal acceleration in steady
    turns (:func:`pdr.phone.walking_direction.turn_evidence`). A swinging hand's direction is the arm's swing axis,
    fixed in the device frame while the grip holds, its sign decided by the turns
    (:class:`pdr.phone.walking_direction.DeviceSwingAxis`): no per-stride continuity or vote. The RMPCA heading passes
    the second UKF (:func:`pdr.phone.heading.improved_rmpca_ut`, eq. 41).
    """

    def __init__(self, rate_hz: float, pocket_axis: str, process_var: float, attitude: AttitudeConfig,
                 site_has_landmarks: bool, placement: str | None) -> None:
        self.rate_hz = rate_hz
        self.pocket_axis = pocket_axis
        self.process_var = process_var
        self.attitude = attitude
        self.site_has_landmarks = site_has_landmarks
        self.prev_yaw: float | None = None
        self.prev_step_start: int | None = None
        self.direction_vote = direction_vote(placement)
        self.swing_axis = DeviceSwingAxis()              # swinging hand's walking direction
        self.swing_end_s: float | None = None           # end (s, log clock) of the last swinging stride
        self.swing_paused = False                       # another placement since that stride
        self.pocket_direction = DeviceFrameDirection()   # pocket's forward/backward continuity
        self.pocket_line = WalkingLineFilter()           # pocket's walking line from stride to stride
        self.stride_s: list[float] = []                  # durations (s) of the last strides (the gait)
        self.pocket_side = PocketSide()                  # front or back of the thigh: the turn lead

    def _walking_gait(self, stride_s: float) -> tuple[bool, bool]:
        """Whether the walker walks (not runs), and whether this stride spans one gait cycle.

        The gait is the bout's, not one stride's (a runner's odd slow stride in a turn is still running): the
        median of the last :data:`GAIT_STRIDES` strides' durations (s), this one's ``stride_s`` included, at least
        :data:`WALKING_MIN_STRIDE_S`. A harmonic of the stride frequency needs a window of one stride: this
        stride's duration within :data:`STRIDE_TOLERANCE` of that median (not a step detected twice or missed).
        """
        self.stride_s = (self.stride_s + [round(stride_s, 6)])[-GAIT_STRIDES:]
        median = float(np.median(self.stride_s))
        return median >= WALKING_MIN_STRIDE_S, abs(stride_s - median) <= STRIDE_TOLERANCE * median

    def reset(self, placement: str | None) -> None:
        """Forget the walking direction's continuity and vote (the placement changed). The swinging hand's swing
        axis is kept through a short spell of another placement (:data:`SWING_GRIP_MEMORY_S`), and dropped when the
        hand swings again after a longer one (:meth:`estimate`).
        """
        self.prev_yaw = self.prev_step_start = None
        self.direction_vote = direction_vote(placement)
        self.swing_paused = self.swing_paused or placement != "swinging"
        self.pocket_direction = DeviceFrameDirection()
        self.pocket_line = WalkingLineFilter()
        self.pocket_side = PocketSide()

    def swing_tracker(self, end_s: float) -> DeviceSwingAxis:
        """The swinging hand's swing-axis tracker for a stride ending at ``end_s`` (s, log clock): the one in use,
        unless the hand last swung more than :data:`SWING_GRIP_MEMORY_S` before, with another placement since (a
        new grip: a fresh tracker). A stop while the hand swings keeps it: the grip stays.
        """
        if self.swing_paused and self.swing_end_s is not None and end_s - self.swing_end_s > SWING_GRIP_MEMORY_S:
            self.swing_axis = DeviceSwingAxis()
        self.swing_end_s, self.swing_paused = end_s, False
        return self.swing_axis

    def estimate(self, win: StepWindow, placement: str) -> StepHeading:
        h, s, e = win.history, win.s, win.e
        q, f_n = win.q, win.f_n
        ps = self.prev_step_start
        s0 = ps if ps is not None and 0 < s - ps <= 2 * (e - s) else s - (e - s)
        self.prev_step_start = s
        stride = h.sl(s0, e)
        q_str, f_str = h.q[stride], h.f_n[stride]
        whole_stride = all_finite(q_str) and all_finite(f_str)
        if not whole_stride:
            q_str, f_str = q, f_n
        walking, one_cycle = self._walking_gait(q_str.shape[0] / self.rate_hz)
        harmonics = walking and one_cycle and whole_stride      # the step-frequency axis is valid
        swing_axis = self.pocket_axis == "swing" or (self.pocket_axis == "auto" and not self.site_has_landmarks)
        reversed_direction = False
        side: float | None = None
        if placement == "swinging":
            # The arm's swing axis, fixed in the device frame while the grip holds, with its sign decided by the
            # turns (pdr.phone.walking_direction.DeviceSwingAxis): no per-stride continuity or vote.
            tracker = self.swing_tracker(float(h.t[h.sl(e - 1, e)][0]))
            axis = tracker.update(q_str, f_str, self.rate_hz, q_str.shape[0] - q.shape[0])
            psi0 = axis
        else:
            if swing_axis:
                # The swing plane's axis of the thigh (pdr.phone.walking_direction), not the device yaw.
                axis, ratio = swing_plane_axis(q_str, self.rate_hz)
                # The step-frequency axis of a walking stride (not running: module doc of
                # pdr.phone.walking_direction) learns the swing plane's offset.
                step_axis = step_frequency_axis(f_str)[0] if harmonics else None
                # Carried from stride to stride by the walker's turn (pdr.phone.walking_direction module doc).
                axis = self.pocket_line.update(axis, h.q, h.start, s0, s, e, self.rate_hz, step_axis, walking,
                                               axis_variance(ratio, q_str.shape[0]))
            else:
                axis, _ratio = pca_axis(f_str[:, :2])             # RMPCA over the stride
            # Continuity in the device frame, and the 180-degree rule from the thigh's fast swing (pdr.phone.heading
            # module doc) and the centripetal acceleration in turns (pdr.phone.walking_direction module doc,
            # "Trouser pocket: continuity").
            psi0 = self.pocket_direction.resolve(axis, q_str)
            turn = turn_evidence(f_str, yaw_rate(q_str, self.rate_hz), psi0, speed_range_mps=TURN_SPEED_MPS)
            reversed_direction = self.direction_vote.update(thigh_swing_evidence(q_str, self.rate_hz, psi0)
                                                            + POCKET_TURN_WEIGHT * turn)
            if reversed_direction:
                psi0 = wrap_angle_float(psi0 + math.pi)
                self.pocket_direction.reverse()
            if swing_axis and walking and whole_stride:
                # In front of the thigh the swing plane trails the path through turns; behind it, it does not
                # (pdr.phone.walking_direction module doc, "Trouser pocket: front or back").
                self.pocket_side.update(f_str, psi0)
                side = self.pocket_side.mean_corr()
                psi0 = wrap_angle_float(psi0 + self.pocket_side.lead_weight()
                                        * step_lead(q_str, self.rate_hz, q_str.shape[0] - q.shape[0]))
        m1 = scatter_of(f_str, win.att_q)
        if swing_axis or placement == "swinging":
            est = HeadingEstimate(psi0, yaw_variance(win.att_q, win.att_p) + self.process_var)
        else:
            est = improved_rmpca_ut(win.att_q, win.att_p, m1, psi0, self.process_var, ut_points(self.attitude))
        if placement == "pocket":
            self.pocket_direction.update(est.yaw, q_str)
        self.prev_yaw = est.yaw
        return StepHeading(est, psi0, axis, m1, reversed_direction, side)

    def corrected(self, step_yaw: float, corrected_yaw: float) -> None:
        """A landmark corrected the output step's heading from ``step_yaw`` to ``corrected_yaw`` (rad). The step
        after it is already resolved (one-step output delay): it keeps its own heading, moved by the correction
        (replacing it by this step's would make every other step resolve against a heading two steps old).
        """
        if self.prev_yaw is not None:
            self.prev_yaw = wrap_angle_float(self.prev_yaw + (corrected_yaw - step_yaw))

    def state(self) -> dict[str, Any]:
        return {"prev_yaw": self.prev_yaw, "prev_step_start": self.prev_step_start,
                "direction_score": self.direction_vote.score, "direction_votes": self.direction_vote.n,
                "swing_axis": self.swing_axis.state(), "swing_end_s": self.swing_end_s,
                "swing_paused": self.swing_paused,
                "pocket_direction": self.pocket_direction.state(),
                "pocket_line": self.pocket_line.state(), "stride_s": list(self.stride_s),
                "pocket_side": self.pocket_side.state()}

    @classmethod
    def from_state(cls, d: dict[str, Any], rate_hz: float, pocket_axis: str, process_var: float,
                   attitude: AttitudeConfig, site_has_landmarks: bool, placement: str | None) -> PocketHeading:
        o = cls(rate_hz, pocket_axis, process_var, attitude, site_has_landmarks, placement)
        o.prev_yaw = d["prev_yaw"]     # (states before the device-frame continuity also hold an unused prev_q)
        o.prev_step_start = None if d["prev_step_start"] is None else int(d["prev_step_start"])
        o.direction_vote.score = float(d["direction_score"])
        o.direction_vote.n = int(d["direction_votes"])
        if d.get("swing_axis") is not None:         # absent in states saved before the device-frame swing axis
            o.swing_axis = DeviceSwingAxis.from_state(d["swing_axis"])
        swing_end_s = d.get("swing_end_s")          # absent in states saved before the grip memory
        o.swing_end_s = None if swing_end_s is None else float(swing_end_s)
        o.swing_paused = bool(d.get("swing_paused", False))
        if d.get("pocket_direction") is not None:   # absent in states saved before the device-frame continuity
            o.pocket_direction = DeviceFrameDirection.from_state(d["pocket_direction"])
        if d.get("pocket_line") is not None:        # absent in states saved before the walking-line filter
            o.pocket_line = WalkingLineFilter.from_state(d["pocket_line"])
        o.stride_s = [float(v) for v in d.get("stride_s", [])]   # absent in states saved before the gait
        if d.get("pocket_side") is not None:        # absent in states saved before the pocket's side
            o.pocket_side = PocketSide.from_state(d["pocket_side"])
        return o


class StairsLandmarkHeading:
    """A site's flight of stairs as a landmark (seed 003 Sec. 5: a landmark is available while the decision tree
    labels the steps stairs). The flight is matched at its first step, which also fixes the position; every step of
    the flight observes the landmark's heading: the first UKF's landmark row on the attitude (eqs. 20, 32; trouser
    pocket, within 45 degrees of the RMPCA direction) and the second UKF's (eq. 42) on the step heading.
    """

    def __init__(self, site: Site | None, attitude: AttitudeConfig) -> None:
        self.site = site
        self.attitude = attitude
        self.stairs_landmark: str | None = None
        self.updates = 0
        self.attitude_updates = 0

    def correct(self, rec: PendingStep, mode: str, prev_mode: str, est: HeadingEstimate, track: TrackState,
                att: AttitudeState, placement: str | None) -> tuple[HeadingEstimate, LandmarkEvent | None, bool]:
        """The step's heading after the landmark (if any), the landmark event when the flight is entered (the track
        is then fixed at the landmark), and whether a landmark corrected the heading.
        """
        on_stairs = mode in ("stairs_up", "stairs_down")
        if self.site is None or not on_stairs:
            self.stairs_landmark = None
            return est, None, False
        entering = prev_mode not in ("stairs_up", "stairs_down")
        if entering:
            lm = self.site.match(mode, track.east_m, track.north_m, rec.floor)
            self.stairs_landmark = None if lm is None else lm.id
        else:
            lm = self.site.by_id(self.stairs_landmark) if self.stairs_landmark is not None else None
        if lm is None:
            return est, None, False
        yaw_lm, var_lm = lm.yaw_and_var()
        d_uh = wrap_angle_float(yaw_lm - rec.psi0)
        attitude_updated = False
        if abs(d_uh) < math.pi / 4 and placement == "pocket":
            # First UKF landmark row (eqs. 20, 32) on the current attitude. The step's scatter matrix
            # was expressed in the device frame of the attitude q1 the filter had when the step was
            # processed; the filter has moved on by one step since (output delay), so the samples are
            # carried into the current device frame (eqs. 14-16 with t1 = now) before f(q) is evaluated.
            m_now = scatter_in_frame(np.array(rec.m1), np.array(rec.q1), att.q)
            att.q[:], att.P[:, :] = landmark_attitude_update(att.q, att.P, m_now, rec.psi0, d_uh, var_lm,
                                                             ut_points(self.attitude))
            attitude_updated = True
        est = fuse_landmark(est, yaw_lm, var_lm)                 # second UKF (eq. 42)
        event = None
        if entering:
            track.fix(lm.east_m, lm.north_m, 1.0)
            event = LandmarkEvent(rec.t_start, lm.id, mode)
        self.updates += 1
        self.attitude_updates += int(attitude_updated)
        return est, event, True

    def state(self) -> dict[str, Any]:
        return {"stairs_landmark": self.stairs_landmark, "landmark_updates": self.updates,
                "landmark_attitude_updates": self.attitude_updates}

    @classmethod
    def from_state(cls, d: dict[str, Any], site: Site | None, attitude: AttitudeConfig) -> StairsLandmarkHeading:
        o = cls(site, attitude)
        # Absent in states saved before per-step stairs landmarks.
        o.stairs_landmark = d.get("stairs_landmark")
        o.updates = int(d.get("landmark_updates", 0))
        o.attitude_updates = int(d.get("landmark_attitude_updates", 0))
        return o


class StepTurn:
    """The walking direction's change since the previous step of the same walk (rad; the step length's turn factor,
    :func:`pdr.phone.step_length.turn_factor`). Hand and torso only: there the step heading follows the device's
    smooth yaw; a pocket phone's per-step heading jitters with the thigh (MobiFall walks: 90th percentile 9-66 deg
    per step), which is no turn. Not on stairs, and zero after a gap longer than ``max_gap_s``.
    """

    def __init__(self, max_gap_s: float) -> None:
        self.max_gap_s = max_gap_s
        self.last_step: tuple[float, float] | None = None   # (raw yaw rad, end time s) of the last emitted step

    def turn(self, rec: PendingStep, on_stairs: bool, placement: str | None) -> float:
        last = self.last_step
        turn = (abs(wrap_angle_float(rec.yaw - last[0]))
                if last is not None and rec.t_start - last[1] < self.max_gap_s and not on_stairs
                and placement in DEVICE_HEADING_PLACEMENTS else 0.0)
        self.last_step = (float(rec.yaw), float(rec.t_end))
        return turn

    def state(self) -> dict[str, Any]:
        return {"last_step": None if self.last_step is None else list(self.last_step)}

    @classmethod
    def from_state(cls, d: dict[str, Any], max_gap_s: float) -> StepTurn:
        o = cls(max_gap_s)
        last = d.get("last_step")             # absent in states saved before the turn factor
        o.last_step = None if last is None else (float(last[0]), float(last[1]))
        return o


class DriftElimination:
    """Heuristic drift elimination of hand-held and torso step headings towards the walk's dominant directions (or
    the site's grid), :class:`pdr.phone.heading.StepDriftElimination`; other placements pass unchanged.
    """

    def __init__(self, enabled: bool, hde: StepDriftElimination) -> None:
        self.enabled = enabled
        self.hde = hde

    def apply(self, est: HeadingEstimate, length_m: float, t_end_s: float, placement: str | None) -> HeadingEstimate:
        if self.enabled and placement in DEVICE_HEADING_PLACEMENTS:
            return HeadingEstimate(self.hde.step(est.yaw, length_m, t_end_s), est.var)
        return est

    def state(self) -> dict[str, Any]:
        return {"hde": self.hde.state()}

    @classmethod
    def from_state(cls, d: dict[str, Any], enabled: bool, hde: StepDriftElimination) -> DriftElimination:
        """``hde``: a fresh drift elimination with the configuration, whose state ``d`` replaces (absent in states
        saved before the drift elimination: then it starts afresh).
        """
        if d.get("hde") is not None:
            hde = StepDriftElimination.from_state(d["hde"], hde.config, hde.grid_yaw)
        return cls(enabled, hde)
