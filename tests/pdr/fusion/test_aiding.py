import numpy as np
import pytest

from pdr.errors import InputError
from pdr.frames import altitude_to_pressure_hpa
from pdr.fusion.aiding import (
    anchor_range_update,
    height_difference_update,
    position_fix_update,
    pressure_height_difference,
)
from pdr.fusion.ranging import RangeModel
from pdr.fusion.state import FootKey, GlobalState

A, B = FootKey("a", "left"), FootKey("b", "left")


def single(pos, var):
    s = GlobalState()
    s.add_foot(A, pos, 0.0, np.diag([var, var, var, 0.01]), 0.0)
    return s


def test_ranges_to_three_anchors_recover_the_position():
    # Simulate then recover: the foot is at (3, 4, 0); the prior is 2 m off with 2 m sigma.
    rng = np.random.default_rng(2)
    truth = np.array([3.0, 4.0, 0.0])
    anchors = [np.array([0.0, 0, 0]), np.array([20.0, 0, 0]), np.array([0.0, 20, 0]), np.array([0, 0, 5.0])]
    s = single(truth + [2.0, -1.5, 0.0], 4.0)
    model = RangeModel(0.2, 0.1)
    for _ in range(10):
        for a in anchors:
            anchor_range_update(s, A, a, float(np.linalg.norm(truth - a)) + rng.normal(0, 0.05), model)
    assert np.linalg.norm(s.position(A) - truth) < 0.3


def test_position_fix_is_a_zero_range_and_ignores_a_far_outlier():
    s = single([0.0, 0.0, 0.0], 4.0)
    position_fix_update(s, A, [1.0, 1.0], RangeModel(0.5, 0.5))
    assert 0.3 < s.position(A)[0] < 1.2 and s.position(A)[2] == 0.0
    s2 = single([0.0, 0.0, 0.0], 1.0)
    position_fix_update(s2, A, [80.0, 0.0], RangeModel(1.0, 1.0))
    assert abs(s2.position(A)[0]) < 0.1
    with pytest.raises(InputError, match="2 coordinates"):
        position_fix_update(s, A, [1.0, 2.0, 3.0], RangeModel())


def test_height_difference_is_signed():
    s = GlobalState()
    s.add_foot(A, [0, 0, 0], 0.0, np.diag([0.01, 0.01, 4.0, 0.01]), 0.0)
    s.add_foot(B, [10, 0, 0], 0.0, np.diag([0.01, 0.01, 0.01, 0.01]), 0.0)
    height_difference_update(s, A, B, 3.0, RangeModel(0.2, 0.2))        # A is 3 m above B
    assert 2.0 < s.position(A)[2] < 3.3 and abs(s.position(B)[2]) < 0.1
    s2 = single([0.0, 0.0, 0.0], 1.0)
    height_difference_update(s2, A, None, -2.0, RangeModel(0.2, 0.2), reference_height_m=0.5)
    assert s2.position(A)[2] < -0.5


def test_pressure_height_difference_uses_the_standard_atmosphere():
    p_ground = 1000.0
    p_up = float(altitude_to_pressure_hpa(3.5, p0_hpa=p_ground))
    assert pressure_height_difference(p_up, p_ground) == pytest.approx(3.5, abs=1e-6)
    assert pressure_height_difference(p_ground, p_up) == pytest.approx(-3.5, abs=0.01)
    with pytest.raises(InputError, match="hPa"):
        pressure_height_difference(-1.0, 1000.0)
