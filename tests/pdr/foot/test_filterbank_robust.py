"""Filter bank: branch likelihood densities, clipped-gyroscope process noise (issue #5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from pdr.errors import InputError
from pdr.foot.detectors import detect
from pdr.foot.filterbank import FilterBankConfig, _log_density, run_filterbank
from pdr.foot.metrics import pyshoe_armse
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


@pytest.mark.data
@pytest.mark.slow
def test_clip_noise_keeps_the_stances_of_a_clipped_running_trial() -> None:
    # PyShoe 2017-11-27-11-11-53: running, the pitch rate clipped in 20 swings. Without the attitude noise of the
    # clipped samples the speed filter bank loses the stances and runs away (14 m); with it, ZUPT-like accuracy.
    rec = read_recording(data_path("pyshoe_vicon", "2017-11-27-11-11-53.mat"))
    imu = foot_imu(rec)
    zv = detect(imu.acc_b, imu.gyro_b, imu.rate_hz)
    truth = rec.truth.positions
    assert truth is not None
    err = []
    for cfg in (FilterBankConfig(variant="speed", clip_excess=0.0), FilterBankConfig(variant="speed")):
        tr = run_filterbank(imu.t_s, imu.acc_b, imu.gyro_b, zv, cfg)
        est = np.stack([np.interp(truth.t_s, tr.t_s, tr.pos_n[:, i]) for i in range(2)], axis=1)
        err.append(pyshoe_armse(est, truth.pos_m[:, :2]))
    assert err[0] > 1.0
    assert err[1] < 0.08
