import gzip
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from pdr import quaternion
from pdr.errors import InputError
from pdr.io import sensorconnect
from tests.conftest import data_path
from tests.pdr.io._registry import detect_or_skip

FIXTURES = Path(__file__).parent / "fixtures" / "sensorconnect"
PREFIX = "inertial-6253.76535:"
V1_COLUMNS = ["scaledAccelX", "scaledAccelY", "scaledAccelZ", "scaledGyroX", "scaledGyroY", "scaledGyroZ",
              "scaledMagX", "scaledMagY", "scaledMagZ", "roll", "pitch", "yaw"]


def _v1_text(n=50, rate=200.0, roll=0.1, pitch=-0.2, yaw=0.7):
    """A level-ish node at rest: specific force from the angles (NED, z down), field 0.45 G."""
    f_b = np.array([np.sin(pitch), -np.sin(roll) * np.cos(pitch), -np.cos(roll) * np.cos(pitch)])
    rows = ["Time," + ",".join(PREFIX + c for c in V1_COLUMNS)]
    for i in range(n):
        vals = [*f_b, 0.001, -0.002, 0.003, 0.2, 0.1, 0.4, roll, pitch, yaw]
        rows.append(f"{i / rate!r}," + ",".join(repr(float(v)) for v in vals))
    return "\n".join(rows) + "\n"


