import gzip

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import xio
from tests.conftest import data_path
from tests.pdr.io._registry import detect_or_skip

HEADER = ("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
          "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)")


def _text(n=40, extra_rows=()):
    rows = [HEADER]
    for i in range(n):
        rows.append(f"{i * 0.0025!r},90,0,-180,0,0,1")
    rows.extend(extra_rows)
    return "\n".join(rows) + "\n"


def _write(tmp_path, text, name="walk.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_units_converted(tmp_path):
    p = _write(tmp_path, _text())
    assert xio.sniff(p)
    rec = xio.read(p)
    np.testing.assert_allclose(rec.values("gyro")[0], [np.pi / 2, 0, -np.pi])
    np.testing.assert_allclose(rec.values("acc")[0], [0, 0, 9.80665])
    assert rec.stream("acc").median_rate_hz() == pytest.approx(400.0)
    assert rec.device.placement == "foot" and rec.device.platform == "imu"


def test_optional_magnetometer_and_rad_units(tmp_path):
    header = ("Time (s),Gyroscope X (rad/s),Gyroscope Y (rad/s),Gyroscope Z (rad/s),Accelerometer X (m/s^2),"
              "Accelerometer Y (m/s^2),Accelerometer Z (m/s^2),Magnetometer X (µT),Magnetometer Y (µT),"
              "Magnetometer Z (µT),Barometer (hPa)")
    p = _write(tmp_path, header + "\n0,1,2,3,0,0,9.8,20,0,-40,1013\n0.01,1,2,3,0,0,9.8,20,0,-40,1013\n")
    rec = xio.read(p)
    np.testing.assert_allclose(rec.values("gyro")[0], [1, 2, 3])
    np.testing.assert_allclose(rec.values("mag")[0], [20, 0, -40])
    np.testing.assert_allclose(rec.values("baro")[:, 0], [1013, 1013])


def test_repeated_rows_dropped_with_warning(tmp_path):
    lines = _text(5).splitlines()
    lines.insert(3, lines[2])  # an exact copy, as in the x-io logs
    rec = xio.read(_write(tmp_path, "\n".join(lines) + "\n"))
    assert len(rec.stream("acc")) == 5
    assert rec.warnings == ("walk.csv: dropped 1 of 6 samples whose time repeats (1) or goes backwards (0), first at "
                            "line 4 (2500000 then 2500000)",)


def test_gz(tmp_path):
    gz = tmp_path / "walk.csv.gz"
    gz.write_bytes(gzip.compress(_text().encode()))
    assert xio.sniff(gz)
    assert len(xio.read(gz).stream("gyro")) == 40


@pytest.mark.parametrize(("text", "line", "field", "match"), [
    ("", 1, None, "empty file"),
    (HEADER + "\n", 2, None, "no samples"),
    (_text(3) + "0.01,1,2,3,0,0\n", 5, None, "expected 7 fields"),  # cut off, not at the end (at the end: dropped)
    (_text(3, ["0.01,1,2,3,0,0,1,7"]), 5, None, "expected 7 fields"),
    (_text(3, ["0.01,1,x2,3,0,0,1"]), 5, "Gyroscope Y (deg/s)", "not a number"),
    (_text(3, ["0.01,1,2,3,0,NaN,1"]), 5, "Accelerometer Y (g)", "not finite"),
    (_text(3, ["0.001,1,2,3,0,0,1", "0.0015,1,2,3,0,0,1"]), 5, "Time (s)", "backwards in 2 of"),
    # a repeated row (dropped) before the clock goes back: the error named the repeat's line 3 ("0.0025 then 0.0025")
    (_text(3).replace("0.005,", "0.0025,") + "0.001,1,2,3,0,0,1\n0.0015,1,2,3,0,0,1\n", 5, "Time (s)",
     r"backwards in 2 of 5 samples \(first at line 5: 2500000 then 1000000\)"),
    (HEADER.replace("(g)", "(furlongs)") + "\n0,1,2,3,0,0,1\n", 1, "Accelerometer X (furlongs)", "unknown"),
])
def test_bad_input_names_file_line_field(tmp_path, text, line, field, match):
    p = _write(tmp_path, text)
    with pytest.raises(InputError, match=match) as err:
        xio.read(p)
    assert err.value.source == str(p) and err.value.line == line and err.value.field == field


def test_old_mac_line_ends_read_as_line_feeds(tmp_path):
    """A log whose lines end in CR alone (an old Mac editor) failed with 'line 1: unreadable header line' and no
    file name (the header was split again from the text's first line feed); it reads as the same log with LF does."""
    p = tmp_path / "walk.csv"
    p.write_bytes(_text().replace("\n", "\r").encode())
    ref = xio.read(_write(tmp_path, _text(), "ref.csv"))
    np.testing.assert_array_equal(xio.read(p).values("acc"), ref.values("acc"))


def test_value_beyond_any_float_in_si_names_line_and_field(tmp_path):
    """1e308 g is a float, but not once converted to m/s^2: it was refused by the stream as "stream 'acc': sample 2
    is not finite", without the file, line or column (and with numpy's overflow warning)."""
    p = _write(tmp_path, _text(3, ["0.01,1,2,3,0,1e308,1"]))
    with pytest.raises(InputError, match="beyond") as err:
        xio.read(p)
    assert (err.value.source, err.value.line, err.value.field) == (str(p), 5, "Accelerometer Y (g)")


@pytest.mark.parametrize("gz", [False, True])
def test_last_line_cut_mid_number_dropped_with_warning(tmp_path, gz):
    """A recording cut off in the last value of its last row (all fields there, no line break: 0.811 of 0.8113459)
    reads as the log without that row, with a warning naming the file and line; a whole log keeps every row."""
    whole = _text(5, ["0.0125,1,2,3,-0.5128708,0.3132063,0.8113459"])
    cut = whole[:-5]
    assert cut.endswith(",0.811")
    name = "walk.csv.gz" if gz else "walk.csv"
    p = tmp_path / name
    p.write_bytes(gzip.compress(cut.encode()) if gz else cut.encode())
    rec = xio.read(p)
    assert len(rec.stream("acc")) == 5
    np.testing.assert_array_equal(rec.values("acc"), xio.read(_write(tmp_path, _text(5), "ref.csv")).values("acc"))
    assert rec.warnings == (f"{name}: dropped the cut-off last line 7 (no line break after its last value, which "
                            "may be cut short): the log ends mid-line",)
    assert len(xio.read(_write(tmp_path, whole, "whole.csv")).stream("acc")) == 6


@pytest.mark.parametrize("name", ["walk.txt", "walk.dat", "walk"])
def test_recognised_by_its_header_whatever_the_extension(tmp_path, name):
    """An x-io log saved as walk.txt or walk.dat was 'not a supported log format' (the sniffer wanted .csv); its
    header names it, and it reads as the .csv does."""
    from pdr.io import detect_format

    p = _write(tmp_path, _text(), name)
    assert detect_format(p) == "xio"
    np.testing.assert_array_equal(xio.read(p).values("acc"), xio.read(_write(tmp_path, _text())).values("acc"))


def test_garbage_and_foreign(tmp_path):
    g = _write(tmp_path, "", "g.csv")
    g.write_bytes(b"\x00\xff" * 500)
    assert not xio.sniff(g)
    with pytest.raises(InputError, match="binary"):
        xio.read(g)
    phyphox = _write(tmp_path, '"Time (s)","Gyroscope x (rad/s)","Gyroscope y (rad/s)"\n0,1,2\n', "Gyroscope.csv")
    assert not xio.sniff(phyphox)
    assert not xio.sniff(tmp_path)


@pytest.mark.data
def test_real_short_walk():
    p = data_path("xio_gait_loop", "short_walk.csv")
    rec = xio.read(p)
    assert rec.stream("acc").median_rate_hz() == pytest.approx(398.3, abs=1.0)
    assert rec.duration_s == pytest.approx(41.6, abs=0.1)
    assert len(rec.stream("acc")) == 16539 - 205  # the repeated rows are gone
    assert np.linalg.norm(rec.values("acc")[:200], axis=1).mean() == pytest.approx(9.80, abs=0.05)
    assert np.abs(rec.values("gyro")[:200]).max() < 0.1  # rad/s while standing
    assert any("dropped 205 of 16539 samples whose time repeats (205)" in w for w in rec.warnings)
    assert detect_or_skip(p) == "xio"
