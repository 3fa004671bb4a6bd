import gzip

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import static_npz
from tests.conftest import data_path
from tests.pdr.io._registry import detect_or_skip

COLUMNS = np.array(["Gyro. X", "Gyro. Y", "Gyro. Z", "Accel. X", "Accel. Y", "Accel. Z"])


def _static(n=20_000, gyro_unit="deg/s", acc_unit="g", seed=0):
    """A bench IMU at rest: gyro bias + ARW-like noise, accelerometer Z up."""
    rng = np.random.default_rng(seed)
    gyro_rad = np.array([0.007, -0.007, -0.005]) + rng.normal(0, 0.006, (n, 3))
    acc_ms2 = np.array([0.0, 0.0, 9.81]) + rng.normal(0, 0.03, (n, 3))
    gyro = np.degrees(gyro_rad) if gyro_unit == "deg/s" else gyro_rad
    if gyro_unit == "deg/s":
        gyro = np.round(gyro / 0.05) * 0.05  # ADIS16405 LSB
    acc = acc_ms2 / 9.80665 if acc_unit == "g" else acc_ms2
    return np.column_stack([gyro, acc]), gyro_rad, acc_ms2


def _save(tmp_path, data, columns=COLUMNS, fs=100.0, name="imu.npz"):
    p = tmp_path / name
    np.savez(p, data=data, columns=columns, fs=np.float64(fs))
    return p


@pytest.mark.parametrize(("gyro_unit", "acc_unit"), [("deg/s", "g"), ("rad/s", "m/s^2"), ("rad/s", "g")])
def test_units_detected_from_data_not_names(tmp_path, gyro_unit, acc_unit):
    data, gyro_rad, acc_ms2 = _static(gyro_unit=gyro_unit, acc_unit=acc_unit)
    p = _save(tmp_path, data, name="adis_16405_imu_deg_g.npz")  # a misleading name changes nothing
    assert static_npz.sniff(p)
    rec = static_npz.read(p)
    assert rec.meta["units"] == {"gyro": gyro_unit, "acc": acc_unit}
    tol = np.radians(0.05) if gyro_unit == "deg/s" else 1e-12
    np.testing.assert_allclose(rec.values("gyro"), gyro_rad, atol=tol)
    np.testing.assert_allclose(rec.values("acc"), acc_ms2, atol=1e-9)
    assert len(rec.warnings) == (gyro_unit != "rad/s") + (acc_unit != "m/s^2")
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(100.0)
    assert rec.t_s("gyro")[-1] == pytest.approx((20_000 - 1) / 100.0)


def test_non_integer_period_and_gz(tmp_path):
    data, _, _ = _static(n=3000)
    p = _save(tmp_path, data, fs=300.0)
    gz = tmp_path / "imu.npz.gz"
    gz.write_bytes(gzip.compress(p.read_bytes()))
    assert static_npz.sniff(gz)
    rec = static_npz.read(gz)
    assert rec.stream("acc").median_rate_hz() == pytest.approx(300.0, rel=1e-6)
    assert rec.t_s("acc")[2999] == pytest.approx(2999 / 300.0, abs=1e-9)


def test_ambiguous_gyro_is_rejected(tmp_path):
    data, _, _ = _static(gyro_unit="rad/s")
    data[:, :3] = 0.03 + np.random.default_rng(1).normal(0, 0.03, (data.shape[0], 3))  # between the two units
    with pytest.raises(InputError, match="cannot tell the gyroscope unit") as err:
        static_npz.read(_save(tmp_path, data))
    assert err.value.field == "Gyro. X"


def test_ambiguous_accelerometer_is_rejected(tmp_path):
    data, _, _ = _static()
    data[:, 3:] *= 4.0
    with pytest.raises(InputError, match="accelerometer unit.*median norm 4") as err:
        static_npz.read(_save(tmp_path, data))
    assert err.value.field == "Accel. X"


