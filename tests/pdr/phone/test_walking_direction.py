"""Walking direction of a swinging phone: swing-plane axis and the centripetal forward/backward cue."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2, wrap_angle
from pdr.phone.walking_direction import (
    DeviceFrameDirection,
    DeviceSwingAxis,
    PocketSide,
    WalkingLineFilter,
    axis_variance,
    body_angular_rate,
    step_frequency_axis,
    step_lead,
    swing_plane_axis,
    turn_evidence,
    yaw_rate,
)

RATE = 100.0


def _swing(walk_yaw: float, mount: np.ndarray, amp_deg: float = 30.0, heading_sway_deg: float = 5.0) -> np.ndarray:
    """Attitudes of a limb swinging about the lateral axis ``f x u`` of the walking yaw, with some yaw sway."""
    t = np.arange(110) / RATE
    theta = math.radians(amp_deg) * np.sin(2 * math.pi * t / 1.1)
    lateral = np.array([math.sin(walk_yaw), -math.cos(walk_yaw), 0.0])
    sway = math.radians(heading_sway_deg) * np.sin(2 * math.pi * t / 1.1 + 0.7)
    rot = quat.from_rotvec(theta[:, None] * lateral + sway[:, None] * np.array([0.0, 0.0, 1.0]))
    return quat.multiply(rot, np.broadcast_to(mount, rot.shape))


@pytest.mark.parametrize("seed", range(4))
def test_swing_plane_gives_the_walking_line_whatever_the_mount(seed):
    rng = np.random.default_rng(seed)
    walk_yaw = rng.uniform(-math.pi, math.pi)
    q = _swing(walk_yaw, quat.from_rotvec(rng.normal(0, 1.5, 3)))
    line, ratio = swing_plane_axis(q, RATE)
    err = 0.5 * float(wrap_angle(2 * (line - walk_yaw)))            # a line: modulo 180 deg
    assert abs(math.degrees(err)) < 2.0 and ratio > 10.0
    assert -math.pi / 2 < line <= math.pi / 2


def test_turn_evidence_points_forward_from_the_centripetal_acceleration():
    # Walking north-east at 1.2 m/s turning left at 0.4 rad/s: mean horizontal acceleration V Omega (u x f).
    rng = np.random.default_rng(5)
    f = math.radians(45.0)
    centripetal = 1.2 * 0.4 * np.array([-math.sin(f), math.cos(f), 0.0])
    gait = rng.normal(0.0, 2.0, (110, 3))
    gait -= gait.mean(axis=0)                                      # the gait's oscillations average out
    f_n = centripetal + gait + np.array([0.0, 0.0, GRAVITY_MPS2])
    assert turn_evidence(f_n, 0.4, f) > 0.5
    assert turn_evidence(f_n, 0.4, f + math.pi) < -0.5              # odd in the direction
    # The same walk turning right: the acceleration and the rate change sign together.
    f_r = -centripetal + gait + np.array([0.0, 0.0, GRAVITY_MPS2])
    assert turn_evidence(f_r, -0.4, f) > 0.5
    assert turn_evidence(f_n, 0.0, f) == 0.0                        # a straight stride says nothing


def _turning_swing_walk(mount: np.ndarray, start_yaw: float, strides: int, rng: np.random.Generator
                        ) -> tuple[list[np.ndarray], list[np.ndarray], list[float], list[float]]:
    """Strides of a hand swinging with a fixed grip while the walker turns at +/-0.35 rad/s in alternate legs of 6
    strides and walks at 1.2 m/s: per stride the attitudes, the specific force (gravity, centripetal, gait noise)
    and the walking yaw at mid-stride and at the centre of the stride's second step (samples 55-109).
    """
    qs, fs, yaws, step_yaws = [], [], [], []
    t = np.arange(110) / RATE
    yaw0 = start_yaw
    for k in range(strides):
        omega = 0.35 if (k // 6) % 2 == 0 else -0.35
        yaw = yaw0 + omega * t
        theta = math.radians(30.0) * np.sin(2 * math.pi * t / 1.1)
        walker = quat.from_rotvec(yaw[:, None] * np.array([0.0, 0.0, 1.0]))
        arm = quat.from_rotvec(theta[:, None] * np.array([0.0, -1.0, 0.0]))     # about the walker's f x u
        qs.append(quat.multiply(quat.multiply(walker, arm), np.broadcast_to(mount, walker.shape)))
        centripetal = 1.2 * omega * np.column_stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)])
        gait = rng.normal(0.0, 1.5, (t.size, 3))
        fs.append(centripetal + gait - gait.mean(axis=0) + np.array([0.0, 0.0, GRAVITY_MPS2]))
        yaws.append(float(yaw[t.size // 2]))
        step_yaws.append(float(0.5 * (yaw[82] + yaw[83])))                     # centre of the second step
        yaw0 = float(yaw[-1] + omega / RATE)
    return qs, fs, yaws, step_yaws


@pytest.mark.parametrize("seed", range(3))
def test_device_swing_axis_recovers_direction_and_sign_with_any_grip(seed):
    rng = np.random.default_rng(seed)
    qs, fs, yaws, step_yaws = _turning_swing_walk(quat.from_rotvec(rng.normal(0, 1.5, 3)), rng.uniform(-3, 3), 30,
                                                  rng)
    tracker, led = DeviceSwingAxis(), DeviceSwingAxis()
    errs, lag, lead = [], [], []
    for k, (q, f, y, ys) in enumerate(zip(qs, fs, yaws, step_yaws, strict=True)):
        out = tracker.update(q, f, RATE)
        if k == 14:                              # the state survives a round trip
            tracker = DeviceSwingAxis.from_state(tracker.state())
        errs.append(abs(math.degrees(float(wrap_angle(out - y)))))
        out_step = led.update(q, f, RATE, step_start=55)
        lag.append(abs(math.degrees(float(wrap_angle(out - ys)))))
        lead.append(abs(math.degrees(float(wrap_angle(out_step - ys)))))
    assert max(errs[6:]) < 8.0                   # forward, not backward, once a turn has been seen
    # At the second step's centre, 0.28 s after the stride's: 5.5 deg behind at 0.35 rad/s unless led.
    assert min(lag[6:]) > 4.0 and np.mean(lead[6:]) < np.mean(lag[6:]) - 3.0


def test_device_swing_axis_restarts_the_sign_on_a_new_grip():
    rng = np.random.default_rng(7)
    tracker = DeviceSwingAxis()
    for q, f, _ in zip(*_turning_swing_walk(quat.from_rotvec([0.3, 1.2, -0.4]), 0.5, 20, rng)[:2], range(20),
                       strict=True):
        tracker.update(q, f, RATE)
    qs, fs, yaws, _ = _turning_swing_walk(quat.from_rotvec([1.4, -0.2, 0.9]), 2.0, 20, rng)
    outs = [tracker.update(q, f, RATE) for q, f in zip(qs, fs, strict=True)]
    assert abs(math.degrees(float(wrap_angle(outs[-1] - yaws[-1])))) < 8.0


def test_step_lead_is_the_turn_from_stride_centre_to_step_centre():
    q = quat.from_rotvec(np.arange(101)[:, None] / RATE * np.array([0.0, 0.0, 0.4]))
    assert step_lead(q, RATE, 50) == pytest.approx(0.4 * 0.25, rel=1e-9)
    assert step_lead(q, RATE, 0) == 0.0
    with pytest.raises(InputError, match="step start"):
        step_lead(q, RATE, 101)


def test_body_angular_rate_of_a_constant_rotation():
    w_b = np.array([0.3, -0.2, 1.0])
    q = quat.multiply(np.broadcast_to(quat.from_rotvec([0.2, 0.5, -1.0]), (50, 4)),
                      quat.from_rotvec(np.arange(50)[:, None] / RATE * w_b))
    assert np.allclose(body_angular_rate(q, RATE), w_b, atol=1e-9)


def test_turn_evidence_speed_gate_drops_pivots_on_the_spot():
    f = math.radians(45.0)
    lateral = np.array([-math.sin(f), math.cos(f), 0.0])
    walking = np.tile(1.2 * 0.4 * lateral + np.array([0.0, 0.0, GRAVITY_MPS2]), (110, 1))   # 1.2 m/s
    pivot = np.tile(0.05 * 1.5 * lateral + np.array([0.0, 0.0, GRAVITY_MPS2]), (110, 1))    # 0.05 m/s, 1.5 rad/s
    assert turn_evidence(walking, 0.4, f, speed_range_mps=(0.4, 4.0)) > 0.5
    assert turn_evidence(pivot, 1.5, f) > 0.0                                # ungated: a full vote
    assert turn_evidence(pivot, 1.5, f, speed_range_mps=(0.4, 4.0)) == 0.0


@pytest.mark.parametrize("seed", range(3))
def test_device_frame_direction_keeps_the_direction_through_turns(seed):
    # A thigh swinging about the lateral axis of a walker who turns 40 deg per stride; the line alone says nothing
    # about forward or backward, the stored device-frame direction does once set.
    rng = np.random.default_rng(seed)
    mount = quat.from_rotvec(rng.normal(0, 1.5, 3))

    def _swing(walk_yaw: float, mount: np.ndarray) -> np.ndarray:     # the thigh turns with the walker
        t = np.arange(110) / RATE
        theta = math.radians(30.0) * np.sin(2 * math.pi * t / 1.1)
        walker = quat.from_rotvec(np.tile([0.0, 0.0, walk_yaw], (t.size, 1)))
        thigh = quat.from_rotvec(theta[:, None] * np.array([0.0, -1.0, 0.0]))
        return quat.multiply(quat.multiply(walker, thigh), np.broadcast_to(mount, walker.shape))

    cont = DeviceFrameDirection()
    yaw0 = rng.uniform(-3, 3)
    for k in range(12):
        walk = yaw0 + math.radians(40.0) * k
        q = _swing(walk, mount)
        line, _ = swing_plane_axis(q, RATE)
        out = cont.resolve(line, q)
        if k == 0:                                   # the first stride: set the right direction
            out = float(wrap_angle(walk))
        assert abs(float(wrap_angle(out - walk))) < math.radians(3.0)
        cont.update(out, q)
        if k == 6:
            cont = DeviceFrameDirection.from_state(cont.state())
    cont.reverse()                                   # a reversal by the vote turns the stored direction round
    q = _swing(yaw0 + math.radians(40.0) * 12, mount)
    assert abs(float(wrap_angle(cont.resolve(swing_plane_axis(q, RATE)[0], q) - (yaw0 + math.radians(40.0) * 12 +
                                                                                   math.pi)))) < math.radians(3.0)


def test_yaw_rate_of_a_turn():
    q = quat.from_rotvec(np.arange(101)[:, None] / RATE * np.array([0.0, 0.0, -0.3]))
    assert yaw_rate(q, RATE) == pytest.approx(-0.3)


def test_bad_input_is_refused():
    with pytest.raises(InputError, match="attitude"):
        swing_plane_axis(np.zeros((2, 4)), RATE)
    with pytest.raises(InputError, match="specific forces"):
        turn_evidence(np.zeros((4, 2)), 0.1, 0.0)


def _continuous_thigh_walk(mount: np.ndarray, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """A thigh swinging 25 deg about the walker's lateral axis (stride 1.1 s) while the walker turns at +/-0.4
    rad/s in alternate 4 s legs: attitudes ``q_nb`` at :data:`RATE` and the walking yaw at each sample.
    """
    t = np.arange(int(seconds * RATE)) / RATE
    omega = np.where((t // 4.0) % 2 == 0, 0.4, -0.4)
    yaw = 0.3 + np.concatenate([[0.0], np.cumsum(omega[:-1]) / RATE])
    walker = quat.from_rotvec(yaw[:, None] * np.array([0.0, 0.0, 1.0]))
    thigh = quat.from_rotvec(math.radians(25.0) * np.sin(2 * math.pi * t / 1.1)[:, None] * np.array([0.0, -1.0, 0.0]))
    return quat.multiply(quat.multiply(walker, thigh), np.broadcast_to(mount, walker.shape)), yaw


def _line_errors(noise_deg: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Per stride, the error (deg, a line: modulo 180) of the swing plane with ``noise_deg`` of added noise, and of
    :class:`WalkingLineFilter` fed with it, against the walking yaw at the stride's centre.
    """
    rng = np.random.default_rng(seed)
    q, yaw = _continuous_thigh_walk(quat.from_rotvec(rng.normal(0, 1.5, 3)), 60.0)
    filt = WalkingLineFilter()
    raw, filtered = [], []
    for k, step_start in enumerate(range(55, q.shape[0] - 55, 55)):
        s0, e = step_start - 55, step_start + 55
        line = swing_plane_axis(q[s0:e], RATE)[0] + math.radians(rng.normal(0.0, noise_deg))
        out = filt.update(line, q, 0, s0, step_start, e, RATE)
        if k == 20:                                          # the state survives a round trip
            filt = WalkingLineFilter.from_state(filt.state())
        truth = yaw[(s0 + e) // 2]
        raw.append(math.degrees(0.5 * float(wrap_angle(2 * (line - truth)))))
        filtered.append(math.degrees(0.5 * float(wrap_angle(2 * (out - truth)))))
    return np.abs(raw[5:]), np.abs(filtered[5:])


@pytest.mark.parametrize("seed", range(3))
def test_walking_line_filter_averages_the_stride_noise_and_follows_turns(seed):
    raw, filtered = _line_errors(13.0, seed)
    assert np.sqrt(np.mean(filtered ** 2)) < 0.7 * np.sqrt(np.mean(raw ** 2))
    # Noise-free strides: the turns are followed without lag (no worse than the strides themselves, which mix
    # the legs on either side of a change of turn).
    raw_exact, exact = _line_errors(0.0, seed)
    assert exact.max() < raw_exact.max() + 1.0 and np.mean(exact) < np.mean(raw_exact) + 0.5


def test_walking_line_filter_restarts_after_a_pause():
    q, _ = _continuous_thigh_walk(quat.from_rotvec([0.2, 1.0, 0.1]), 10.0)
    filt = WalkingLineFilter(max_gap_s=2.0)
    filt.update(0.1, q, 0, 0, 55, 110, RATE)
    assert filt.update(0.5, q, 0, 110, 165, 220, RATE) != pytest.approx(0.5)      # filtered
    # The next step starts 3 s after the last stride ended: the filter starts again from the measurement, less the
    # swing plane's offset it has learnt (none is observable without the step-frequency axis).
    assert filt.update(0.9, q, 0, 520, 575, 630, RATE) == pytest.approx(0.9 - filt.bias)
    assert abs(filt.bias) < math.radians(0.5)
    assert -math.pi / 2 < filt.update(-1.6, q, 0, 575, 630, 685, RATE) <= math.pi / 2


def _stride_specific_force(walk_yaw: float, thigh_offset_deg: float, rng: np.random.Generator,
                           n: int = 110) -> np.ndarray:
    """(n, 3) specific force (m/s^2, ENU) over one stride of a phone on the thigh: the body's fore-aft oscillation
    at the step frequency (1.5 m/s^2 along the walking direction), its lateral sway at the stride frequency
    (0.5 m/s^2), the thigh's swing at the stride frequency (4 m/s^2, in a plane ``thigh_offset_deg`` off the
    walking direction), the vertical bounce at the step frequency and white noise (0.5 m/s^2).
    """
    k = np.arange(n) / n
    fwd = np.array([math.cos(walk_yaw), math.sin(walk_yaw), 0.0])
    lat = np.array([-math.sin(walk_yaw), math.cos(walk_yaw), 0.0])
    a = walk_yaw + math.radians(thigh_offset_deg)
    thigh = np.array([math.cos(a), math.sin(a), 0.0])
    phase = rng.uniform(0, 2 * math.pi)
    f = (1.5 * np.sin(4 * math.pi * k + phase)[:, None] * fwd + 0.5 * np.cos(2 * math.pi * k)[:, None] * lat
         + 4.0 * np.sin(2 * math.pi * k + 1.0)[:, None] * thigh
         + np.array([0.0, 0.0, GRAVITY_MPS2]) + 2.0 * np.cos(4 * math.pi * k + phase)[:, None] * np.array([0, 0, 1.0]))
    return f + rng.normal(0.0, 0.5, (n, 3))


@pytest.mark.parametrize("seed", range(4))
def test_step_frequency_axis_is_the_walking_line_whatever_the_thighs_swing(seed):
    # The noise leaves about 2.6 deg of spread on the harmonic's axis (0.5 * sqrt(2 / 110) against 1.5 m/s^2).
    rng = np.random.default_rng(seed)
    errors = []
    for walk_yaw in rng.uniform(-math.pi, math.pi, 10):
        line, ratio = step_frequency_axis(_stride_specific_force(walk_yaw, rng.uniform(-30, 30), rng))
        errors.append(abs(math.degrees(0.5 * float(wrap_angle(2 * (line - walk_yaw))))))
        assert -math.pi / 2 < line <= math.pi / 2 and ratio > 5.0
    assert max(errors) < 9.0 and np.mean(errors) < 3.5


def test_step_frequency_axis_refuses_a_short_window():
    with pytest.raises(InputError):
        step_frequency_axis(np.zeros((3, 3)))


def _offset_walk(offset_deg: float, seed: int, walking: bool = True) -> tuple[WalkingLineFilter, list[float]]:
    """Strides of the turning thigh walk whose swing plane is ``offset_deg`` off the walking line (13 deg of noise)
    and whose step-frequency axis is on it (15 deg of noise): the filtered line's errors (deg) from stride 30."""
    rng = np.random.default_rng(seed)
    q, yaw = _continuous_thigh_walk(quat.from_rotvec(rng.normal(0, 1.5, 3)), 90.0)
    filt = WalkingLineFilter()
    errors = []
    for k, step_start in enumerate(range(55, q.shape[0] - 55, 55)):
        s0, e = step_start - 55, step_start + 55
        truth = yaw[(s0 + e) // 2]
        swing = truth + math.radians(offset_deg + rng.normal(0.0, 13.0))
        step_axis = truth + math.radians(rng.normal(0.0, 15.0))
        out = filt.update(swing, q, 0, s0, step_start, e, RATE, step_axis, walking)
        if k >= 30:
            errors.append(abs(math.degrees(0.5 * float(wrap_angle(2 * (out - truth))))))
    return filt, errors


@pytest.mark.parametrize("seed", range(3))
def test_walking_line_filter_learns_the_swing_planes_offset(seed):
    filt, errors = _offset_walk(20.0, seed)
    assert math.degrees(filt.bias) == pytest.approx(20.0, abs=6.0)
    assert np.mean(errors) < 7.0
    # The offset survives a round trip of the state, and states saved before it resume with none.
    again = WalkingLineFilter.from_state(filt.state())
    assert again.bias == filt.bias and again.cov == filt.cov
    old = {k: v for k, v in filt.state().items() if k in ("line_sigma_deg", "turn_sigma_deg", "max_gap_s", "line",
                                                            "var", "window")}
    assert WalkingLineFilter.from_state(old).bias == 0.0


@pytest.mark.parametrize("ratio", [1.5, 3.0, 10.0])
def test_axis_variance_is_the_sampling_spread_of_a_principal_axis(ratio):
    # Simulate then recover: n samples of a 2-D Gaussian whose scatter has the eigenvalue ratio `ratio` along a
    # known axis; the angles of the measured principal axis scatter by the predicted variance.
    from pdr.phone.heading import pca_axis

    rng = np.random.default_rng(7)
    n, axis = 400, 0.4
    rot = np.array([[math.cos(axis), -math.sin(axis)], [math.sin(axis), math.cos(axis)]])
    angles = []
    for _ in range(3000):
        xy = rng.normal(size=(n, 2)) * np.array([math.sqrt(ratio), 1.0]) @ rot.T
        angles.append(0.5 * float(wrap_angle(2 * (pca_axis(xy)[0] - axis))))
    assert np.var(angles) == pytest.approx(axis_variance(ratio, n), rel=0.25)


def test_axis_variance_limits():
    # No axis at all (a round scatter, or no samples): the variance of an angle spread over the half circle.
    assert axis_variance(1.0, 50) == axis_variance(3.0, 0) == pytest.approx(math.pi ** 2 / 12)
    assert axis_variance(1.01, 50) == pytest.approx(math.pi ** 2 / 12)
    assert axis_variance(1e6, 50) < 1e-6
    assert axis_variance(4.0, 100) == pytest.approx(4.0 / (9.0 * 100))


def test_a_stride_without_a_clear_swing_plane_moves_the_line_less():
    # Two filters on the same walk; one stride's swing plane is 40 deg off, once with a sharp plane (its
    # variance 0) and once with a nearly round scatter (its axis variance large): the second barely moves.
    # A third filter, fed the true line, is the reference.
    q, yaw = _continuous_thigh_walk(quat.from_rotvec([0.2, 1.0, 0.1]), 10.0)
    sharp, blurred, ref = WalkingLineFilter(), WalkingLineFilter(), WalkingLineFilter()
    for f in (sharp, blurred, ref):
        f.update(float(yaw[55]), q, 0, 0, 55, 110, RATE)
        f.update(float(yaw[165]), q, 0, 110, 165, 220, RATE)
    truth = float(yaw[275])
    on_line = ref.update(truth, q, 0, 220, 275, 330, RATE)
    off_sharp = 0.5 * float(wrap_angle(2 * (sharp.update(truth + math.radians(40), q, 0, 220, 275, 330, RATE)
                                            - on_line)))
    off_blurred = 0.5 * float(wrap_angle(2 * (blurred.update(truth + math.radians(40), q, 0, 220, 275, 330, RATE,
                                                             line_var=axis_variance(1.1, 110)) - on_line)))
    assert math.radians(10) < off_sharp and abs(off_blurred) < 0.25 * off_sharp


def test_running_strides_take_the_swing_plane_as_it_is():
    # Running: no step-frequency axis and no offset; a swing plane on the line is followed without bias.
    filt, errors = _offset_walk(0.0, 1, walking=False)
    assert filt.bias == 0.0 and np.mean(errors) < 7.0


def test_the_gait_is_the_bouts_and_a_harmonic_needs_one_stride():
    from pdr.phone.attitude import AttitudeConfig
    from pdr.phone.heading_stages import PocketHeading

    head = PocketHeading(50.0, "swing", 0.0, AttitudeConfig(), False, "pocket")
    # A walk (1.2 s strides): walking, every stride one gait cycle, a step found twice is not.
    assert [head._walking_gait(1.2) for _ in range(4)] == [(True, True)] * 4
    assert head._walking_gait(0.6) == (True, False)
    # A run (0.7 s strides) with one slow stride in a turn: still running.
    run = PocketHeading(50.0, "swing", 0.0, AttitudeConfig(), False, "pocket")
    assert [run._walking_gait(d)[0] for d in (0.7, 0.7, 0.7, 1.1, 0.7)] == [False] * 5
    # The recent strides are kept with the state.
    again = PocketHeading.from_state(head.state(), 50.0, "swing", 0.0, AttitudeConfig(), False, "pocket")
    assert again.stride_s == head.stride_s


def _thigh_point_specific_force(walk_yaw: float, offset_m: float, rng: np.random.Generator) -> np.ndarray:
    """Specific force (N, 3, ENU) of a point on a thigh swinging +/-30 deg about the hip over one 1.1 s stride,
    0.25 m down the thigh and ``offset_m`` in front of its long axis (negative: behind it), with the body's own
    step-frequency bounce and sensor noise."""
    t = np.arange(110) / RATE
    theta = math.radians(30) * np.sin(2 * math.pi * t / 1.1)
    fwd = 0.25 * np.sin(theta) + offset_m * np.cos(theta)
    up = -0.25 * np.cos(theta) + offset_m * np.sin(theta)
    acc_fwd = np.gradient(np.gradient(fwd, 1 / RATE), 1 / RATE)
    acc_up = np.gradient(np.gradient(up, 1 / RATE), 1 / RATE) + 1.0 * np.cos(4 * math.pi * t / 1.1)
    f = np.column_stack([acc_fwd * math.cos(walk_yaw), acc_fwd * math.sin(walk_yaw), acc_up + GRAVITY_MPS2])
    return f + rng.normal(0.0, 0.3, f.shape)


@pytest.mark.parametrize("seed", range(3))
def test_pocket_side_tells_front_from_back_of_the_thigh(seed):
    """A phone in front of the thigh's long axis rises as the thigh swings forward (forward and vertical specific
    force covary): the full half-step lead; behind it they covary the other way: no lead. Walking the other way
    along the same line reads the side the other way round (the direction must be the resolved one)."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-math.pi, math.pi)
    front, back, front_reversed = PocketSide(), PocketSide(), PocketSide()
    for _ in range(30):
        front.update(_thigh_point_specific_force(yaw, 0.1, rng), yaw)
        back.update(_thigh_point_specific_force(yaw, -0.1, rng), yaw)
        front_reversed.update(_thigh_point_specific_force(yaw, 0.1, rng), yaw + math.pi)
    assert front.lead_weight() == 1.0
    assert back.lead_weight() == 0.0 and front_reversed.lead_weight() == 0.0
    assert PocketSide.from_state(front.state()) == front
    assert PocketSide().lead_weight() == 0.0      # no evidence yet: no lead


def test_a_swinging_hands_grip_is_kept_through_a_short_misread_placement():
    from pdr.phone.attitude import AttitudeConfig
    from pdr.phone.heading_stages import SWING_GRIP_MEMORY_S, PocketHeading

    head = PocketHeading(50.0, "auto", 0.0, AttitudeConfig(), False, "swinging")
    grip = head.swing_tracker(10.0)
    head.reset("pocket")                          # a few strides read as a pocket ...
    head.reset("swinging")                        # ... then the hand again: the same grip, its sign kept
    assert head.swing_tracker(10.0 + 0.5 * SWING_GRIP_MEMORY_S) is grip
    assert head.swing_tracker(30.0) is grip      # a stop with the hand swinging keeps it too
    head = PocketHeading.from_state(head.state(), 50.0, "auto", 0.0, AttitudeConfig(), False, "swinging")
    kept = head.swing_tracker(30.5)
    assert kept.state() == grip.state()           # the state round trip keeps it
    head.reset("pocket")
    head.reset("swinging")                        # back in the hand after a longer spell: a new grip
    assert head.swing_tracker(31.0 + 2 * SWING_GRIP_MEMORY_S) is not kept
