import numpy as np
import pytest

from pdr.allan import synthetic as sy
from pdr.allan.confidence import edf_table
from pdr.allan.estimators import allan_curve
from pdr.allan.noise_model import TERMS, fit_noise_model, model_avar
from pdr.errors import InputError


def _fit(y, fs, **kw):
    c = allan_curve(y, fs)
    return c, fit_noise_model(c.tau_s, c.avar[:, 0], edf_table(c.m, c.n_samples, c.kind), **kw)


def test_noise_free_model_curve_is_recovered_exactly():
    truth = {"Q": 2e-4, "N": 3e-3, "B": 1e-3, "K": 2e-5, "R": 3e-7}
    tau = np.logspace(-2, 4, 60)
    edf = {a: np.full(tau.size, 1e4) for a in (2, 0, -1, -2)}
    fit = fit_noise_model(tau, model_avar(tau, truth), edf)
    for k in TERMS:
        assert fit.estimate[k] == pytest.approx(truth[k], rel=1e-6)
        assert fit.resolved[k], fit.reason[k]


@pytest.mark.parametrize("bias_model", ["flicker", "gauss_markov_sum"])
def test_simulate_then_recover_n_b_k(bias_model):
    # acceptance: white noise + bias instability + rate random walk -> N, K within 5 %, B within 15 %
    fs, n = 10.0, 2_000_000
    n_true, b_true, k_true = 0.01, 0.01, 0.002  # crossovers near 2 s (N/B) and 33 s (B/K)
    rng = np.random.default_rng(20240601)
    y = sy.white_noise(n, fs, n_true, rng) + sy.random_walk(n, fs, k_true, rng)
    if bias_model == "flicker":
        y += sy.flicker_noise(n, fs, b_true, rng)
    else:
        y += sy.sum_of_gauss_markov(n, fs, b_true, 0.05, n / fs, rng)
    _, fit = _fit(y, fs)
    assert fit.value["N"] == pytest.approx(n_true, rel=0.05)
    assert fit.value["B"] == pytest.approx(b_true, rel=0.15)
    assert fit.value["K"] == pytest.approx(k_true, rel=0.05)
    assert fit.value["Q"] is None


@pytest.mark.slow
def test_recovery_holds_over_many_seeds():
    fs, n = 10.0, 2_000_000
    rel_errs: list[list[float]] = []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        y = (sy.white_noise(n, fs, 0.01, rng) + sy.random_walk(n, fs, 0.002, rng)
             + sy.flicker_noise(n, fs, 0.01, rng))
        _, fit = _fit(y, fs)
        rel_errs.append([fit.estimate["N"] / 0.01 - 1, fit.estimate["B"] / 0.01 - 1, fit.estimate["K"] / 0.002 - 1])
    errs = np.abs(np.array(rel_errs))
    assert np.all(errs[:, 0] < 0.05) and np.all(errs[:, 1] < 0.15) and np.all(errs[:, 2] < 0.05), errs


def test_white_noise_only_leaves_other_terms_unresolved_with_bounds():
    rng = np.random.default_rng(1)
    fs = 100.0
    y = sy.white_noise(200_000, fs, 0.02, rng)
    c, fit = _fit(y, fs)
    assert fit.value["N"] == pytest.approx(0.02, rel=0.02)
    for k in ("B", "K", "R", "Q"):
        assert fit.value[k] is None and fit.reason[k]
    assert "too short" in fit.reason["K"]
    # the bound is consistent with the curve: a K at its upper bound would touch the last points' upper limits
    assert fit.upper_bound["K"] > 0 and fit.upper_bound["K"] ** 2 * c.tau_s[-1] / 3 >= c.avar[-1, 0] * 0.5


def test_short_record_cannot_resolve_random_walk():
    # the same sensor as the recovery test but only 10 minutes: K's +1/2 region never appears
    fs = 10.0
    rng = np.random.default_rng(9)
    n = 6000
    y = sy.white_noise(n, fs, 0.01, rng) + sy.random_walk(n, fs, 0.002, rng) + sy.flicker_noise(n, fs, 0.01, rng)
    _, fit = _fit(y, fs)
    assert fit.value["N"] == pytest.approx(0.01, rel=0.1)
    assert fit.value["K"] is None and "too short" in fit.reason["K"]


def test_random_walk_recovered_from_analytic_gauss_markov_limits():
    # eq. 3 GM with long correlation time looks like a random walk (eq. 4) at tau << gamma
    tau = np.logspace(-1, 1, 20)
    k_equiv = np.sqrt(2.0 * 0.5**2 / 1000.0)  # driving density sqrt(2 sigma^2 / gamma)
    avar = sy.gauss_markov_avar(tau, 0.5, 1000.0)
    fit = fit_noise_model(tau, avar, {a: np.full(20, 1e4) for a in (2, 0, -1, -2)}, terms=("N", "K"))
    assert fit.estimate["K"] == pytest.approx(k_equiv, rel=0.01)


@pytest.mark.parametrize(
    ("tau", "avar", "kw", "match"),
    [
        ([1.0, 2.0], [1.0, 1.0], {}, "at least 3"),
        ([1.0, 2.0, 3.0], [1.0, np.nan, 1.0], {}, "finite"),
        ([1.0, 2.0, 3.0], [1.0, 1.0], {}, "matching"),
        ([1.0, 2.0, 3.0], [1.0, 1.0, 1.0], {"terms": ("N", "X")}, "unknown noise terms"),
    ],
)
def test_bad_input(tau, avar, kw, match):
    edf = {a: np.ones(3) * 10 for a in (2, 0, -1, -2)}
    with pytest.raises(InputError, match=match):
        fit_noise_model(tau, avar, edf, **kw)
