import json

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.fusion.centre import FusionCentre, FusionConfig
from pdr.fusion.ranging import RangeModel
from pdr.fusion.state import FootKey
from pdr.step_increment import StepIncrement

COV = np.diag([1e-4, 1e-4, 1e-4, 1e-5])


def inc(t, dp=(1.0, 0.0, 0.0), dpsi=0.0, index=0):
    return StepIncrement(t, index, np.asarray(dp, float), dpsi, COV)


def two_agents():
    c = FusionCentre()
    c.add_agent("a", [0, 0, 0], 0.0, None, 0.0, [[0, 0.1, 0], [0, -0.1, 0]])
    c.add_agent("b", [0, 10, 0], 0.0, np.diag([1.0, 1.0, 0.0, 0.0]), 0.0)
    return c


def test_initial_uncertainty_is_common_to_the_feet():
    c = two_agents()
    b = [c.state.block(FootKey("b", f)) for f in ("left", "right")]
    np.testing.assert_allclose(c.state.cov[np.ix_(b[0], b[1])], np.diag([1.0, 1.0, 0.0, 0.0]))
    np.testing.assert_allclose(c.state.position(FootKey("a", "left")), [0, 0.1, 0])


def test_steps_propagate_and_the_separation_constraint_holds_the_feet_together():
    c = two_agents()
    for k in range(1, 40):
        c.apply_step("a", "left", inc(float(k), dp=(1.0, 0.0, 0.0), dpsi=0.01))       # left foot turns
        c.apply_step("a", "right", inc(k + 0.5, dp=(1.0, 0.0, 0.0), dpsi=-0.01))  # right foot the other way
    left, right = c.state.position(FootKey("a", "left")), c.state.position(FootKey("a", "right"))
    assert np.linalg.norm(left[:2] - right[:2]) <= 1.0 + 1e-6
    assert c.counts["steps"] == 78 and c.counts["constraints_active"] > 0
    assert c.ranging_foot("a") == FootKey("a", "right")


def test_range_corrects_the_uncertain_agent_and_the_correction_carries_its_feet():
    c = two_agents()
    c.apply_range("a", "b", 8.0)
    corr = c.correction("b")
    assert corr.feet == ("left", "right") and corr.mean.shape == (8,) and corr.cov.shape == (8, 8)
    assert corr.mean[1] < 9.5 and corr.mean[5] < 9.5        # both feet of b moved towards a
    assert corr.cov[1, 1] < 1.0
    assert c.counts["ranges"] == 1


def test_serialised_state_resumes_identically():
    c = two_agents()
    c.apply_step("a", "left", inc(1.0))
    c.apply_range("a", "b", 9.0)
    restored = FusionCentre.from_dict(json.loads(json.dumps(c.to_dict())))
    for centre in (c, restored):
        centre.apply_step("b", "right", inc(1.5, dpsi=0.1))
        centre.apply_range("a", "b", 9.5)
        centre.apply_anchor_range("a", [5.0, -5.0, 0.0], 7.0)
        centre.apply_position_fix("b", [0.5, 9.0], RangeModel(1.0, 1.0))
        centre.apply_height_difference("a", "b", 0.2, RangeModel(0.5, 0.5))
    np.testing.assert_array_equal(c.state.mean, restored.state.mean)
    np.testing.assert_array_equal(c.state.cov, restored.state.cov)
    assert c.counts == restored.counts


def test_configuration_round_trip_and_kalman_reference():
    cfg = FusionConfig(robust=False, kalman_range_variance_m2=2.0)
    assert FusionConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    c = FusionCentre(cfg)
    c.add_agent("a", [0, 0, 0], 0.0, np.diag([1.0, 1.0, 0.0, 0.0]))
    c.add_agent("b", [10, 0, 0])
    c.apply_range("a", "b", 60.0)                                         # Kalman follows an outlier
    assert c.state.position(FootKey("a", "left"))[0] < -10


def test_bad_input_is_reported():
    c = two_agents()
    with pytest.raises(InputError, match="already"):
        c.add_agent("a", [0, 0, 0])
    with pytest.raises(InputError, match="unknown agent"):
        c.apply_range("a", "zz", 3.0)
    with pytest.raises(InputError, match="unknown foot"):
        c.apply_step("a", "middle", inc(1.0))
    with pytest.raises(InputError, match="two different agents"):
        c.apply_range("a", "a", 3.0)
    with pytest.raises(InputError, match="foot offsets"):
        c.add_agent("c", [0, 0, 0], foot_offsets_n=[[0, 0, 0]])
    with pytest.raises(InputError, match="covariance"):
        c.add_agent("d", [0, 0, 0], cov0=np.eye(3))
    with pytest.raises(InputError, match="malformed"):
        FusionCentre.from_dict({"config": {}, "agents": ["a"]})
    with pytest.raises(InputError, match="malformed fusion configuration"):
        FusionConfig.from_dict({"colour": 1})
