import gzip
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import phyphox
from tests.pdr.io._registry import detect_or_skip

FIXTURE = Path(__file__).parent / "fixtures" / "phyphox" / "android_export"
START_NS = 1_717_000_000_250_000_000
RESUME_NS = 1_717_000_010_250_000_000


def _zip(folder: Path, out: Path, top: str | None = None) -> Path:
    with zipfile.ZipFile(out, "w") as zf:
        for f in sorted(folder.rglob("*")):
            if f.is_file():
                rel = str(f.relative_to(folder))
                zf.write(f, f"{top}/{rel}" if top else rel)
    return out


@pytest.mark.parametrize("packaging", ["folder", "zip", "zip_with_top_folder"])
def test_export_streams_units_and_epoch_clock(packaging, tmp_path):
    path = FIXTURE
    if packaging != "folder":
        path = _zip(FIXTURE, tmp_path / "export.zip", top="Acceleration 2024-05-29" if "top" in packaging else None)
    assert phyphox.sniff(path)
    rec = phyphox.read(path)
    assert rec.device.platform == "android" and rec.device.model == "Pixel 7"
    assert set(rec.streams) == {"acc", "lin_acc", "gyro", "mag", "baro"}
    np.testing.assert_allclose(rec.values("acc").mean(axis=0), [0.0, 0.0, 9.81], atol=0.1)  # face-up
    np.testing.assert_allclose(rec.values("mag").mean(axis=0), [1.0, 21.0, -40.0], atol=0.3)  # uT
    assert rec.values("baro").mean() == pytest.approx(1012.3, abs=0.05)
    assert rec.warnings == ()
    # experiment time 1.29e-4 s after the first START at epoch 1717000000.25 s, exactly in ns
    assert rec.stream("acc").t_ns[0] == START_NS + 129_000
    # samples after the resume (experiment time >= 0.5 s) are placed after the 9.5 s pause
    t = rec.stream("gyro").t_ns
    first_after = int(np.argmax(t > START_NS + 600_000_000))
    exp_time = float((FIXTURE / "Gyroscope.csv").read_text().splitlines()[first_after + 1].split(",")[0])
    assert t[first_after] == RESUME_NS + round((exp_time - 0.5) * 1e9)
    assert rec.stream("acc").median_rate_hz() == pytest.approx(50.0, rel=0.05)


def test_single_csv_and_gz_use_experiment_time(tmp_path):
    src = FIXTURE / "Gyroscope.csv"
    gz = tmp_path / "Gyroscope.csv.gz"
    gz.write_bytes(gzip.compress(src.read_bytes()))
    for p in (src, gz):
        assert phyphox.sniff(p)
        rec = phyphox.read(p)
        assert set(rec.streams) == {"gyro"}
        assert rec.stream("gyro").t_ns[0] == 5_000_000
        assert any("experiment time" in w for w in rec.warnings)


def test_semicolon_decimal_comma_dialect(tmp_path):
    text = ('"Time (s)";"Acceleration x (m/s^2)";"Acceleration y (m/s^2)";"Acceleration z (m/s^2)";'
            '"Absolute acceleration (m/s^2)"\n'
            "0,000000000E0;1,0E-2;-2,0E-2;9,81E0;9,81E0\n1,000000000E-2;1,0E-2;-2,0E-2;9,80E0;9,80E0\n")
    p = tmp_path / "Raw Data.csv"
    p.write_text(text, encoding="utf-8")
    assert phyphox.sniff(p)
    rec = phyphox.read(p)
    np.testing.assert_allclose(rec.values("acc"), [[0.01, -0.02, 9.81], [0.01, -0.02, 9.80]])


def test_degree_and_g_units_converted(tmp_path):
    p = tmp_path / "Raw Data.csv"
    p.write_text('"Time (s)","Gyroscope x (deg/s)","Gyroscope y (deg/s)","Gyroscope z (deg/s)"\n0,180,0,-90\n'
                 "0.01,180,0,-90\n")
    np.testing.assert_allclose(phyphox.read(p).values("gyro")[0], [np.pi, 0, -np.pi / 2])


def test_value_beyond_any_float_in_si_names_line_and_field(tmp_path):
    """1e308 g is a float but not in m/s^2: it was refused as "stream 'acc': sample 1 is not finite", without the
    file, line or column (and with numpy's overflow warning)."""
    p = tmp_path / "Raw Data.csv"
    p.write_text('"Time (s)","Acceleration x (g)","Acceleration y (g)","Acceleration z (g)"\n0,0,0,1\n'
                 "0.01,0,1e308,1\n0.02,0,0,1\n")
    with pytest.raises(InputError, match="beyond any float") as err:
        phyphox.read(p)
    assert (err.value.source, err.value.line, err.value.field) == (str(p), 3, "Acceleration y (g)")


def _copy(tmp_path):
    dst = tmp_path / "export"
    shutil.copytree(FIXTURE, dst)
    return dst


