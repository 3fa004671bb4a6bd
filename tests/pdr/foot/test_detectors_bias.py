"""Gyroscope bias from the still samples of a recording (pdr.foot.detectors.stationary_gyro_bias)."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.foot.detectors import stationary_gyro_bias
from pdr.foot.zupt import ZuptConfig, run_zupt
from tests.pdr.foot.gait import simulate_gait


def test_bias_is_recovered_from_the_stances_and_removing_it_stops_the_heading_drift() -> None:
    bias = np.radians([0.05, -0.03, 0.2])
    g = simulate_gait(n_strides=10, stance_s=0.6, sigma_acc=0.003, sigma_gyro=0.0005, seed=2)
    gyro = g.gyro_b + bias
    est = stationary_gyro_bias(g.acc_b, gyro, 200.0)
    np.testing.assert_allclose(est, bias, atol=np.radians(0.005))
    cfg = ZuptConfig(hde_directions=0)
    raw = run_zupt(g.t_s, g.acc_b, gyro, g.stance, cfg)
    fixed = run_zupt(g.t_s, g.acc_b, gyro - est, g.stance, cfg)
    assert abs(fixed.yaw[-1] - g.yaw[-1]) < 0.1 * abs(raw.yaw[-1] - g.yaw[-1])


def test_no_estimate_without_enough_still_samples() -> None:
    g = simulate_gait(n_strides=3, sigma_acc=1.0, sigma_gyro=0.1, seed=1)
    np.testing.assert_array_equal(stationary_gyro_bias(g.acc_b, g.gyro_b + 0.01, 200.0), np.zeros(3))


def test_bad_input() -> None:
    g = simulate_gait(n_strides=1)
    with pytest.raises(InputError, match="sampling rate"):
        stationary_gyro_bias(g.acc_b, g.gyro_b, 0.0)
    with pytest.raises(InputError, match="expected shape"):
        stationary_gyro_bias(g.acc_b, g.gyro_b[:, :2], 200.0)
