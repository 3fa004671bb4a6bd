import math

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.fusion.dead_reckoning import propagate_step, step_transition
from pdr.fusion.state import FootKey, GlobalState
from pdr.step_increment import StepIncrement

A = FootKey("a", "left")
B = FootKey("b", "left")


def two_feet():
    s = GlobalState()
    s.add_foot(A, [0, 0, 0], 0.0, np.zeros((4, 4)), 0.0)
    s.add_foot(B, [5, 5, 0], math.pi / 2, np.diag([1.0, 1.0, 1.0, 0.1]), 0.0)
    return s


def step(t, dp, dpsi=0.0, cov=None):
    return StepIncrement(t, 0, np.asarray(dp, float), dpsi, np.zeros((4, 4)) if cov is None else cov)


def test_square_walk_returns_to_the_start():
    s = two_feet()
    for k in range(4):
        propagate_step(s, A, step(k + 1.0, [2.0, 0.0, 0.0], math.pi / 2))
    np.testing.assert_allclose(s.position(A), [0, 0, 0], atol=1e-12)
    assert s.heading(A) == pytest.approx(2 * math.pi)
    assert s.steps.tolist() == [4, 0] and s.t_s[0] == 4.0


def test_displacement_is_rotated_by_the_heading_eq_7():
    s = two_feet()
    propagate_step(s, B, step(1.0, [1.0, 0.0, 0.2]))
    np.testing.assert_allclose(s.position(B), [5, 6, 0.2], atol=1e-12)


def test_other_feet_are_untouched_and_cross_covariances_follow_the_jacobian():
    s = two_feet()
    s.cov[0:4, 4:8] = s.cov[4:8, 0:4] = 0.01
    before = s.cov.copy()
    cov = np.diag([1e-4, 1e-4, 1e-4, 1e-3])
    propagate_step(s, B, step(1.0, [1.0, 0.0, 0.0], 0.0, cov))
    np.testing.assert_allclose(s.cov[0:4, 0:4], before[0:4, 0:4])
    _, jac, cov_w = step_transition(math.pi / 2, np.array([1.0, 0, 0]), 0.0, cov)
    np.testing.assert_allclose(s.cov[4:8, 4:8], jac @ before[4:8, 4:8] @ jac.T + cov_w)
    np.testing.assert_allclose(s.cov[4:8, 0:4], jac @ before[4:8, 0:4])


def test_monte_carlo_spread_matches_the_propagated_covariance():
    # Simulate-then-recover: heading and displacement noise of Sec. 5.1, 100 steps of 1 m.
    rng = np.random.default_rng(0)
    sig_p, sig_h = 0.01, math.radians(0.2)
    cov = np.diag([sig_p**2] * 3 + [sig_h**2])
    finals = []
    for _ in range(400):
        x, chi = np.zeros(3), 0.0
        for _ in range(100):
            dp = np.array([1.0, 0, 0]) + rng.normal(0, sig_p, 3)
            x = x + np.array([[math.cos(chi), -math.sin(chi), 0], [math.sin(chi), math.cos(chi), 0], [0, 0, 1]]) @ dp
            chi += rng.normal(0, sig_h)
        finals.append(np.concatenate([x - [100, 0, 0], [chi]]))
    s = GlobalState()
    s.add_foot(A, [0, 0, 0], 0.0, np.zeros((4, 4)), 0.0)
    for k in range(100):
        propagate_step(s, A, step(k + 1.0, [1.0, 0, 0], 0.0, cov))
    empirical = np.cov(np.array(finals).T)
    for i in range(4):
        assert empirical[i, i] == pytest.approx(s.cov[i, i], rel=0.2)
    # NEES of the Monte Carlo errors under the propagated covariance: mean ~ 4 (the dimension).
    e = np.array(finals)
    nees = np.einsum("ni,ij,nj->n", e, np.linalg.inv(s.cov), e)
    assert 3.4 < nees.mean() < 4.6


def test_bad_increments_are_input_errors():
    s = two_feet()
    with pytest.raises(InputError, match="dp"):
        propagate_step(s, A, step(1.0, [1.0, np.nan, 0.0]))
    with pytest.raises(InputError, match="positive semi-definite"):
        propagate_step(s, A, step(1.0, [1.0, 0.0, 0.0], 0.0, -np.eye(4)))
    with pytest.raises(InputError, match="older"):
        propagate_step(s, A, step(-1.0, [1.0, 0.0, 0.0]))
    with pytest.raises(InputError, match="unknown foot"):
        propagate_step(s, FootKey("c", "left"), step(1.0, [1.0, 0.0, 0.0]))
