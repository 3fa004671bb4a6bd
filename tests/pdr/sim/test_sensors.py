import math

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.sim.sensors import GRADES, ErrorModel, apply, flicker, gauss_markov, random_walk

RATE = 100.0


def _t(n):
    return np.arange(n) / RATE


def _allan(x, m):
    """Non-overlapping Allan deviation (seed 004 eq. 1) for clusters of m samples."""
    k = x.size // m
    means = x[: k * m].reshape(k, m).mean(axis=1)
    return math.sqrt(0.5 * np.mean(np.diff(means) ** 2))


def test_ideal_model_changes_nothing():
    x = np.random.default_rng(0).normal(size=(500, 3))
    np.testing.assert_array_equal(apply(GRADES["ideal"]["gyro"], x, _t(500), np.random.default_rng(1)), x)


def test_white_noise_std_follows_density():
    n = 200_000
    y = apply(ErrorModel(white_noise_density=0.01), np.zeros((n, 3)), _t(n), np.random.default_rng(2))
    np.testing.assert_allclose(y.std(axis=0), 0.01 * math.sqrt(RATE), rtol=0.01)
    # white noise: Allan deviation falls as 1/sqrt(tau) with N = density
    assert _allan(y[:, 0], 100) == pytest.approx(0.01 / math.sqrt(1.0), rel=0.05)


def test_turn_on_bias_is_constant_and_has_the_given_spread():
    biases = []
    for seed in range(300):
        y = apply(ErrorModel(bias_sigma=0.2), np.zeros((50, 3)), _t(50), np.random.default_rng(seed))
        np.testing.assert_allclose(y, np.broadcast_to(y[0], y.shape))
        biases.append(y[0])
    assert np.std(biases) == pytest.approx(0.2, rel=0.1)


def test_gauss_markov_std_and_correlation_time():
    tau, sigma = 2.0, 0.3
    x = gauss_markov(400_000, 1 / RATE, sigma, tau, 1, np.random.default_rng(3))[:, 0]
    assert x.std() == pytest.approx(sigma, rel=0.05)
    lag = int(tau * RATE)
    rho = np.corrcoef(x[:-lag], x[lag:])[0, 1]
    assert -1.0 / math.log(rho) * tau == pytest.approx(tau, rel=0.15)   # exp(-dt/tau) at dt = tau
    # lag-1 AR coefficient of eq. 3
    phi = np.dot(x[:-1], x[1:]) / np.dot(x[:-1], x[:-1])
    assert -1 / RATE / math.log(phi) == pytest.approx(tau, rel=0.15)


def test_rate_random_walk_variance_grows_linearly():
    k = 0.05
    x = np.stack([random_walk(1001, 1 / RATE, k, 1, np.random.default_rng(s))[:, 0] for s in range(400)])
    assert x[:, -1].var() == pytest.approx(k**2 * 10.0, rel=0.15)
    assert x[:, 500].var() == pytest.approx(k**2 * 5.0, rel=0.15)


def test_flicker_noise_has_a_flat_allan_floor_at_0664_b():
    b = 0.01
    x = flicker(2**18, 1 / RATE, b, 1, np.random.default_rng(5))[:, 0]
    devs = [_allan(x, m) for m in (100, 400, 1600)]
    for d in devs:
        assert d == pytest.approx(0.664 * b, rel=0.3)
    # 1/f: log-log PSD slope about -1 over two decades
    f = np.fft.rfftfreq(x.size, 1 / RATE)
    psd = np.abs(np.fft.rfft(x)) ** 2
    band = (f > 0.01) & (f < 1.0)
    slope = np.polyfit(np.log(f[band]), np.log(psd[band]), 1)[0]
    assert -1.3 < slope < -0.7


def test_scale_factor_and_misalignment_recovered_by_regression():
    rng = np.random.default_rng(6)
    x = rng.normal(0, 5, (5000, 3))
    y = apply(ErrorModel(scale_factor_sigma=0.02, misalignment_sigma=0.01), x, _t(5000), np.random.default_rng(7))
    m, *_ = np.linalg.lstsq(x, y, rcond=None)
    matrix = m.T
    assert np.all(np.abs(np.diag(matrix) - 1) < 0.08) and np.any(np.abs(np.diag(matrix) - 1) > 1e-4)
    off = matrix[~np.eye(3, dtype=bool)]
    assert np.all(np.abs(off) < 0.05) and np.any(np.abs(off) > 1e-5)


def test_quantisation_to_lsb():
    y = apply(ErrorModel(white_noise_density=0.1, quantization_step=0.05), np.zeros((1000, 3)), _t(1000),
              np.random.default_rng(8))
    np.testing.assert_allclose(y / 0.05, np.round(y / 0.05), atol=1e-9)


def test_same_generator_state_same_errors():
    m = GRADES["consumer"]["gyro"]
    a = apply(m, np.zeros((300, 3)), _t(300), np.random.default_rng(9))
    b = apply(m, np.zeros((300, 3)), _t(300), np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)


def test_bad_parameters_raise_input_error():
    with pytest.raises(InputError, match="white_noise_density"):
        ErrorModel(white_noise_density=-1.0)
    with pytest.raises(InputError, match="bias_instability_model"):
        ErrorModel(bias_instability_model="pink")
    with pytest.raises(InputError, match="unknown error parameter"):
        ErrorModel().with_overrides({"noise": 1.0})
