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
    WalkingLineFilter,
    body_angular_rate,
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
    # The next step starts 3 s after the last stride ended: the filter starts again from the measurement.
    assert filt.update(0.9, q, 0, 520, 575, 630, RATE) == pytest.approx(0.9)
    assert -math.pi / 2 < filt.update(-1.6, q, 0, 575, 630, 685, RATE) <= math.pi / 2