def _write(tmp_path, text, name="SensorConnectData_99.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_variant1_units_and_orientation(tmp_path):
    p = _write(tmp_path, _v1_text())
    assert sensorconnect.sniff(p)
    rec = sensorconnect.read(p)
    assert rec.meta["variant"] == 1 and rec.device.device_id == "inertial-6253.76535"
    assert rec.stream("acc").median_rate_hz() == pytest.approx(200.0)
    np.testing.assert_allclose(np.linalg.norm(rec.values("acc"), axis=1), 9.80665)
    np.testing.assert_allclose(rec.values("mag")[0], [20.0, 10.0, 40.0])  # Gauss -> uT
    np.testing.assert_allclose(rec.values("gyro")[0], [0.001, -0.002, 0.003])  # rad/s unchanged
    # q_nb maps the specific force at rest onto ENU up
    f_n = quaternion.rotate(rec.values("orientation"), rec.values("acc"))
    np.testing.assert_allclose(f_n, np.tile([0, 0, 9.80665], (50, 1)), atol=1e-9)
    # yaw is measured from north towards east (NED): 0.7 rad -> ENU yaw pi/2 - 0.7
    _, _, yaw_enu = quaternion.to_euler(rec.values("orientation")[0])
    assert float(yaw_enu) == pytest.approx(np.pi / 2 - 0.7)
    assert rec.truth.is_empty()


def test_variant2_fixture_drops_invalid_rows():
    p = FIXTURES / "SensorConnectData_42_head.csv"
    assert sensorconnect.sniff(p)
    rec = sensorconnect.read(p)
    assert rec.meta["variant"] == 2
    assert len(rec.stream("acc")) == 20 and len(rec.stream("gyro")) == 20
    assert len(rec.stream("orientation")) == 16
    assert any("orientation: dropped 4 of 20 rows flagged invalid" in w for w in rec.warnings)
    assert rec.stream("acc").median_rate_hz() == pytest.approx(250.0, rel=1e-3)
    acc = rec.values("acc")[:16]
    assert np.linalg.norm(acc, axis=1).mean() == pytest.approx(9.8, abs=0.1)  # already m/s^2
    # the filter's attitude agrees with gravity to within a few degrees at the start of the walk
    f_n = quaternion.rotate(rec.values("orientation"), acc).mean(axis=0)
    assert np.degrees(np.arctan2(np.hypot(f_n[0], f_n[1]), f_n[2])) < 6.0


def test_gz_and_header_variants(tmp_path):
    text = _v1_text().replace("Time,", "Time (s),", 1)
    gz = tmp_path / "log.csv.gz"
    gz.write_bytes(gzip.compress(text.encode()))
    assert sensorconnect.sniff(gz)
    assert len(sensorconnect.read(gz).stream("acc")) == 50


def test_units_cross_checked_against_data(tmp_path):
    """An export whose 'scaled' accelerometer is already m/s^2 is caught by the data, with a warning."""
    lines = _v1_text().splitlines()
    out = [lines[0]]
    for line in lines[1:]:
        f = line.split(",")
        f[1:4] = [repr(float(v) * 9.80665) for v in f[1:4]]
        out.append(",".join(f))
    rec = sensorconnect.read(_write(tmp_path, "\n".join(out) + "\n"))
    assert np.linalg.norm(rec.values("acc"), axis=1).mean() == pytest.approx(9.80665)
    assert any("acc" in w for w in rec.warnings)


def _gcp_mat(folder: Path, stem: str, k: int, complete=1):
    savemat(folder / f"{stem}.mat", {
        "GCP_meters": np.column_stack([np.arange(k) * 1.4, np.zeros(k)]),
        "GCP_stride_numbers": np.arange(k, dtype=np.uint8)[None, :], "numberOfStrides": np.array([[k - 1]]),
        "GCP_exist_and_correct": np.array([[complete]], dtype=np.uint8), "tile_edge_length": np.array([[0.6]])})


def test_stride_truth_with_llio_times(tmp_path):
    own = tmp_path / "own"
    own.mkdir()
    p = _write(own, _v1_text(n=400))
    _gcp_mat(own, "SensorConnectData_99", 3)
    llio = tmp_path / "LLIO_training_data"
    llio.mkdir()
    (llio / "SensorConnectData_99_strideIndex_timestamp_gcpX_gcpY.csv").write_text(
        "strideIndex,timestamp,gcpX,gcpY\n1.0e+02,0.5,0,0\n2.0e+02,1.0,-1.4,0\n3.0e+02,1.5,-2.8,0\n")
    rec = sensorconnect.read(p)
    pos = rec.truth.positions
    assert pos is not None and pos.kind == "stride" and pos.frame == "map"
    np.testing.assert_allclose(pos.t_s, [0.5, 1.0, 1.5])
    np.testing.assert_allclose(pos.pos_m[:, 0], [0.0, 1.4, 2.8])  # the tile frame of the .mat, not LLIO's
    np.testing.assert_array_equal(rec.truth.extra["stride_end_index"], [100, 200, 300])
    assert rec.meta["tile_edge_length_m"] == 0.6 and rec.meta["gcp_complete"] is True
    assert rec.warnings == ()


def test_stride_numbers_only_go_to_extra(tmp_path):
    p = _write(tmp_path, _v1_text(n=400))
    _gcp_mat(tmp_path, "SensorConnectData_99", 4, complete=0)
    rec = sensorconnect.read(p)
    assert rec.truth.positions is None
    assert rec.truth.extra["gcp_m"].shape == (4, 2)
    np.testing.assert_array_equal(rec.truth.extra["gcp_stride_number"], [0, 1, 2, 3])
    assert any("without stride times" in w for w in rec.warnings)
    assert any("partial" in w for w in rec.warnings)


def test_bad_llio_index_names_line(tmp_path):
    p = _write(tmp_path, _v1_text(n=100))
    _gcp_mat(tmp_path, "SensorConnectData_99", 2)
    (tmp_path / "SensorConnectData_99_strideIndex_timestamp_gcpX_gcpY.csv").write_text(
        "strideIndex,timestamp,gcpX,gcpY\n10,0.05,0,0\n500,2.5,1,0\n")
    with pytest.raises(InputError, match="not a sample") as err:
        sensorconnect.read(p)
    assert err.value.line == 3 and err.value.field == "strideIndex"


def _replace_line(text, line, new):
    lines = text.splitlines()
    lines[line - 1] = new
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("edit", "line", "field", "match"), [
    (lambda t: "", 1, None, "empty file"),
    (lambda t: t.splitlines()[0] + "\n", 2, None, "no samples"),
    (lambda t: t[: t.index("\n", t.index("\n", t.index("\n") + 1) + 1) - 8] + "\n", 3, None, "expected 13 fields"),
    (lambda t: _replace_line(t, 4, "0.015,1,2,3"), 4, None, "expected 13 fields"),
    (lambda t: _replace_line(t, 5, ",".join(["0.02"] + ["abc"] + ["0"] * 11)), 5, "scaledAccelX", "not a number"),
    (lambda t: _replace_line(t, 5, ",".join(["0.02"] + ["0"] * 5 + ["nan"] + ["0"] * 6)), 5, "scaledGyroZ",
     "not finite"),
    (lambda t: _replace_line(_replace_line(t, 6, ",".join(["0.001"] + ["0"] * 12)), 7,
                             ",".join(["0.0015"] + ["0"] * 12)), 6, "Time", "backwards in 2 of"),
    (lambda t: t.replace("Time,", "Clock,", 1), 1, "Time", "no Time column"),
    # 1e308 g is a float but not in m/s^2: was "stream 'acc': sample 3 is not finite", no file, line or column
    (lambda t: _replace_line(t, 5, ",".join(["0.02", "1e308"] + ["0"] * 11)), 5, "scaledAccelX", "beyond any float"),
])
def test_bad_input_names_file_line_field(tmp_path, edit, line, field, match):
    p = _write(tmp_path, edit(_v1_text()))
    with pytest.raises(InputError, match=match) as err:
        sensorconnect.read(p)
    assert err.value.source == str(p)
    assert err.value.line == line and err.value.field == field


