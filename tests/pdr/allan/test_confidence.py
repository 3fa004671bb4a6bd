import numpy as np
import pytest

from pdr.allan.confidence import chi2_interval, edf_allan, edf_table
from pdr.allan.estimators import avar_nonoverlapping, avar_overlapping
from pdr.errors import InputError


@pytest.mark.parametrize("alpha", [2, 0, -1, -2])
@pytest.mark.parametrize(("overlapping", "modified"), [(True, False), (False, False), (True, True)])
def test_edf_matches_greenhall_reference(alpha, overlapping, modified):
    at = pytest.importorskip("allantools")
    n = 100_001
    # below m(d+1) <= 100 Greenhall averages the phase over one sample (F = m); our phase is the exact
    # running sum (F = inf), so compare where both use the same kernel, and for the modified one everywhere
    for m in ((1, 3, 30, 1000, 20_000) if modified or alpha == 2 else (34, 100, 1000, 20_000)):
        ref = at.edf_greenhall(alpha=alpha, d=2, m=m, N=n, overlapping=overlapping, modified=modified)
        got = edf_allan(alpha, m, n, overlapping=overlapping, modified=modified)
        assert got == pytest.approx(ref, rel=2e-3)


def test_white_noise_edf_limits():
    # non-overlapping white FM at m=1: consecutive differences correlated -1/2 -> edf close to 2/3 of n
    n = 10_001
    assert edf_allan(0, 1, n, overlapping=False) == pytest.approx((n - 2) * 2 / 3, rel=0.01)
    # overlapping estimates carry more degrees of freedom than disjoint bins
    assert edf_allan(0, 100, n) > edf_allan(0, 100, n, overlapping=False)


@pytest.mark.parametrize(("fn", "overlapping"), [(avar_overlapping, True), (avar_nonoverlapping, False)])
def test_interval_coverage_on_white_noise(fn, overlapping):
    rng = np.random.default_rng(42)
    n, reps = 2000, 300
    m = np.array([5, 50, 200])
    y = rng.standard_normal((n, reps))
    avar, _ = fn(y, m)
    truth = 1.0 / m  # sigma^2 / m for unit white noise
    edf = np.array([edf_allan(0, int(k), n + 1, overlapping=overlapping) for k in m])
    lo, hi = chi2_interval(avar, edf[:, None])
    coverage = np.mean((lo <= truth[:, None]) & (truth[:, None] <= hi), axis=1)
    assert np.all(np.abs(coverage - 0.683) < 0.07), coverage


def test_edf_table_has_every_alpha():
    tab = edf_table([1, 10, 100], 10_000, "overlapping")
    assert set(tab) == {2, 0, -1, -2}
    assert all(v.shape == (3,) and np.all(v > 0) for v in tab.values())


def test_bad_input():
    with pytest.raises(InputError, match="confidence"):
        chi2_interval([1.0], [10.0], confidence=1.5)
    with pytest.raises(InputError, match="alpha=-3"):
        edf_allan(-3, 10, 1000)
    with pytest.raises(InputError, match="too short"):
        edf_allan(0, 600, 1000)
