"""Real static recordings: ADIS16405, 2.8 h at 100 Hz (SMAC-Group imudata, CC BY-NC-SA; test input only)."""


import numpy as np
import pytest

from pdr.allan.characterise import characterise_recording
from pdr.allan.report import comparison_dict, report_dict
from pdr.io import read_recording
from tests.conftest import data_path

RAD2DEG = 180.0 / np.pi


def _read(unit: int):
    return read_recording(data_path("allan_static_imudata", f"adis_16405_imu{unit}.npz"))


@pytest.mark.data
def test_one_adis_unit_matches_its_datasheet_order_of_magnitude():
    rec = _read(1)
    res = characterise_recording(rec)
    gyro, acc = res.sensors["gyro"], res.sensors["acc"]
    assert gyro.quality is not None and gyro.quality.flags == () and gyro.n_samples == 1_000_000
    for ax in gyro.axes.values():
        # datasheet: ARW about 2 deg/sqrt(h), in-run bias stability about 0.007 deg/s = 25 deg/h
        n, b = ax.fit.value["N"], ax.fit.value["B"]
        assert n is not None and b is not None
        arw = n * RAD2DEG * 60
        bi = b * RAD2DEG * 3600
        assert 0.5 < arw < 8.0 and 25 / 5 < bi < 25 * 5
        # the fit and the classic -1/2 reading agree on white noise
        assert ax.fit.value["N"] == pytest.approx(ax.slopes.N, rel=0.15)
    for ax in acc.axes.values():
        n = ax.fit.value["N"]
        assert n is not None
        ug_rthz = n / 9.80665e-6
        assert 100 < ug_rthz < 2000  # datasheet noise density about 0.5 mg/sqrt(Hz)
    assert gyro.grade == "consumer"
    assert all(v[0] > 0 for v in gyro.bias_used.values())


@pytest.mark.data
@pytest.mark.slow
def test_three_adis_units_agree():
    reports = [report_dict(characterise_recording(_read(u))) for u in (1, 2, 3)]
    comp = comparison_dict(reports)
    for a in ("x", "y", "z"):
        assert comp["sensors"]["gyro"][a]["N"]["cv_pct"] < 10
        assert comp["sensors"]["gyro"][a]["B"]["cv_pct"] < 30
        assert comp["sensors"]["acc"][a]["N"]["cv_pct"] < 15

