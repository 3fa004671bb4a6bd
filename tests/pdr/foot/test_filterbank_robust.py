"""Filter bank: branch likelihood densities, clipped-gyroscope process noise (issue #5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from pdr.errors import InputError
from pdr.evaluation.foot_metrics import pyshoe_armse
from pdr.foot.detectors import detect
from pdr.foot.filterbank import FilterBankConfig, _log_density, run_filterbank
from pdr.foot.navigate import foot_imu
from pdr.io import read_recording
from tests.conftest import data_path


@pytest.mark.parametrize("nu", [0.0, 1.0, 4.0, 30.0])
def test_branch_density_is_the_normal_or_student_t(nu: float) -> None:
    rng = np.random.default_rng(5)
    a = rng.standard_normal((4, 4))
    S = a @ a.T + 0.5 * np.eye(4)
    e = 3.0 * rng.standard_normal(4)
    chi2 = float(e @ np.linalg.solve(S, e))
    logdet = float(np.linalg.slogdet(S)[1])
    ref = (stats.multivariate_normal(np.zeros(4), S).logpdf(e) if nu == 0.0
           else stats.multivariate_t(np.zeros(4), S, df=nu).logpdf(e))
    assert _log_density(4, logdet, chi2, nu) == pytest.approx(ref, rel=1e-10)


def test_bad_configuration() -> None:
    with pytest.raises(InputError):
        FilterBankConfig(clip_excess=-0.1)
    with pytest.raises(InputError):
        FilterBankConfig(student_nu=0.0)
    with pytest.raises(InputError):
        FilterBankConfig(clip_excess=math.nan)


def _pyshoe_armse(trial: str, *configs: FilterBankConfig) -> list[float]:
    """PyShoe ARMSE (m) of the filter bank on one VICON trial, per configuration."""
    rec = read_recording(data_path("pyshoe_vicon", trial))
    imu = foot_imu(rec)
    zv = detect(imu.acc_b, imu.gyro_b, imu.rate_hz)
    truth = rec.truth.positions
    assert truth is not None
    err = []
    for cfg in configs:
        tr = run_filterbank(imu.t_s, imu.acc_b, imu.gyro_b, zv, cfg)
        est = np.stack([np.interp(truth.t_s, tr.t_s, tr.pos_n[:, i]) for i in range(2)], axis=1)
        err.append(pyshoe_armse(est, truth.pos_m[:, :2]))
    return err


@pytest.mark.data
@pytest.mark.slow
def test_clip_noise_keeps_the_stances_of_a_clipped_running_trial() -> None:
    # PyShoe 2017-11-27-11-11-53: running, the pitch rate clipped in 20 swings. Without the attitude noise of the
    # clipped samples the speed filter bank loses the stances and runs away (14 m); with it, ZUPT-like accuracy.
    err = _pyshoe_armse("2017-11-27-11-11-53.mat", FilterBankConfig(variant="speed", clip_excess=0.0),
                        FilterBankConfig(variant="speed"))
    assert err[0] > 1.0
    assert err[1] < 0.08


def test_lost_stance_settings_are_checked() -> None:
    with pytest.raises(InputError, match="max_swing_s"):
        FilterBankConfig(max_swing_s=-1.0)
    with pytest.raises(InputError, match="lost_sigma_v"):
        FilterBankConfig(lost_sigma_v=0.0)


def _spin_after_rest(rate: float = 100.0, rest_s: float = 1.0, spin_s: float = 4.0) -> tuple[np.ndarray, ...]:
    """A foot at rest, then spinning about the vertical at 3 rad/s (never a stance) with gravity only."""
    n_rest, n_spin = int(rest_s * rate), int(spin_s * rate)
    t = np.arange(n_rest + n_spin) / rate
    acc = np.tile([0.0, 0.0, 9.81], (t.size, 1))
    gyro = np.zeros((t.size, 3))
    gyro[n_rest:, 2] = 3.0
    zv = np.zeros(t.size, dtype=bool)
    zv[:n_rest] = True
    return t, acc, gyro, zv


def test_a_swing_longer_than_max_swing_reopens_the_velocity_variance() -> None:
    t, acc, gyro, zv = _spin_after_rest()
    on = run_filterbank(t, acc, gyro, zv, FilterBankConfig(max_swing_s=1.5, lost_sigma_v=1.0))
    off = run_filterbank(t, acc, gyro, zv, FilterBankConfig(max_swing_s=0.0))
    assert np.all(on.mode[150:] == 0) and np.all(off.mode[150:] == 0)      # the spin is a swing throughout
    spin_start = 100
    before = slice(spin_start + 20, spin_start + 140)                      # within 1.5 s of the swing's start
    after = slice(spin_start + 160, None)                                  # later than 1.5 s
    np.testing.assert_array_equal(on.vel_var[before], off.vel_var[before])
    assert np.all(on.vel_var[after] >= 1.0 - 1e-9)
    assert np.all(off.vel_var[after] < 0.1)


@pytest.mark.data
@pytest.mark.slow
def test_lost_stances_are_recovered_on_a_running_trial() -> None:
    # PyShoe 2017-11-27-11-24-07: running. With the seed's memoryless model the speed bank loses its stances after
    # a few strides and integrates freely (13 m); reopening the velocities after a 1.5 s swing recovers them.
    err = _pyshoe_armse("2017-11-27-11-24-07.mat", FilterBankConfig(max_swing_s=0.0), FilterBankConfig())
    assert err[0] > 5.0
    assert err[1] < 1.0