@pytest.mark.parametrize(("kwargs", "field", "match"), [
    ({"data": np.zeros((10, 5))}, "columns", "6 column names for 5"),
    ({"columns": np.array(["Gyro. X", "b", "c", "d", "e", "f"])}, "columns", "gyro needs X, Y and Z"),
    ({"columns": np.array(["a", "b", "c", "d", "e", "f"])}, "columns", "no gyro/accel/mag"),
    ({"fs": -1.0}, "fs", "positive"),
    ({"fs": "fast"}, "fs", "not a number"),
    ({"data": np.zeros((1, 6))}, "data", "at least 2 samples"),
    # a rate whose sample period is below 1 ns or whose time axis overflows int64 ns was "stream 'acc': timestamp of
    # sample 1 (0) duplicates sample 0 (0)", without the file
    ({"fs": 1e308}, "fs", "no nanosecond time axis"),
    ({"fs": 2e9}, "fs", "no nanosecond time axis"),
    ({"fs": 1e-308}, "fs", "no nanosecond time axis"),
    ({"data": np.array([["a"] * 6] * 3)}, "data", "numeric"),
])
def test_bad_arrays_name_field(tmp_path, kwargs, field, match):
    data, _, _ = _static(n=100)
    arrays = {"data": data, "columns": COLUMNS, "fs": np.float64(100.0)} | kwargs
    p = tmp_path / "bad.npz"
    np.savez(p, **arrays)
    with pytest.raises(InputError, match=match) as err:
        static_npz.read(p)
    assert err.value.field == field and err.value.source == str(p)


def test_nan_names_sample_and_column(tmp_path):
    data, _, _ = _static(n=100)
    data[42, 4] = np.nan
    with pytest.raises(InputError, match="sample 42 is not finite") as err:
        static_npz.read(_save(tmp_path, data))
    assert err.value.field == "Accel. Y"


def test_value_beyond_any_float_in_si_names_sample_and_column(tmp_path):
    """1e308 g is a float, but not in m/s^2: it was refused as "stream 'acc': sample 42 is not finite", without the
    file or the column."""
    data, _, _ = _static(n=100)
    data[42, 4] = 1e308
    p = _save(tmp_path, data)
    with pytest.raises(InputError, match=r"sample 42 \(1e\+308 g\) is beyond any float") as err:
        static_npz.read(p)
    assert (err.value.source, err.value.field) == (str(p), "Accel. Y")


def test_missing_member_and_garbage(tmp_path):
    p = tmp_path / "m.npz"
    np.savez(p, data=np.zeros((3, 6)), columns=COLUMNS)
    assert not static_npz.sniff(p)
    with pytest.raises(InputError, match="missing arrays") as err:
        static_npz.read(p)
    assert err.value.field == "fs"
    g = tmp_path / "g.npz"
    g.write_bytes(bytes(range(256)) * 16)
    assert not static_npz.sniff(g)
    with pytest.raises(InputError, match="not a readable .npz"):
        static_npz.read(g)
    empty = tmp_path / "e.npz"
    empty.write_bytes(b"")
    assert not static_npz.sniff(empty)
    with pytest.raises(InputError, match="e.npz"):
        static_npz.read(empty)
    assert not static_npz.sniff(tmp_path)


def test_million_samples(tmp_path):
    data, _, _ = _static(n=1_000_000)
    p = _save(tmp_path, data)
    rec = static_npz.read(p)
    assert len(rec.stream("gyro")) == 1_000_000


@pytest.mark.data
def test_real_adis_recording():
    p = data_path("allan_static_imudata", "adis_16405_imu1.npz")
    rec = static_npz.read(p)
    assert rec.meta["units"] == {"gyro": "deg/s", "acc": "g"}
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(100.0)
    assert len(rec.stream("acc")) == 1_000_000
    assert rec.duration_s == pytest.approx(10_000.0, abs=0.02)
    assert np.linalg.norm(rec.values("acc"), axis=1).mean() == pytest.approx(9.97, abs=0.05)  # 1.016 g
    # bias about +0.4/-0.4/-0.3 deg/s
    np.testing.assert_allclose(np.degrees(rec.values("gyro").mean(axis=0)), [0.4, -0.42, -0.29], atol=0.03)
    assert any("quantised in steps of 0.05" in w for w in rec.warnings)
    assert detect_or_skip(p) == "static_npz"
