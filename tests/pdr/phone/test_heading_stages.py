"""The heading stages of the phone pipeline (pdr.phone.heading_stages): analytic truth and state round trips."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pdr.frames import heading_deg_to_yaw, wrap_angle
from pdr.phone.attitude import AttitudeConfig, AttitudeState
from pdr.phone.heading import HeadingEstimate, StepDriftElimination, yaw_variance
from pdr.phone.heading_stages import DeviceHeading, DriftElimination, StairsLandmarkHeading, StepTurn
from pdr.phone.history import SampleHistory
from pdr.phone.landmarks import Site
from pdr.phone.stage import PendingStep, StepWindow
from pdr.phone.track import TrackState


def pending(t_start: float, t_end: float, yaw: float, psi0: float | None = None, floor: float = 0.0) -> PendingStep:
    """A processed step with heading ``yaw`` (rad) between ``t_start`` and ``t_end`` (s)."""
    return PendingStep(0, 10, t_start, t_end, [0.0] * 7, yaw, 0.01, yaw if psi0 is None else psi0, yaw, "walking",
                       0.0, floor, np.zeros((3, 3)).tolist(), [1.0, 0.0, 0.0, 0.0], 1.0)


def window(yaw_y: float, yaw_z: float, n: int = 50, axis: float = 0.0) -> StepWindow:
    """A step of ``n`` samples whose device y and z axes point at the constant yaws ``yaw_y``, ``yaw_z`` (rad)."""
    h = SampleHistory(200)
    t = np.arange(n, dtype=np.float64)
    t *= 0.01                                               # s, 100 Hz
    h.append(100, t, np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n))
    h.yaw_y[:] = yaw_y
    h.yaw_z[:] = yaw_z
    p = np.diag([1e-4, 1e-4, 1e-4, 1e-4])
    return StepWindow(100, 100 + n, h, np.tile([1.0, 0, 0, 0], (n, 1)), np.zeros((n, 3)), axis,
                      np.array([1.0, 0, 0, 0]), p)


@pytest.mark.parametrize(("placement", "expected"), [("hand", 0.7), ("torso", -2.0)])
def test_device_heading_is_the_forward_axis_yaw(placement: str, expected: float) -> None:
    """Hand: the device y axis' yaw; torso: the z axis'; variance the attitude's yaw variance plus the process noise."""
    stage = DeviceHeading("zero", process_var=0.003)
    win = window(0.7, -2.0)
    out = stage.estimate(win, placement, with_scatter=False)
    assert out.est.yaw == pytest.approx(expected)
    assert out.psi0 == pytest.approx(expected)
    assert out.est.var == pytest.approx(yaw_variance(win.att_q, win.att_p) + 0.003)
    assert not out.m1.any() and not out.reversed_direction


def test_device_heading_pca_offset_learns_the_axis_and_resumes() -> None:
    """With ``pca`` the offset moves the device yaw towards the RMPCA axis (a line: 30 deg, not 210 deg), and a
    stage restored from its JSON state continues exactly like the one that was not interrupted.
    """
    device = 0.2
    # The axis is a line: 20 and 40 deg off the device yaw, some given as the opposite direction.
    axes = [device + math.radians(20.0 if k % 2 else 40.0) + (math.pi if k % 3 == 0 else 0.0) for k in range(200)]
    stage = DeviceHeading("pca", process_var=0.0)
    yaws = [stage.estimate(window(device, 0.0, axis=a), "hand", False).est.yaw for a in axes]
    assert float(wrap_angle(yaws[-1] - device)) == pytest.approx(math.radians(30.0), abs=math.radians(1.0))
    axis = axes[-1]

    again = DeviceHeading.from_state(json.loads(json.dumps(stage.state())), "pca", 0.0)
    a = stage.estimate(window(device, 0.0, axis=axis + 0.1), "hand", False).est.yaw
    b = again.estimate(window(device, 0.0, axis=axis + 0.1), "hand", False).est.yaw
    assert a == b


def test_step_turn_is_the_wrapped_change_within_a_walk() -> None:
    turn = StepTurn(max_gap_s=2.0)
    assert turn.turn(pending(0.0, 0.5, math.radians(170.0)), False, "hand") == 0.0      # first step: no turn
    # From 170 to -170 deg is a 20 deg turn, not 340.
    assert turn.turn(pending(0.5, 1.0, math.radians(-170.0)), False, "hand") == pytest.approx(math.radians(20.0))
    # A gap longer than max_gap_s starts a new walk; stairs and pocket steps have no turn.
    assert turn.turn(pending(5.0, 5.5, math.radians(-100.0)), False, "hand") == 0.0
    assert turn.turn(pending(5.5, 6.0, math.radians(0.0)), True, "hand") == 0.0
    assert turn.turn(pending(6.0, 6.5, math.radians(90.0)), False, "pocket") == 0.0
    assert turn.turn(pending(6.5, 7.0, math.radians(60.0)), False, "torso") == pytest.approx(math.radians(30.0))

    again = StepTurn.from_state(json.loads(json.dumps(turn.state())), 2.0)
    assert again.turn(pending(7.0, 7.5, math.radians(50.0)), False, "hand") == pytest.approx(math.radians(10.0))
    assert StepTurn.from_state({}, 2.0).last_step is None                 # a state saved before the turn factor


