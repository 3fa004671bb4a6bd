import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr.errors import InputError
from pdr.fusion.constraints import (
    SeparationConfig,
    constrained_moments,
    project_to_ball,
    separation_constraint,
    sigma_points,
)


def test_sigma_points_reproduce_mean_and_covariance():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(3, 3))
    p = a @ a.T
    m = rng.normal(size=3)
    pts, w = sigma_points(m, p, 4.0)
    assert pts.shape == (7, 3) and w.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(w @ pts, m, atol=1e-12)
    d = pts - m
    np.testing.assert_allclose((w[:, None] * d).T @ d, p, atol=1e-12)


def test_projection_eq_15():
    pts = np.array([[0.5, 0, 0], [3.0, 4.0, 0.0], [0, 0, -2.0]])
    out = project_to_ball(pts, 1.0)
    np.testing.assert_allclose(out, [[0.5, 0, 0], [0.6, 0.8, 0.0], [0, 0, -1.0]])


def test_inactive_when_the_prior_is_well_inside():
    assert constrained_moments(np.zeros(3), 0.01 * np.eye(3), 1.0, 4.0) is None


def feet_state(sep, var_a, var_b):
    x = np.array([0.0, 0, 0, 0, sep, 0, 0, 0])
    p = np.diag([var_a] * 3 + [0.01] + [var_b] * 3 + [0.01])
    return x, p


def test_feet_drifted_apart_are_pulled_together_and_the_uncertain_foot_moves_most():
    x, p = feet_state(3.0, 0.01, 1.0)
    x2, p2, active = separation_constraint(x, p, [0, 1, 2], [4, 5, 6], 1.0, 0.5)
    assert active
    assert np.linalg.norm(x2[4:7] - x2[0:3]) <= 1.0 + 1e-9
    assert abs(x2[4] - 3.0) > 10 * abs(x2[0])       # the precise foot barely moves
    assert p2[4, 4] < p[4, 4]                        # along the separation the uncertainty shrinks
    assert np.all(np.linalg.eigvalsh(p2) > -1e-12)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 20.0), st.floats(1e-4, 25.0), st.floats(1e-4, 25.0), st.floats(0.3, 2.0))
def test_posterior_mean_separation_is_within_the_bound(sep, var_a, var_b, gamma):
    x, p = feet_state(sep, var_a, var_b)
    x2, p2, _ = separation_constraint(x, p, [0, 1, 2], [4, 5, 6], gamma, gamma)
    assert np.linalg.norm(x2[4:7] - x2[0:3]) <= max(gamma, 0.0) + 1e-6
    assert np.all(np.isfinite(p2)) and np.min(np.linalg.eigvalsh(p2)) > -1e-9


def test_vertical_bound_is_scaled_by_d_gamma():
    x = np.array([0.0, 0, 0, 0, 0.0, 0, 0.5, 0])       # 0.5 m vertical, 0 horizontal
    p = np.diag([0.01, 0.01, 0.01, 0.0] * 2)
    x_loose, _, active_loose = separation_constraint(x, p, [0, 1, 2], [4, 5, 6], 1.0, 1.0)
    x_tight, _, active_tight = separation_constraint(x, p, [0, 1, 2], [4, 5, 6], 1.0, 0.3)
    assert not active_loose and active_tight
    assert abs(x_tight[6] - x_tight[2]) <= 0.3 + 1e-9


def test_config_widens_with_asynchrony_and_rejects_bad_values():
    cfg = SeparationConfig(gamma_xy=1.0, gamma_z=0.5, speed_bound_mps=1.5, grace_s=1.0)
    assert cfg.bounds(0.5) == (1.0, 0.5)
    assert cfg.bounds(-3.0) == pytest.approx((4.0, 3.5))
    with pytest.raises(InputError, match="eta"):
        SeparationConfig(eta=2.0)
    with pytest.raises(InputError, match="gamma_z"):
        SeparationConfig(gamma_z=0.0)