def test_garbage_is_rejected_and_not_sniffed(tmp_path):
    g = tmp_path / "g.csv"
    g.write_bytes(bytes(range(256)) * 8)
    assert not sensorconnect.sniff(g)
    with pytest.raises(InputError, match="binary"):
        sensorconnect.read(g)
    other = _write(tmp_path, "Time (s),Gyroscope X (deg/s)\n0,1\n", "x.csv")
    assert not sensorconnect.sniff(other)
    assert not sensorconnect.sniff(tmp_path / "missing.csv")
    assert not sensorconnect.sniff(tmp_path)


@pytest.mark.data
@pytest.mark.parametrize("n", [31, 34])
def test_real_walk(n, tmp_path):
    p = data_path("foot_stride_gcp", "own", f"SensorConnectData_{n}.csv")
    rec = sensorconnect.read(p)
    for kind in ("acc", "gyro", "mag", "orientation"):
        assert rec.stream(kind).median_rate_hz() == pytest.approx(200.0, rel=1e-3)
    acc = rec.values("acc")
    assert np.linalg.norm(acc[:100], axis=1).mean() == pytest.approx(9.82, abs=0.05)  # standing at the start
    assert 25 < np.linalg.norm(rec.values("mag"), axis=1).mean() < 65  # uT
    f_n = quaternion.rotate(rec.values("orientation")[:100], acc[:100]).mean(axis=0)
    assert np.hypot(f_n[0], f_n[1]) < 0.3 and f_n[2] == pytest.approx(9.82, abs=0.05)
    pos = rec.truth.positions
    assert pos is not None and pos.kind == "stride"
    mat_gcps = {31: 34, 34: 25}[n]
    assert len(pos) == mat_gcps
    steps = np.linalg.norm(np.diff(pos.pos_m, axis=0), axis=1)
    assert 0.3 < np.median(steps) < 2.0  # stride lengths in metres
    assert np.all(np.diff(pos.t_s) > 0) and pos.t_s[-1] <= rec.duration_s
    assert detect_or_skip(p) == "sensorconnect"


@pytest.mark.data
def test_real_walk_without_llio_times(tmp_path):
    src = data_path("foot_stride_gcp", "own")
    for ext in ("csv", "mat"):
        shutil.copy(src / f"SensorConnectData_35.{ext}", tmp_path / f"SensorConnectData_35.{ext}")
    rec = sensorconnect.read(tmp_path / "SensorConnectData_35.csv")
    assert rec.duration_s == pytest.approx(30.0, abs=0.05)
    assert rec.truth.positions is None and rec.truth.extra["gcp_m"].shape == (29, 2)


def test_times_a_tenth_of_a_nanosecond_apart_are_a_repeat_dropped_with_a_warning(tmp_path):
    """Rows 0.1 ns apart (in order in seconds, one nanosecond once rounded) refused the whole file: "stream 'acc':
    timestamp of sample 2 (5000000) duplicates sample 1 (5000000)"; the later row is dropped as a repeat now, with a
    warning naming the line (pdr.io.time_order on the int64 nanoseconds, as exact repeats)."""
    text = _v1_text()
    lines = text.splitlines()
    fields = lines[3].split(",")
    fields[0] = repr(float(lines[2].split(",")[0]) + 1e-10)
    lines[3] = ",".join(fields)
    whole = sensorconnect.read(_write(tmp_path, text, "whole.csv"))
    rec = sensorconnect.read(_write(tmp_path, "\n".join(lines) + "\n"))
    for kind in ("acc", "gyro", "mag", "orientation"):
        np.testing.assert_array_equal(rec.stream(kind).t_ns, np.delete(whole.stream(kind).t_ns, 2))
    assert any(w.startswith("SensorConnectData_99.csv: dropped 1 of 50 samples whose time repeats (1)")
               and "line 4" in w for w in rec.warnings), rec.warnings