def test_drift_elimination_applies_to_hand_and_torso_only() -> None:
    """Enabled, hand and torso steps get the heuristic drift elimination's heading (the same as running it directly);
    pocket steps and a disabled stage pass the estimate unchanged. Its state resumes.
    """
    yaws = [math.radians(3.0)] * 30 + [math.radians(93.0)] * 30     # two straight legs near a 90 deg grid
    stage = DriftElimination(True, StepDriftElimination())
    direct = StepDriftElimination()
    for k, y in enumerate(yaws):
        est = stage.apply(HeadingEstimate(y, 0.01), 0.7, 0.5 * k, "hand")
        assert est.yaw == direct.step(y, 0.7, 0.5 * k)
        assert est.var == 0.01
    assert direct.updates > 0

    pocket = stage.apply(HeadingEstimate(0.3, 0.02), 0.7, 40.0, "pocket")
    assert pocket == HeadingEstimate(0.3, 0.02)
    off = DriftElimination(False, StepDriftElimination())
    assert off.apply(HeadingEstimate(0.3, 0.02), 0.7, 0.0, "hand") == HeadingEstimate(0.3, 0.02)

    again = DriftElimination.from_state(json.loads(json.dumps(stage.state())), True, StepDriftElimination())
    assert (again.apply(HeadingEstimate(0.05, 0.01), 0.7, 31.0, "hand")
            == stage.apply(HeadingEstimate(0.05, 0.01), 0.7, 31.0, "hand"))
    fresh = DriftElimination.from_state({}, True, StepDriftElimination())    # saved before the drift elimination
    assert fresh.hde.updates == 0


SITE = Site.from_dict({"landmarks": [
    {"id": "S1", "type": "stairs_up", "east_m": 10.0, "north_m": 0.0, "floor": 0, "heading_deg": [80, 100]}]})


def test_stairs_landmark_fixes_the_position_and_fuses_its_heading() -> None:
    """Entering a matched flight fixes the track at the landmark and emits its event; every step of the flight fuses
    the landmark's heading (second UKF, eq. 42: the variance-weighted mean); walking again drops it.
    """
    stage = StairsLandmarkHeading(SITE, AttitudeConfig())
    track = TrackState(9.0, 0.5)
    att = AttitudeState()                   # a hand-held step: the attitude is not updated
    q_before = att.q.copy()
    yaw_lm, var_lm = SITE.landmarks[0].yaw_and_var()
    assert yaw_lm == pytest.approx(heading_deg_to_yaw(90.0))       # compass east: the centre of [80, 100]
    prior = HeadingEstimate(yaw_lm + 0.2, var_lm)                    # as sure as the landmark: the mean halves
    est, event, used = stage.correct(pending(1.0, 1.5, prior.yaw), "stairs_up", "walking", prior, track, att, "hand")
    assert used and event is not None and event.landmark == "S1" and event.t_s == 1.0
    assert (track.east_m, track.north_m) == (10.0, 0.0)
    assert est.yaw == pytest.approx(yaw_lm + 0.1) and est.var == pytest.approx(var_lm / 2)
    assert np.array_equal(att.q, q_before) and stage.attitude_updates == 0

    # The next step of the flight: no new fix, the heading still fused.
    track.step(0.3, yaw_lm, 0.0, 0.0)
    est, event, used = stage.correct(pending(1.5, 2.0, prior.yaw), "stairs_up", "stairs_up", prior, track, att,
                                     "hand")
    assert used and event is None and track.east_m == pytest.approx(10.3)
    assert est.yaw == pytest.approx(yaw_lm + 0.1)

    again = StairsLandmarkHeading.from_state(json.loads(json.dumps(stage.state())), SITE, AttitudeConfig())
    assert (again.stairs_landmark, again.updates) == ("S1", 2)
    est2, _, used2 = again.correct(pending(2.0, 2.5, prior.yaw), "stairs_up", "stairs_up", prior, track, att, "hand")
    assert used2 and est2 == est

    # Walking again, or no site: unchanged.
    assert stage.correct(pending(3.0, 3.5, 0.0), "walking", "stairs_up", prior, track, att, "hand")[0] == prior
    assert stage.stairs_landmark is None
    none = StairsLandmarkHeading(None, AttitudeConfig())
    assert none.correct(pending(0.0, 0.5, 0.0), "stairs_up", "walking", prior, track, att, "hand") == (prior, None,
                                                                                                      False)


def test_stairs_landmark_far_away_is_not_matched() -> None:
    stage = StairsLandmarkHeading(SITE, AttitudeConfig())
    track = TrackState(-50.0, 40.0)
    prior = HeadingEstimate(0.0, 0.01)
    est, event, used = stage.correct(pending(1.0, 1.5, 0.0), "stairs_up", "walking", prior, track, AttitudeState(),
                                     "hand")
    assert (est, event, used) == (prior, None, False)
    assert (track.east_m, track.north_m) == (-50.0, 40.0)
