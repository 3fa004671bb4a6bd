"""Walking direction of a swinging phone: swing-plane axis and the centripetal forward/backward cue."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2, wrap_angle
from pdr.phone.walking_direction import swing_plane_axis, turn_evidence

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


def test_bad_input_is_refused():
    with pytest.raises(InputError, match="attitude"):
        swing_plane_axis(np.zeros((2, 4)), RATE)
    with pytest.raises(InputError, match="specific forces"):
        turn_evidence(np.zeros((4, 2)), 0.1, 0.0)
