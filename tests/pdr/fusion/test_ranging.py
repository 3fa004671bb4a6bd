import numpy as np
import pytest

from pdr.errors import InputError
from pdr.fusion.ranging import (
    RangeModel,
    kalman_range_update,
    range_update,
    sampled_moments,
    square_lattice,
    uniform_cauchy,
)
from pdr.fusion.state import FootKey, GlobalState

A, B = FootKey("a", "left"), FootKey("b", "left")


def pair(var=1.0, distance=10.0):
    s = GlobalState()
    s.add_foot(A, [distance, 0, 0], 0.0, np.diag([var, var, var, 0.01]), 0.0)
    s.add_foot(B, [0, 0, 0], 0.0, np.zeros((4, 4)), 0.0)
    return s


def estimated_range(s):
    return float(np.linalg.norm(s.position(A) - s.position(B)))


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_lattice_reproduces_the_standard_gaussian(dim):
    lat = square_lattice(dim)
    np.testing.assert_allclose(lat.weights @ lat.points, 0.0, atol=1e-12)
    np.testing.assert_allclose((lat.weights[:, None] * lat.points).T @ lat.points, np.eye(dim), atol=1e-12)


def test_flat_likelihood_returns_the_prior():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 3))
    p = a @ a.T
    m = rng.normal(size=3)
    moments = sampled_moments(m, p, lambda s: np.ones(len(s)), square_lattice(3))
    assert moments is not None
    mean, cov = moments
    np.testing.assert_allclose(mean, m, atol=1e-12)
    np.testing.assert_allclose(cov, p, atol=1e-12)


def test_likelihood_eq_20_is_flat_inside_gamma_and_heavy_tailed():
    model = RangeModel(2.0, 0.5)
    inside = uniform_cauchy(10.0, np.array([9.0, 10.0, 11.0]), model)
    assert np.ptp(inside) < 0.15 * inside.max()
    far = uniform_cauchy(10.0, np.array([40.0, 80.0]), model)
    assert far[0] > 0 and far[0] / far[1] == pytest.approx((70 / 30) ** 2, rel=0.05)   # ~ 1/residual^2


def test_robust_update_ignores_a_50_m_outlier_that_a_kalman_update_follows():
    robust, kalman = pair(), pair()
    range_update(robust, A, B, 60.0, RangeModel(2.0, 0.5))
    kalman_range_update(kalman, A, B, 60.0, 1.0)
    assert abs(estimated_range(robust) - 10.0) < 0.1
    assert estimated_range(kalman) - 10.0 == pytest.approx(25.0, rel=1e-6)   # P/(P+R) of the 50 m residual


def test_robust_update_follows_a_consistent_range_like_kalman():
    # Fig. 8: with prior and ranging errors of the same size the update behaves like the Kalman update
    # for residuals of a few standard deviations.
    for r in (12.0, 13.0):
        robust, kalman = pair(), pair()
        range_update(robust, A, B, r, RangeModel(2.0, 0.5))
        kalman_range_update(kalman, A, B, r, 1.0)
        assert 0.3 < (estimated_range(robust) - 10) / (estimated_range(kalman) - 10) < 1.2


def test_small_prior_gives_the_flat_spot_of_figure_8():
    s = pair(var=0.3)
    range_update(s, A, B, 10.5, RangeModel(2.0, 0.5))
    assert abs(estimated_range(s) - 10.0) < 0.05


def test_range_update_moves_only_along_the_line_of_sight_and_shrinks_it():
    s = pair(var=4.0)
    range_update(s, A, B, 8.0, RangeModel(0.5, 0.3))
    assert s.position(A)[0] < 9.0
    assert abs(s.position(A)[1]) < 0.05
    assert s.cov[0, 0] < 1.0 < 2.0 < s.cov[1, 1] <= 4.0


def test_negative_range_is_an_input_error():
    with pytest.raises(InputError, match="non-negative"):
        range_update(pair(), A, B, -1.0, RangeModel())
    with pytest.raises(InputError, match="sigma"):
        RangeModel(1.0, 0.0)
