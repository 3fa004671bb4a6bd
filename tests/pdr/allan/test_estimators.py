import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr.allan.estimators import allan_curve, avar_modified, avar_nonoverlapping, avar_overlapping
from pdr.allan.taus import averaging_factors
from pdr.errors import InputError


def _eq1_by_the_book(y, m):
    """Seed 004 eq. 1 written out literally: N disjoint bins, sum of squared differences of bin means."""
    n_bins = len(y) // m
    ybar = [sum(y[i * m:(i + 1) * m]) / m for i in range(n_bins)]
    return sum((ybar[i + 1] - ybar[i]) ** 2 for i in range(n_bins - 1)) / (2 * (n_bins - 1))


def test_nonoverlapping_is_seed_eq1_exactly():
    rng = np.random.default_rng(3)
    y = rng.standard_normal(997) * 0.2 + 1.5
    m = np.array([1, 2, 3, 7, 50, 333, 498])
    got, terms = avar_nonoverlapping(y, m)
    want = [_eq1_by_the_book(list(y), int(k)) for k in m]
    np.testing.assert_allclose(got[:, 0], want, rtol=1e-12)
    np.testing.assert_array_equal(terms, 997 // m - 1)


def test_white_noise_matches_analytic_avar():
    # white noise of per-sample std sigma at rate fs: AVAR(tau) = sigma^2 / (tau fs)
    rng = np.random.default_rng(7)
    fs, sigma = 200.0, 0.3
    y = rng.standard_normal((400_000, 2)) * sigma
    c = allan_curve(y, fs, tau_max_s=20.0)
    truth = sigma**2 / (c.tau_s * fs)
    # overlapping white-FM estimate has roughly n/m degrees of freedom: relative sd ~ sqrt(2 m / n)
    tol = 4.0 * np.sqrt(2.0 * c.m / c.n_samples) + 1e-3
    assert np.all(np.abs(c.avar / truth[:, None] - 1.0) < tol[:, None])


@pytest.mark.parametrize(("kind", "fn"), [("overlapping", "oadev"), ("nonoverlapping", "adev"), ("modified", "mdev")])
def test_agrees_with_allantools(kind, fn):
    at = pytest.importorskip("allantools")
    rng = np.random.default_rng(11)
    n = 30_000
    y = 0.05 * rng.standard_normal(n) + 1e-3 * np.cumsum(rng.standard_normal(n)) / 30 + 0.7
    c = allan_curve(y, 100.0, kind=kind, per_decade=12, tau_max_s=None)
    taus, dev, _, n_terms = getattr(at, fn)(y, rate=100.0, data_type="freq", taus=c.tau_s)
    np.testing.assert_allclose(taus, c.tau_s, rtol=1e-12)
    np.testing.assert_allclose(dev, c.adev[:, 0], rtol=1e-9)
    np.testing.assert_array_equal(n_terms, c.n_terms)


def test_axes_are_independent_columns():
    rng = np.random.default_rng(5)
    y = rng.standard_normal((5000, 3)) * [1.0, 2.0, 0.5]
    m = np.array([1, 4, 16, 64])
    for fn in (avar_nonoverlapping, avar_overlapping, avar_modified):
        both, _ = fn(y, m)
        for a in range(3):
            single, _ = fn(y[:, a], m)
            np.testing.assert_allclose(both[:, a], single[:, 0], rtol=1e-12)


@settings(max_examples=25, deadline=None)
@given(offset=st.floats(-1e3, 1e3), scale=st.floats(1e-3, 1e3), seed=st.integers(0, 2**32 - 1))
def test_offset_invariance_and_quadratic_scaling(offset, scale, seed):
    y = np.random.default_rng(seed).standard_normal(600)
    m = np.array([1, 3, 10, 50])
    for fn in (avar_nonoverlapping, avar_overlapping, avar_modified):
        base, _ = fn(y, m)
        moved, _ = fn(scale * y + offset, m)
        np.testing.assert_allclose(moved, scale**2 * base, rtol=1e-7, atol=1e-12 * scale**2)


def test_modified_white_noise_is_below_overlapping():
    # for white FM, Mod AVAR / AVAR -> 1/2 at large m (SP 1065 Table): a sanity check of the m^4 normalisation
    y = np.random.default_rng(2).standard_normal(200_000)
    m = np.array([64, 256])
    mod, _ = avar_modified(y, m)
    ov, _ = avar_overlapping(y, m)
    np.testing.assert_allclose(mod[:, 0] / ov[:, 0], 0.5, rtol=0.1)


def test_tau_grid_density_and_all():
    m = averaging_factors(100_000, 100.0, per_decade=10)
    assert m[0] == 1 and m[-1] == 25_000
    decades = np.log10(m[-1])
    assert len(m) <= 10 * decades + 1 and np.all(np.diff(m) > 0)
    dense = averaging_factors(100_000, 100.0, per_decade=20)
    assert len(dense) > len(m)
    allm = averaging_factors(1000, 10.0, all_taus=True, tau_max_s=50.0)
    np.testing.assert_array_equal(allm, np.arange(1, 501))


@pytest.mark.parametrize(
    ("samples", "rate", "kwargs", "match"),
    [
        (np.r_[np.zeros(50), np.nan, np.zeros(50)], 10.0, {}, "sample 50 of axis 0 is nan"),
        (np.zeros(3), 10.0, {}, "at least 4"),
        (np.zeros(100), 0.0, {}, "sampling rate"),
        (np.zeros(100), 10.0, {"tau_max_s": 6.0}, "too short for tau = 6 s"),
        (np.zeros(100), 10.0, {"m": [2.5]}, "whole numbers"),
        (np.zeros(100), 10.0, {"m": [51]}, "needs more than the 100 samples"),
        (np.zeros(100), 10.0, {"kind": "hadamard"}, "unknown estimator"),
        (np.zeros((2, 2, 2)), 10.0, {}, "shape"),
        (["a", "b"], 10.0, {}, "not numeric"),
    ],
)
def test_bad_input(samples, rate, kwargs, match):
    with pytest.raises(InputError, match=match):
        allan_curve(samples, rate, **kwargs)
