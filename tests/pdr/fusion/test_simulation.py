import numpy as np
import pytest

from pdr.errors import InputError
from pdr.evaluation.coop import (
    cost_experiment,
    fit_power_law,
    influence_function,
    kalman_config,
    march_experiment,
    static_experiment,
)
from pdr.fusion.centre import FusionConfig
from pdr.fusion.simulation import SimulationConfig, march_scenario, run_scenario, static_circle_scenario
from pdr.fusion.state import FootKey


def test_noise_free_scenario_is_recovered_exactly():
    cfg = SimulationConfig(step_sigma_m=0.0, heading_sigma_deg=0.0, range_scale_m=0.0)
    for scenario in (march_scenario(3, 30, cfg, np.random.default_rng(0)),
                     static_circle_scenario(40, cfg, np.random.default_rng(0))):
        res = run_scenario(scenario)
        for e in res.error.values():
            assert np.nanmax(np.abs(e)) < 1e-6


def test_truth_follows_the_seed_gait():
    scenario = march_scenario(2, 10, SimulationConfig(), np.random.default_rng(0))
    left, right = scenario.truth[FootKey("a0", "left")], scenario.truth[FootKey("a0", "right")]
    np.testing.assert_allclose(np.diff(left.t_s), 1.0)
    np.testing.assert_allclose(right.t_s[1:3], [0.5, 1.5])
    np.testing.assert_allclose(np.linalg.norm(np.diff(left.pos_n, axis=0), axis=1), 1.0)
    assert len(scenario.ranges) == 10 and {r[1:3] for r in scenario.ranges} == {("a0", "a1")}
    np.testing.assert_allclose([r[4] for r in scenario.ranges], 10.0)


def test_fit_power_law_recovers_an_exponent():
    n = np.array([1, 2, 4, 8])
    p, c = fit_power_law(n, 3.0 * n**-0.5)
    assert p == pytest.approx(0.5) and c == pytest.approx(3.0)


def test_small_march_error_falls_with_the_group_and_relative_error_stays_bounded():
    # The seed's march at smaller scale (fewer runs, 120 m): absolute RMSE falls with N, relative bounded.
    r = march_experiment((1, 4), duration_s=120, runs=8, seed=1)
    assert r.abs_rmse_m[1, -1] < 0.8 * r.abs_rmse_m[0, -1]
    assert np.max(r.rel_rmse_m[1]) < 1.5
    assert np.max(r.rel_rmse_m[1]) < 0.5 * r.abs_rmse_m[0, -1]


def test_small_static_scenario_is_bounded_while_dead_reckoning_drifts():
    r = static_experiment(duration_s=240, runs=4, seed=2)
    third = r.t_s.size // 3
    assert np.max(r.rmse_m) < 2.0
    assert np.mean(r.rmse_m[2 * third:]) < 1.5 * np.mean(r.rmse_m[third:2 * third])
    assert r.rmse_m[-1] < 0.6 * r.rmse_dead_reckoning_m[-1]
    assert r.static_rmse_m < 1e-6


def test_robust_fusion_beats_kalman_with_cauchy_ranges():
    sc = [march_scenario(2, 100, SimulationConfig(), np.random.default_rng([7, k])) for k in range(6)]
    rel = {}
    for name, cfg in (("robust", FusionConfig()), ("kalman", kalman_config())):
        sq = []
        for s in sc:
            res = run_scenario(s, cfg)
            e = np.stack([res.error[FootKey(a, "left")][-30:] for a in s.agents])
            sq.append(np.mean(np.sum((e[0] - e[1]) ** 2, axis=-1)))
        rel[name] = np.sqrt(np.mean(sq))
    assert rel["robust"] < 0.7 * rel["kalman"]


def test_monte_carlo_nees_of_the_fused_pair_is_consistent():
    # NEES of the two agents' relative position (the ranged quantity) over runs, from the filter covariance.
    nees = []
    for k in range(12):
        s = march_scenario(2, 60, SimulationConfig(), np.random.default_rng([11, k]))
        res = run_scenario(s)
        st = res.centre.state
        ia = st.position_indices(FootKey("a0", "left"))
        ib = st.position_indices(FootKey("a1", "left"))
        e = res.error[FootKey("a0", "left")][-1] - res.error[FootKey("a1", "left")][-1]
        p = st.cov[np.ix_(ia, ia)] + st.cov[np.ix_(ib, ib)] - st.cov[np.ix_(ia, ib)] - st.cov[np.ix_(ib, ia)]
        nees.append(float(e @ np.linalg.solve(p, e)))
    # chi-square with 3 dof: mean 3; loose bounds for 12 runs and a non-Gaussian (Cauchy) range model
    assert 0.5 < np.mean(nees) < 9.0


def test_influence_function_of_figure_8():
    r = influence_function(np.array([0.0, 2.0, 50.0]))
    i50 = 2
    assert abs(r.robust_m[0, i50]) < 0.1 and r.kalman_m[0, i50] == pytest.approx(25.0, rel=1e-6)
    assert r.robust_m[0, 1] > 0.3                            # P = I: follows a 2 m residual
    assert abs(r.robust_m[1, 0]) < 0.02                      # P = 0.3 I: flat spot in the middle


def test_cost_counts_the_seed_message_sizes_and_keeps_up():
    c = cost_experiment((2, 4), duration_s=10)
    np.testing.assert_allclose(c.downlink_values_per_s, 8.0)          # 4 values per foot step, 2 feet at 1 Hz
    assert np.all((c.uplink_values_per_s > 28.0) & (c.uplink_values_per_s < 29.0))   # 14 per step + ranges
    assert np.all(c.realtime_factor < 0.5)


def test_monte_carlo_runs_give_the_same_figures_in_parallel():
    serial = march_experiment((1, 2), duration_s=20, runs=3, seed=4)
    forked = march_experiment((1, 2), duration_s=20, runs=3, seed=4, workers=2)
    for name in ("abs_rmse_m", "rel_rmse_m", "correlation_mc", "correlation_filter"):
        assert np.array_equal(getattr(serial, name), getattr(forked, name), equal_nan=True), name
    s1, s2 = (static_experiment(duration_s=20, runs=2, seed=5, workers=w) for w in (1, 2))
    assert np.array_equal(s1.rmse_m, s2.rmse_m) and np.array_equal(s1.rmse_dead_reckoning_m, s2.rmse_dead_reckoning_m)
    assert s1.static_rmse_m == s2.static_rmse_m and np.array_equal(s1.t_s, s2.t_s)
    with pytest.raises(InputError, match="workers"):
        static_experiment(duration_s=20, runs=2, workers=0)


@pytest.mark.slow
def test_full_march_exponent_is_one_half():
    r = march_experiment((1, 2, 4, 8), duration_s=200, runs=12, seed=0, workers=2)  # 0.51 (0.44 with 10 runs)
    assert 0.35 <= r.exponent <= 0.65
    assert np.max(r.rel_rmse_m[1:]) < 1.5


@pytest.mark.slow
def test_full_static_scenario_is_bounded():
    r = static_experiment(duration_s=600, runs=20, seed=0, workers=2)
    third = r.t_s.size // 3
    assert np.max(r.rmse_m) < 2.5
    assert np.mean(r.rmse_m[2 * third:]) < 1.3 * np.mean(r.rmse_m[third:2 * third])
