"""Heuristic drift elimination shared by the foot navigators (pdr.foot.drift): simulate a drifting gyro, recover."""

from collections.abc import Callable

import numpy as np
import pytest

from pdr.foot.bc import BCConfig, run_bc
from pdr.foot.detectors import detect
from pdr.foot.filterbank import FilterBankConfig, run_filterbank
from pdr.foot.zupt import ZuptConfig, run_zupt
from pdr.frames import wrap_angle
from tests.pdr.foot.gait import gyro_drift_walk

RUNS: dict[str, Callable] = {
    "zupt": lambda t, f, w, zv, z: run_zupt(t, f, w, zv, z),
    "filterbank": lambda t, f, w, zv, z: run_filterbank(t, f, w, zv, FilterBankConfig(zupt=z)),
    "filterbank-height": lambda t, f, w, zv, z: run_filterbank(t, f, w, zv, FilterBankConfig("height", zupt=z)),
    "bc": lambda t, f, w, zv, z: run_bc(t, f, w, zv, BCConfig(hde=z)),
}


@pytest.mark.parametrize("method", list(RUNS))
def test_shared_drift_elimination_removes_gyro_drift(method: str) -> None:
    # 0.15 deg/s of heading drift on a 56 m, 45 s straight walk: about 6.6 deg of heading error and the end 3.2 m
    # off without the drift elimination, whatever the navigator; with the same shared drift elimination every
    # navigator (its own stance decision, the merged or condensed estimate) ends within 1 deg and 1.5 %.
    g, gyro = gyro_drift_walk(0.15)
    dist = 40 * 1.4
    zv = detect(g.acc_b, gyro, 200.0)
    off = RUNS[method](g.t_s, g.acc_b, gyro, zv, ZuptConfig(hde_directions=0))
    on = RUNS[method](g.t_s, g.acc_b, gyro, zv, ZuptConfig())
    err_off = np.linalg.norm(off.pos_n[-1, :2] - g.pos_n[-1, :2])
    err_on = np.linalg.norm(on.pos_n[-1, :2] - g.pos_n[-1, :2])
    assert abs(np.degrees(wrap_angle(off.yaw[-1] - g.yaw[-1]))) > 5.0
    assert err_off > 0.05 * dist
    assert abs(np.degrees(wrap_angle(on.yaw[-1] - g.yaw[-1]))) < 1.0
    assert err_on < 0.015 * dist and err_on < 0.25 * err_off, (err_on, err_off)
    np.testing.assert_allclose(np.linalg.norm(on.q_nb, axis=1), 1.0, atol=1e-9)
