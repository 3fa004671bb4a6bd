"""Placement detection: simulated pendulum arm, thigh and held phone, then the online decision and its state."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2
from pdr.phone.placement_detect import (
    PlacementDetectConfig,
    PlacementDetector,
    StrideCues,
    classify_stride,
    stride_cues,
)

RATE = 100.0
UP = np.array([0.0, 0.0, GRAVITY_MPS2])


def _limb(theta: np.ndarray, radius_m: float, mount: np.ndarray, extra_acc_n: np.ndarray | None = None):
    """A device at ``radius_m`` below a pivot on a limb at angle ``theta`` (rad) about the east axis (walking north).

    Returns the attitudes q_nb (N, 4) and the specific force in the device frame (N, 3).
    """
    dt = 1.0 / RATE
    pos = radius_m * np.column_stack([np.zeros_like(theta), np.sin(theta), -np.cos(theta)])
    acc = np.gradient(np.gradient(pos, dt, axis=0), dt, axis=0)
    if extra_acc_n is not None:
        acc = acc + extra_acc_n
    limb = quat.from_rotvec(np.column_stack([theta, np.zeros_like(theta), np.zeros_like(theta)]))
    q = quat.multiply(limb, np.broadcast_to(mount, limb.shape))
    f_b = quat.rotate(quat.conjugate(q), acc + UP)
    return q, f_b


def _stride(period_s: float = 1.1) -> np.ndarray:
    return np.arange(int(round(period_s * RATE))) / RATE


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_phone_on_a_freely_swinging_arm_is_swinging(seed):
    # Free pendulum (arm 0.65 m, its natural period, +/-30 deg): the specific force stays along the arm.
    rng = np.random.default_rng(seed)
    length = 0.65
    period = 2 * math.pi * math.sqrt(length / GRAVITY_MPS2)
    t = _stride(period)
    theta = math.radians(30.0) * np.sin(2 * math.pi * t / period)
    mount = quat.from_rotvec(rng.normal(0, 1.0, 3))
    q, f_b = _limb(theta, length, mount)
    cues = stride_cues(q, f_b, RATE)
    assert cues.tilt_swing_deg == pytest.approx(60.0, abs=3.0)
    assert cues.ratio < 0.5
    # The mount's long axis must hang near vertical for "pocket"; a pendulum is swinging whatever the mount.
    assert classify_stride(cues) == "swinging"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_phone_on_the_thigh_is_in_the_pocket(seed):
    # Thigh: +25/-20 deg, long axis along the thigh (up to 20 deg off). Through the stance the thigh turns about the
    # planted foot while the hip moves on at nearly constant velocity, so the phone's acceleration is the trunk's
    # (vertical bounce 1.5 m/s^2 and fore-aft 1 m/s^2 at the step frequency), not a pendulum's.
    rng = np.random.default_rng(seed)
    t = _stride()
    theta = math.radians(2.5) + math.radians(22.5) * np.sin(2 * math.pi * t / 1.1)
    tilt = quat.from_rotvec(np.array([rng.uniform(-0.35, 0.35), rng.uniform(-0.35, 0.35), 0.0]))
    spin = quat.from_rotvec(np.array([0.0, rng.uniform(-math.pi, math.pi), 0.0]))   # about the long axis
    # Device y up: rotate the device so its y axis is the navigation up axis (x east stays east).
    y_up = quat.from_rotvec(np.array([math.pi / 2, 0.0, 0.0]))
    mount = quat.multiply(tilt, quat.multiply(y_up, spin))
    step_phase = 4 * math.pi * t / 1.1
    bounce = np.column_stack([np.zeros_like(t), 1.0 * np.cos(step_phase), 1.5 * np.sin(step_phase)])
    q, f_b = _limb(theta, 0.0, mount, bounce)
    cues = stride_cues(q, f_b, RATE)
    assert cues.tilt_swing_deg > 30.0 and cues.ratio > 0.9 and cues.long_axis_up > 0.8
    assert classify_stride(cues) == "pocket"


def test_a_phone_held_for_reading_is_in_the_hand():
    # Screen up, tilted 40 deg towards the face, swaying 2 deg, with the trunk's bounce.
    t = _stride()
    theta = math.radians(40.0) + math.radians(2.0) * np.sin(2 * math.pi * t / 1.1)
    bounce = np.column_stack([np.zeros_like(t), 0.5 * np.sin(4 * math.pi * t / 1.1),
                              1.5 * np.sin(4 * math.pi * t / 1.1)])
    q, f_b = _limb(theta, 0.0, np.array([1.0, 0.0, 0.0, 0.0]), bounce)
    cues = stride_cues(q, f_b, RATE)
    assert cues.tilt_swing_deg < 6.0
    assert classify_stride(cues) == "hand"


def test_a_phone_that_turns_across_the_vertical_is_held_not_in_a_pocket():
    # Large turns but the long axis horizontal (a reading phone swaying in a walking hand): not a pocket.
    cues = StrideCues(tilt_swing_deg=20.0, force_swing_deg=30.0, long_axis_up=0.2)
    assert classify_stride(cues) == "hand"
    assert classify_stride(StrideCues(20.0, 30.0, 0.95)) == "pocket"


def test_the_detector_follows_a_change_of_place_after_agreeing_strides_only():
    pocket, held = StrideCues(25.0, 30.0, 0.95), StrideCues(4.0, 8.0, 0.1)
    det = PlacementDetector(PlacementDetectConfig(switch_strides=3))
    # The first strides (a walk starting from rest) each decide on their own.
    assert [det.update(c) for c in (held, pocket, pocket)] == ["hand", "pocket", "pocket"]
    assert det.update(held) == "pocket"                      # afterwards one odd stride changes nothing
    assert det.update(pocket) == "pocket"
    assert [det.update(held) for _ in range(3)] == ["pocket", "pocket", "hand"]   # taken out of the pocket
    restored = PlacementDetector.from_state(det.state())
    assert restored.state() == det.state()
    assert [restored.update(pocket) for _ in range(3)] == ["hand", "hand", "pocket"]


def test_a_pocket_phone_that_slows_down_stays_in_the_pocket_until_it_moves():
    along_thigh, screen_up = (0.0, 0.97, 0.24), (0.0, 0.5, 0.87)          # 16 deg and 60 deg from the device's y
    pocket = StrideCues(25.0, 30.0, 0.95, along_thigh)
    gentle = StrideCues(6.0, 8.0, 0.95, (0.05, 0.96, 0.27))               # steady, where the pocket's up was
    held = StrideCues(4.0, 8.0, 0.5, screen_up)                           # steady, turned 44 deg: taken out
    det = PlacementDetector(PlacementDetectConfig(switch_strides=3))
    assert [det.update(pocket) for _ in range(4)] == ["pocket"] * 4
    assert [det.update(gentle) for _ in range(5)] == ["pocket"] * 5
    assert [det.update(held) for _ in range(3)] == ["pocket", "pocket", "hand"]
    restored = PlacementDetector.from_state(det.state())
    assert restored.pocket_up_b == det.pocket_up_b
    # A phone steady for longer than a slow-down (8 strides) while the steps go on is not on a thigh.
    det = PlacementDetector(PlacementDetectConfig(switch_strides=3, pocket_hold_strides=8))
    assert [det.update(pocket) for _ in range(4)] == ["pocket"] * 4
    assert [det.update(gentle) for _ in range(11)] == ["pocket"] * 10 + ["hand"]
    assert PlacementDetector.from_state(det.state()).held_in_pocket == det.held_in_pocket
    # Strides without the mean up direction (cues built by hand) follow the labels alone.
    det = PlacementDetector(PlacementDetectConfig(switch_strides=3))
    assert [det.update(c) for c in [pocket] * 4 + [StrideCues(6.0, 8.0, 0.95)] * 3][-1] == "hand"


def test_a_pause_ends_the_walk_and_the_next_one_settles_afresh():
    along_thigh = (0.0, 0.97, 0.24)
    pocket = StrideCues(25.0, 30.0, 0.95, along_thigh)
    held = StrideCues(6.0, 8.0, 0.95, (0.05, 0.96, 0.27))       # steady, where the pocket's up direction was
    cfg = PlacementDetectConfig(switch_strides=3, pocket_hold_strides=8, pause_s=2.4)

    def walk(det: PlacementDetector, cues: list[StrideCues], t0: float) -> list[str]:
        # One stride per 0.6 s step, steps back to back.
        return [det.update(c, t0 + 0.6 * i, t0 + 0.6 * (i + 1)) for i, c in enumerate(cues)]

    det = PlacementDetector(cfg)
    assert walk(det, [pocket] * 4, 0.0) == ["pocket"] * 4
    # The phone held steady after a 20 s stand: the new walk's first stride decides, no pocket hold.
    assert walk(det, [held] * 3, 22.4) == ["hand"] * 3
    # A gap within a walk (one missed step, 1.7 s) is no pause: the slowed-down pocket keeps its hold.
    det = PlacementDetector(cfg)
    assert walk(det, [pocket] * 4, 0.0) + walk(det, [held] * 3, 4.1) == ["pocket"] * 7
    restored = PlacementDetector.from_state(det.state(), cfg)
    assert restored.state() == det.state() and restored.last_end_s == pytest.approx(5.9)
    # Without times (the strides' cues alone) no pause is seen.
    det = PlacementDetector(cfg)
    assert [det.update(c) for c in [pocket] * 4 + [held] * 3] == ["pocket"] * 7


def test_a_strides_mean_up_direction_is_the_device_frame_vertical():
    # A phone lying flat, screen up: the navigation frame's up axis is the device's z.
    cues = stride_cues(np.tile([1.0, 0.0, 0.0, 0.0], (50, 1)), np.tile([0.0, 0.0, 9.81], (50, 1)), RATE)
    assert cues.up_b == pytest.approx((0.0, 0.0, 1.0))


def test_bad_input_is_refused_with_its_field():
    with pytest.raises(InputError, match="same stride"):
        stride_cues(np.zeros((5, 4)), np.zeros((4, 3)), RATE)
    with pytest.raises(InputError, match="positive"):
        PlacementDetectConfig(switch_strides=0)