def _edit_line(path: Path, line: int, new: str):
    lines = path.read_text().splitlines()
    lines[line - 1] = new
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(("edit", "line", "field", "match"), [
    (lambda p: p.write_text('"Time (s)","Gyroscope x (rad/s)","Gyroscope y (rad/s)","Gyroscope z (rad/s)"\n'), 2,
     None, "no samples"),
    (lambda p: p.write_text(p.read_text()[:-20] + "\n"), None, None, "expected 4 fields"),  # at the end: dropped
    (lambda p: _edit_line(p, 3, "2.0E-2,1.0E-3,2.0E-3"), 3, None, "expected 4 fields"),
    (lambda p: _edit_line(p, 3, "2.0E-2,1.0E-3,2.0E-3,4.0E-3,9"), 3, None, "expected 4 fields"),
    (lambda p: _edit_line(p, 4, "3.0E-2,1.0E-3,abc,4.0E-3"), 4, "Gyroscope y (rad/s)", "not a number"),
    (lambda p: _edit_line(p, 4, "3.0E-2,1.0E-3,NaN,4.0E-3"), 4, "Gyroscope y (rad/s)", "not finite"),
    (lambda p: (_edit_line(p, 5, "1.0E-3,1.0E-3,2.0E-3,4.0E-3"), _edit_line(p, 6, "1.5E-3,1.0E-3,2.0E-3,4.0E-3")), 5,
     "Time (s)", "backwards in 2 of"),
    (lambda p: p.write_text('"Time (s)","Gyroscope x (rad/h)","Gyroscope y (rad/h)","Gyroscope z (rad/h)"\n0,1,2,3\n'),
     1, "Gyroscope x (rad/h)", "unknown unit"),
])
def test_bad_data_csv_names_file_line_field(tmp_path, edit, line, field, match):
    folder = _copy(tmp_path)
    target = folder / "Gyroscope.csv"
    edit(target)
    with pytest.raises(InputError, match=match) as err:
        phyphox.read(folder)
    assert str(err.value.source).endswith("Gyroscope.csv")
    if line is None:
        line = len(target.read_text().splitlines())
    assert err.value.line == line and err.value.field == field


def test_bad_time_csv(tmp_path):
    folder = _copy(tmp_path)
    (folder / "meta" / "time.csv").write_text('"event","experiment time","system time"\n"START",0,soon\n')
    with pytest.raises(InputError, match="not a number") as err:
        phyphox.read(folder)
    assert err.value.line == 2 and err.value.field == "system time"
    (folder / "meta" / "time.csv").write_text('"event","when"\n"START",0\n')
    with pytest.raises(InputError, match="missing column") as err:
        phyphox.read(folder)
    assert err.value.line == 1


def test_binary_member_and_foreign_inputs(tmp_path):
    folder = _copy(tmp_path)
    (folder / "Gyroscope.csv").write_bytes(b"\x00\x01\x02" * 100)
    with pytest.raises(InputError, match="Gyroscope.csv.*binary"):
        phyphox.read(folder)
    g = tmp_path / "g.csv"
    g.write_bytes(bytes(range(256)))
    assert not phyphox.sniff(g)
    xio = tmp_path / "x.csv"
    xio.write_text("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s)\n0,1,2,3\n")
    assert not phyphox.sniff(xio)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert not phyphox.sniff(empty)
    bad_zip = tmp_path / "b.zip"
    bad_zip.write_bytes(b"PK\x03\x04nope")
    assert not phyphox.sniff(bad_zip)
    only_meta = tmp_path / "only_meta"
    shutil.copytree(FIXTURE / "meta", only_meta / "meta")
    with pytest.raises(InputError, match="no phyphox data set"):
        phyphox.read(only_meta)


def test_detect_format():
    assert detect_or_skip(FIXTURE) == "phyphox"


_ACC_ROWS = [(0.0, 0.01, -0.02, 9.81), (0.01, 0.01, -0.02, 9.80), (0.02, 0.02, -0.01, 9.79)]


def _dialect_text(delim: str, decimal: str) -> str:
    cols = ["Time (s)", "Acceleration x (m/s^2)", "Acceleration y (m/s^2)", "Acceleration z (m/s^2)"]
    lines = [delim.join(f'"{c}"' for c in cols)]
    for row in _ACC_ROWS:
        lines.append(delim.join(f"{v:.9E}".replace(".", decimal) for v in row))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("delim", "decimal"), [(",", "."), ("\t", "."), (";", "."), ("\t", ","), (";", ",")])
def test_all_five_csv_dialects(delim, decimal, tmp_path):
    # phyphox's export menu: comma / tabulator / semicolon with a decimal point, tabulator / semicolon with a
    # decimal comma ("Tabulator, decimal comma" was refused: '0,000000000E0' is not a number).
    p = tmp_path / "Raw Data.csv"
    p.write_text(_dialect_text(delim, decimal), encoding="utf-8")
    assert phyphox.sniff(p)
    rec = phyphox.read(p)
    np.testing.assert_allclose(rec.values("acc"), [r[1:] for r in _ACC_ROWS])
    assert rec.stream("acc").t_ns[-1] == 20_000_000


