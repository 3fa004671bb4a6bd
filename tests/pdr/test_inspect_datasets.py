"""Acceptance: ``pdr inspect`` reports the rates and durations stated in each dataset's SOURCE.md.

One file (or trial) of every dataset in ../shared/data is run through the real command line
(``pdr inspect LOG --json``) with format detection. Every expected figure below is quoted from the
dataset's SOURCE.md, never from a previous run; tolerances cover the stated ranges only.
"""

from __future__ import annotations

import json

import pytest

from pdr.cli import main
from pdr.frames import GRAVITY_MPS2
from tests.conftest import data_path

pytestmark = pytest.mark.data


def inspect_json(capsys: pytest.CaptureFixture[str], path) -> dict:
    code = main(["inspect", str(path), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def streams(summary: dict) -> dict[str, dict]:
    return {s["kind"]: s for s in summary["streams"]}


def assert_gravity_in_m_s2(s: dict, tol: float = 1.5) -> None:
    """Specific force including gravity has a median norm near 1 g once converted to m/s^2."""
    assert s["unit"] == "m/s^2"
    assert s["median_norm"] == pytest.approx(GRAVITY_MPS2, abs=tol)


# ------------------------------------------------------------------------------------- ipin2023_t3

def test_ipin_logfile_sm_a520f(capsys):
    # SOURCE.md: ACCE 50 Hz, MAGN 50 Hz, GYRO 100 Hz (A520F), PRES 5.5-6.2 Hz (A520F), AHRS 50 Hz;
    # trials last 143-302 s with 10-26 POSI landmarks; hand-held.
    s = inspect_json(capsys, data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt"))
    assert s["format"] == "ipin"
    assert s["device"]["model"] == "SM-A520F" and s["device"]["platform"] == "android"
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(50, rel=0.02)
    assert st["mag"]["rate_hz"] == pytest.approx(50, rel=0.02)
    assert st["gyro"]["rate_hz"] == pytest.approx(100, rel=0.02)
    assert 5.5 <= st["baro"]["rate_hz"] <= 6.25
    assert st["orientation"]["rate_hz"] == pytest.approx(50, rel=0.02)
    assert 143 <= s["duration_s"] <= 302
    assert 10 <= s["truth"]["positions"]["points"] <= 26
    assert_gravity_in_m_s2(st["acc"])
    assert 25 <= st["mag"]["median_norm"] <= 65  # earth field in uT
    assert 900 <= st["baro"]["median_norm"] <= 1050  # hPa


def test_ipin_logfile_sm_g930f(capsys):
    # SOURCE.md: GYRO 50 Hz and PRES 10 Hz on the G930F.
    path = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial21_repetition01.txt")
    s = inspect_json(capsys, path)
    assert s["device"]["model"] == "SM-G930F"
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(50, rel=0.02)
    assert st["gyro"]["rate_hz"] == pytest.approx(50, rel=0.02)
    assert st["baro"]["rate_hz"] == pytest.approx(10, rel=0.05)
    assert 143 <= s["duration_s"] <= 302


def test_ipin_mat_elevator_trial(capsys):
    # SOURCE.md: T53_rep01 (elevator): POSI goes from floor 0 to floor -2; pressure 976.09-976.87 hPa.
    s = inspect_json(capsys, data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial53_repetition01.mat"))
    assert s["format"] == "ipin"
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(50, rel=0.02)
    assert st["mag"]["rate_hz"] == pytest.approx(50, rel=0.02)
    # one of the two phones: A520F (gyro 100 Hz, pressure 5.5-6.2 Hz) or G930F (50 Hz, 10 Hz)
    a520f = st["gyro"]["rate_hz"] == pytest.approx(100, rel=0.02) and 5.5 <= st["baro"]["rate_hz"] <= 6.25
    g930f = (st["gyro"]["rate_hz"] == pytest.approx(50, rel=0.02)
             and st["baro"]["rate_hz"] == pytest.approx(10, rel=0.05))
    assert a520f or g930f
    assert 976.0 <= st["baro"]["median_norm"] <= 977.0
    assert s["truth"]["positions"]["floors"] == [-2.0, 0.0]
    assert 10 <= s["truth"]["positions"]["points"] <= 26


# ------------------------------------------------------------------------------ ms_indoor_location

def test_ms_indoor_trace(capsys):
    # SOURCE.md: OPPO PBCM10, hand-held flat; IMU 50 Hz; traces 6-92 s with 2-21 waypoints.
    folder = data_path("ms_indoor_location", "site2", "F3", "path_data_files")
    path = sorted(folder.iterdir())[0]
    s = inspect_json(capsys, path)
    assert s["format"] == "ms_indoor"
    assert s["device"]["model"] == "PBCM10"
    st = streams(s)
    for kind in ("acc", "gyro", "mag", "orientation"):
        assert st[kind]["rate_hz"] == pytest.approx(50, rel=0.02), kind
    assert 6 <= s["duration_s"] <= 92
    assert 2 <= s["truth"]["positions"]["points"] <= 21
    assert s["truth"]["positions"]["kind"] == "waypoint"


# ----------------------------------------------------------------------------- oxford_step_counter

@pytest.mark.parametrize(("trial", "rate_lo", "rate_hi"), [
    ("Pixel_Jamie_Hard_FrontPocket_1", 395, 415),      # "Pixel about 405 Hz (2.47 ms)"
    ("Samsung_Carmelo_Hard_FrontPocket_1", 190, 230),  # "Samsung about 210-225 Hz (about 5 ms, jittery)"
])
def test_oxford_optimisation_trial(capsys, trial, rate_lo, rate_hi):
    # SOURCE.md: accelerometer only; walks last about 2.5 min (150-350 steps).
    s = inspect_json(capsys, data_path("oxford_step_counter", "optimisation", "data", trial))
    assert s["format"] == "oxford"
    st = streams(s)
    assert set(st) == {"acc"}
    assert rate_lo <= st["acc"]["rate_hz"] <= rate_hi
    assert 100 <= s["duration_s"] <= 200
    assert_gravity_in_m_s2(st["acc"])
    truth = s["truth"]
    steps = truth.get("step_count", truth.get("step_times_s", {}).get("steps"))
    assert 150 <= steps <= 350
    if trial.startswith("Samsung_Carmelo"):
        assert steps == 139 + 138  # SOURCE.md: rising edges of both contact channels


def test_oxford_validation_file(capsys):
    # SOURCE.md: validation/user*_*.csv (Samsung S6) at 100 Hz (10 ms), with cumulative ground-truth steps.
    folder = data_path("oxford_step_counter", "validation")
    path = sorted(p for p in folder.iterdir() if p.name.startswith("user1_frontpocket"))[0]
    s = inspect_json(capsys, path)
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(100, rel=0.02)
    assert s["truth"]["step_count"] == 327  # "user1_frontpocket ends at ... ground truth=327"


# ------------------------------------------------------------------------------ mobifall_v2_pocket

def test_mobifall_walking_trial(capsys):
    # SOURCE.md: acc about 87-100 Hz, irregular (median 94 Hz); gyro about 200 Hz; WAL is 1 x 5 min.
    s = inspect_json(capsys, data_path("mobifall_v2_pocket", "sub2", "ADL", "WAL", "WAL_acc_2_1.txt.gz"))
    assert s["format"] == "mobifall"
    st = streams(s)
    assert 87 <= st["acc"]["rate_hz"] <= 100
    assert st["gyro"]["rate_hz"] == pytest.approx(200, rel=0.05)
    assert s["duration_s"] == pytest.approx(300, abs=15)
    assert_gravity_in_m_s2(st["acc"])
    assert s["truth"]["modes"]["labels"] == ["walk"] or len(s["truth"]["modes"]["labels"]) == 1


# ----------------------------------------------------------------------------- driving_phone_mount

def test_driving_trip(capsys):
    # SOURCE.md: trip 17 lasts 406 s; acc and gyro about 51 Hz; Motorola XT1058 on a windshield mount.
    s = inspect_json(capsys, data_path("driving_phone_mount", "17"))
    assert s["format"] == "driving"
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(51, rel=0.03)
    assert st["gyro"]["rate_hz"] == pytest.approx(51, rel=0.03)
    assert s["duration_s"] == pytest.approx(406, abs=3)
    assert_gravity_in_m_s2(st["acc"])


# ------------------------------------------------------------------------------------ pyshoe_vicon

def test_pyshoe_vicon_trial(capsys):
    # SOURCE.md: foot IMU at 200 Hz; trials last 16-96 s; VICON foot position at every IMU sample.
    folder = data_path("pyshoe_vicon")
    path = sorted(folder.glob("*.mat"))[0]
    s = inspect_json(capsys, path)
    assert s["format"] == "pyshoe"
    assert s["device"]["role"] in ("left_foot", "right_foot")
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(200, rel=0.02)
    assert st["gyro"]["rate_hz"] == pytest.approx(200, rel=0.02)
    assert 16 <= s["duration_s"] <= 96
    assert s["truth"]["positions"]["points"] == st["acc"]["samples"]
    assert_gravity_in_m_s2(st["acc"], tol=2.5)


# --------------------------------------------------------------------------------- foot_stride_gcp

def test_sensorconnect_scaled_variant(capsys):
    # SOURCE.md: NN 31-40: accel in g, gyro rad/s, mag Gauss at 200 Hz, Time starts at 0.
    s = inspect_json(capsys, data_path("foot_stride_gcp", "own", "SensorConnectData_31.csv"))
    assert s["format"] == "sensorconnect"
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(200, rel=0.02)
    assert st["gyro"]["rate_hz"] == pytest.approx(200, rel=0.02)
    assert st["acc"]["first_s"] == pytest.approx(0.0, abs=0.01)
    assert_gravity_in_m_s2(st["acc"], tol=2.5)  # converted from g
    if "mag" in st:
        assert 10 <= st["mag"]["median_norm"] <= 100  # converted from Gauss to uT


def test_sensorconnect_estimated_variant(capsys):
    # SOURCE.md: NN 42-45: EKF outputs in m/s^2 and rad/s at 250 Hz.
    s = inspect_json(capsys, data_path("foot_stride_gcp", "own", "SensorConnectData_42.csv"))
    st = streams(s)
    assert st["acc"]["rate_hz"] == pytest.approx(250, rel=0.02)
    assert st["gyro"]["rate_hz"] == pytest.approx(250, rel=0.02)
    assert_gravity_in_m_s2(st["acc"], tol=2.5)


# ---------------------------------------------------------------------------------- xio_gait_loop

def test_xio_short_walk(capsys):
    # SOURCE.md: 16,539 rows, 41.6 s, about 400 Hz (2.51 ms median); acc in g, gyro in deg/s.
    s = inspect_json(capsys, data_path("xio_gait_loop", "short_walk.csv"))
    assert s["format"] == "xio"
    st = streams(s)
    # 16,539 rows; a reader may drop rows that repeat the previous timestamp (it says so in warnings)
    assert 0.98 * 16539 <= st["acc"]["samples"] <= 16539 and st["gyro"]["samples"] == st["acc"]["samples"]
    assert st["acc"]["samples"] == 16539 or s["warnings"]
    assert st["acc"]["rate_hz"] == pytest.approx(1 / 2.51e-3, rel=0.01)
    assert s["duration_s"] == pytest.approx(41.6, abs=0.1)
    assert_gravity_in_m_s2(st["acc"], tol=2.5)  # converted from g
    assert st["gyro"]["unit"] == "rad/s"


# --------------------------------------------------------------------------- allan_static_imudata

def test_allan_static_npz(capsys):
    # SOURCE.md: ADIS16405, 100 Hz, 1,000,000 samples, 10,000 s; gyro deg/s, accel g (Z about -1.016 g).
    s = inspect_json(capsys, data_path("allan_static_imudata", "adis_16405_imu1.npz"))
    assert s["format"] == "static_npz"
    st = streams(s)
    for kind in ("acc", "gyro"):
        assert st[kind]["samples"] == 1_000_000
        assert st[kind]["rate_hz"] == pytest.approx(100, rel=1e-6)
        assert st[kind]["gaps"] == 0
    assert s["duration_s"] == pytest.approx(10_000, abs=0.02)
    assert st["acc"]["median_norm"] == pytest.approx(1.016 * GRAVITY_MPS2, rel=0.01)
    assert st["gyro"]["median_norm"] < 0.02  # ~0.4 deg/s biases, in rad/s
