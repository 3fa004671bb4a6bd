import numpy as np
import pytest

from pdr.allan.noise_model import FLICKER_FACTOR, model_avar
from pdr.allan.slopes import local_slopes, read_slopes
from pdr.errors import InputError


def test_readings_on_an_analytic_u_curve():
    tau = np.logspace(-2, 6, 100)
    truth = {"N": 1e-3, "B": 1e-4, "K": 2e-6}
    adev = np.sqrt(model_avar(tau, truth))
    r = read_slopes(tau, adev)
    assert r.N == pytest.approx(1e-3, rel=0.02)
    assert r.K == pytest.approx(2e-6, rel=0.05)
    # minimum / 0.664 over-reads B where white and RRW still add to the floor
    assert r.B is not None and 1.0 <= r.B / 1e-4 < 1.3
    assert r.adev_min == pytest.approx(adev.min())


def test_pure_slopes_are_exact():
    tau = np.logspace(-1, 3, 30)
    assert np.allclose(local_slopes(tau, 2.0 / np.sqrt(tau)), -0.5)
    r = read_slopes(tau, np.sqrt(model_avar(tau, {"N": 2e-3, "B": 0.0, "K": 0.0})))
    assert r.N == pytest.approx(2e-3, rel=1e-9)
    assert r.B is None and r.K is None
    assert any("still falling" in n for n in r.notes) and any("+1/2" in n for n in r.notes)


def test_flat_floor_reads_b():
    tau = np.logspace(-1, 3, 30)
    adev = np.full(30, 0.5 * FLICKER_FACTOR)
    adev[0] *= 1.5
    adev[-1] *= 1.5
    assert read_slopes(tau, adev).B == pytest.approx(0.5)


def test_bad_input():
    with pytest.raises(InputError, match="positive"):
        read_slopes([1.0, 2.0, 3.0], [1.0, 0.0, 1.0])
    with pytest.raises(InputError, match="matching"):
        read_slopes([1.0, 2.0], [1.0, 2.0])


def test_minimum_ignores_unreliable_long_tau_points():
    tau = np.logspace(-1, 3, 30)
    adev = np.sqrt(model_avar(tau, {"N": 1e-2, "B": 1e-3, "K": 1e-4}))
    adev[-1] = adev.min() / 3  # a noisy dip at the last point, 2 degrees of freedom
    edf = np.linspace(1e5, 2, 30)
    assert read_slopes(tau, adev).tau_min_s == tau[-1]
    r = read_slopes(tau, adev, edf=edf)
    assert r.tau_min_s < tau[-1] and r.B is not None