def _ios_multi_sensor_export(folder: Path, with_acc: bool = True) -> Path:
    """phyphox iOS multi-sensor export: one CSV per sensor named after it, bare ``X (unit)`` columns, meta/."""
    (folder / "meta").mkdir(parents=True)
    (folder / "meta" / "time.csv").write_text('"event","experiment time","system time","system time text"\n'
                                              '"START",0.000000000E0,1717000000.25,"x"\n')
    (folder / "meta" / "device.csv").write_text('"property","value"\n"deviceModel","iPhone14,5"\n'
                                                '"deviceBrand","Apple"\n')
    t = np.arange(100) * 0.01
    files = {"Gyroscope.csv": ("rad/s", [0.1, 0.0, -0.1]), "Linear Accelerometer.csv": ("m/s^2", [0.2, 0.1, 0.0])}
    if with_acc:
        files["Accelerometer.csv"] = ("m/s^2", [0.2, 0.1, 9.81])
    for fname, (unit, v) in files.items():
        lines = [f'"Time (s)","X ({unit})","Y ({unit})","Z ({unit})"']
        lines += [f"{ti:.9E},{v[0]:.9E},{v[1]:.9E},{v[2]:.9E}" for ti in t]
        (folder / fname).write_text("\n".join(lines) + "\n")
    return folder


def test_ios_multi_sensor_export_streams_from_file_names(tmp_path):
    path = _ios_multi_sensor_export(tmp_path / "Multi 2024-05-29")
    assert phyphox.sniff(path)
    rec = phyphox.read(path)
    assert rec.device.platform == "ios"
    assert set(rec.streams) == {"acc", "lin_acc", "gyro"}
    np.testing.assert_allclose(rec.values("acc")[0], [0.2, 0.1, 9.81])       # Accelerometer.csv includes g
    np.testing.assert_allclose(rec.values("lin_acc")[0], [0.2, 0.1, 0.0])
    np.testing.assert_allclose(rec.values("gyro")[0], [0.1, 0.0, -0.1])
    assert rec.warnings == ()


def test_bare_axis_columns_outside_an_export_are_not_read(tmp_path):
    # Without meta/ the file name is no evidence of a phyphox sensor (x-io and others write "X (...)" too).
    path = _ios_multi_sensor_export(tmp_path / "export")
    single = path / "Accelerometer.csv"
    assert not phyphox.sniff(single)


def test_linear_acceleration_only_export_warns_which_experiment_to_use(tmp_path):
    path = _ios_multi_sensor_export(tmp_path / "export", with_acc=False)
    (path / "Gyroscope.csv").unlink()
    rec = phyphox.read(path)
    assert set(rec.streams) == {"lin_acc"}
    assert any("'Acceleration (with g)' experiment" in w for w in rec.warnings)


def test_repeated_timestamps_are_dropped_with_a_warning(tmp_path):
    # A spreadsheet-resaved file keeps fewer time digits: many rows share a timestamp.
    p = tmp_path / "Raw Data.csv"
    p.write_text('"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)","Acceleration z (m/s^2)"\n'
                 "0.00,0,0,9.8\n0.00,1,0,9.8\n0.01,0,0,9.8\n0.01,2,0,9.8\n0.01,3,0,9.8\n0.02,0,0,9.8\n")
    rec = phyphox.read(p)
    np.testing.assert_allclose(rec.values("acc")[:, 0], [0.0, 0.0, 0.0])    # the first of each repeat kept
    assert any("dropped 3 of 6 samples whose time repeats (3)" in w for w in rec.warnings)


def test_last_line_without_line_break_kept_unless_its_last_value_is_cut(tmp_path):
    """phyphox for iOS leaves the last row without a line break: a whole last row is read, one whose last value
    lost digits ('9.8066' of '9.806650000E0') is dropped with a warning naming file and line; a resaved file of
    other numbers keeps its last row (read as before)."""
    text = _dialect_text(",", ".").rstrip("\n")
    whole = phyphox.read(_write(tmp_path / "whole.csv", text))
    assert len(whole.stream("acc")) == len(_ACC_ROWS) and not any("cut-off" in w for w in whole.warnings)
    cut = phyphox.read(_write(tmp_path / "Raw Data.csv", text[:-7]))
    np.testing.assert_array_equal(cut.values("acc"), whole.values("acc")[:-1])
    assert (f"Raw Data.csv: dropped the cut-off last line {len(_ACC_ROWS) + 1} (no line break after its last value "
            f"'{text[:-7].rpartition(',')[2]}', which is cut short): the log ends mid-line") in cut.warnings
    resaved = text.replace("E+00", "").replace("E-02", "e-2")
    assert len(phyphox.read(_write(tmp_path / "resaved.csv", resaved[:-3])).stream("acc")) == len(_ACC_ROWS)


def _write(p: Path, text: str) -> Path:
    p.write_text(text, encoding="utf-8")
    return p
