"""Chi-square quantiles without scipy (pdr.chi_square): against scipy.stats.chi2.ppf, the textbook points, and the
refused arguments."""

import numpy as np
import pytest

from pdr.chi_square import chi2_quantile


def test_chi2_quantile_matches_scipy_stats_chi2_ppf():
    from scipy.stats import chi2
    rng = np.random.default_rng(3)
    for q in (1e-6, 0.01, 0.3, 0.5, 0.9, 0.95, 0.99, 0.999):
        for dof in [0.1, 0.5, 1.0, 2.0, 7.0, *rng.uniform(1.0, 5000.0, 60)]:
            assert chi2_quantile(q, dof) == pytest.approx(float(chi2.ppf(q, dof)), rel=1e-13)


def test_textbook_points_and_closed_forms():
    assert chi2_quantile(0.95, 1.0) == pytest.approx(3.841459, abs=1e-6)
    assert chi2_quantile(0.99, 1.0) == pytest.approx(6.634897, abs=1e-6)
    # Two degrees of freedom: an exponential of mean 2, so the quantile is -2 ln(1 - q).
    for q in (0.1, 0.5, 0.99):
        assert chi2_quantile(q, 2.0) == pytest.approx(-2.0 * np.log1p(-q), rel=1e-14)


@pytest.mark.parametrize(("q", "dof"), [(-0.1, 1.0), (1.5, 1.0), (0.5, 0.0), (float("nan"), 1.0), (0.5, -2.0)])
def test_arguments_outside_the_domain_are_refused(q, dof):
    with pytest.raises(ValueError, match="0 <= q <= 1"):
        chi2_quantile(q, dof)


def test_the_ends_are_zero_and_infinity_as_in_scipy():
    assert chi2_quantile(0.0, 3.0) == 0.0 and chi2_quantile(1.0, 3.0) == float("inf")
