"""GetSensorData / IPIN logfile reader: real logfiles and .mat exports, reference-scorer agreement, bad input."""

from __future__ import annotations

import gzip
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.io import ipin
from pdr.io.android import rotation_vector_to_q_nb
from tests.conftest import SHARED_DATA
from tests.pdr.io.dataset_samples import detect_or_skip, foreign_to, sample_path, samples_of

HEADER = """% LogFile created by the 'GetSensorData' App for Android.
% Model:                   \tSM-TEST
"""
GOOD = HEADER + """ACCE;0.050;100.000;0.10000;0.20000;9.80000;3
GYRO;0.052;100.001;0.01000;0.02000;0.03000;3
ACCE;0.070;100.020;0.10000;0.20000;9.81000;3
GYRO;0.072;100.011;0.01000;0.02000;0.03000;3
AHRS;0.073;100.020;1.0;2.0;3.0;0.0;0.0;0.0;3
POSI;0.080;1;49.4611;11.1110;0;100
"""


def _load_reference():
    path = SHARED_DATA.parent / "tools" / "ipin_ref.py"
    if not path.exists():
        pytest.skip(f"reference scorer not available: {path}")
    spec = importlib.util.spec_from_file_location("ipin_ref", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# ---------------------------------------------------------------------------------------------------------
# real data

@pytest.mark.data
def test_sm_a520f_logfile_rates_units_and_truth():
    path = sample_path("ipin:txt")
    rec = ipin.read(path)   # its speed: tools/reader_speed.py (no wall-clock assertion on a shared machine)
    assert rec.format == "ipin" and rec.t0_ns == 0
    assert rec.device.model == "SM-A520F" and rec.device.platform == "android"
    assert rec.device.role == "phone" and rec.device.placement == "hand"
    assert set(rec.streams) == {"acc", "gyro", "mag", "baro", "orientation"}
    assert rec.stream("acc").median_rate_hz() == pytest.approx(50.0, rel=0.02)
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(100.0, rel=0.02)
    assert rec.stream("mag").median_rate_hz() == pytest.approx(50.0, rel=0.02)
    assert 5.0 < rec.stream("baro").median_rate_hz() < 7.0
    assert rec.duration_s == pytest.approx(232.0, abs=1.0)
    assert len(rec.stream("acc")) == 11521 and len(rec.stream("gyro")) == 23048
    # mbar == hPa, near the venue's altitude
    assert 950.0 < np.median(rec.values("baro")) < 1000.0
    assert np.median(np.linalg.norm(rec.values("acc"), axis=1)) == pytest.approx(9.8, abs=0.5)
    assert rec.meta["ignored_records"]["WIFI"] == 982
    # the first GNSS fix geo-references the log (the earth's field model's place and date), near the first landmark
    fix = rec.meta["location"]
    assert fix["fixes"] == rec.meta["ignored_records"]["GNSS"] > 0
    assert 2023.0 < 1970.0 + fix["unix_time_s"] / (365.25 * 86400) < 2024.0
    pos = rec.truth.positions
    assert pos is not None and len(pos) == 14
    assert pos.kind == "landmark" and pos.frame == "enu"
    # the origin is the file's first POSI (no hard-coded venue): the first landmark is at (0, 0)
    assert pos.origin_lat_lon_deg is not None and np.all(pos.pos_m[0] == 0.0)
    assert abs(fix["lat_deg"] - pos.origin_lat_lon_deg[0]) < 0.01
    assert abs(fix["lon_deg"] - pos.origin_lat_lon_deg[1]) < 0.01
    assert np.all(pos.floor == 0.0)
    assert pos.t_s[0] == pytest.approx(61.4235)


@pytest.mark.data
def test_time_axis_is_app_timestamp_and_matches_reference_scorer():
    path = sample_path("ipin:txt")
    ref = _load_reference()
    log = ref.read_log(str(path))
    rec = ipin.read(path)
    # POSI truth identical to the scorer's (same time base, same projection)
    t_ref, en_ref, floor_ref = ref.truth(log)
    pos = rec.truth.positions
    assert pos is not None
    np.testing.assert_allclose(pos.t_s, t_ref, atol=1e-9)
    # the scorer's frame starts at its fixed venue origin, ours at the first POSI; the same sphere (WGS-84 semi-major)
    np.testing.assert_allclose(pos.pos_m[:, :2] - pos.pos_m[0, :2], en_ref - en_ref[0], atol=5e-3)
    np.testing.assert_array_equal(pos.floor, floor_ref)
    # sample times: SensorTimestamp mapped onto AppTimestamp, within the delivery jitter
    for kind, key in (("acc", "ACCE"), ("gyro", "GYRO"), ("orientation", "AHRS")):
        app = log[key][:, 0]
        dt = rec.t_s(kind) - app
        assert abs(np.median(dt)) < 1e-3
        assert np.percentile(np.abs(dt), 99) < 0.05
        np.testing.assert_allclose(np.diff(rec.t_s(kind)), np.diff(log[key][:, 1]), atol=2e-9)


@pytest.mark.data
def test_orientation_is_q_nb_in_enu():
    rec = ipin.read(sample_path("ipin:txt"))
    q = rec.values("orientation")
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    t_acc, t_q = rec.t_s("acc"), rec.t_s("orientation")
    idx = np.clip(np.searchsorted(t_q, t_acc), 0, len(t_q) - 1)
    acc_n = quat.rotate(q[idx], rec.values("acc"))
    # at rest and on average specific force points up in ENU: ~ (0, 0, +g)
    np.testing.assert_allclose(np.median(acc_n, axis=0), [0.0, 0.0, 9.8], atol=0.15)
    # the horizontal magnetic field points north (indoors: loosely), not east/west or south
    t_mag = rec.t_s("mag")
    idx = np.clip(np.searchsorted(t_q, t_mag), 0, len(t_q) - 1)
    mag_n = np.median(quat.rotate(q[idx], rec.values("mag")), axis=0)
    assert mag_n[1] > 2.0 * abs(mag_n[0])
    assert mag_n[2] < 0.0  # northern hemisphere: field points down


@pytest.mark.data
def test_sm_g930f_logfile_has_50_hz_gyro_and_floor_changes():
    path = sample_path("ipin:txt").parent / "IPIN2023_T3_TrainingTrial52_repetition01.txt"
    if not path.exists():
        pytest.skip(f"not available: {path}")
    rec = ipin.read(path)
    assert rec.device.model == "SM-G930F"
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(50.0, rel=0.02)
    assert rec.stream("baro").median_rate_hz() == pytest.approx(10.0, rel=0.05)
    pos = rec.truth.positions
    assert pos is not None and pos.floor is not None and set(np.unique(pos.floor)) >= {0.0, -2.0}


@pytest.mark.data
def test_mat_export_elevator_trial():
    rec = ipin.read(sample_path("ipin:mat"))
    assert rec.t0_ns == 0 and rec.device.model == ""
    assert rec.stream("acc").median_rate_hz() == pytest.approx(50.0, rel=0.02)
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(100.0, rel=0.02)
    p = rec.values("baro")[:, 0]
    assert 975.5 < p.min() and p.max() < 977.5  # SOURCE.md: 976.09-976.87 hPa
    pos = rec.truth.positions
    assert pos is not None and len(pos) == 16 and pos.floor is not None
    change = np.flatnonzero(np.diff(pos.floor) != 0)
    assert pos.floor[0] == 0.0 and -2.0 in pos.floor
    i = int(change[0])  # elevator: same place on both floors
    np.testing.assert_allclose(pos.pos_m[i], pos.pos_m[i + 1], atol=1e-9)
    assert pos.t_s[i] == pytest.approx(74.569) and pos.t_s[i + 1] == pytest.approx(103.7967)
    # the export's Gnss rows (the text log's GNSS records without the tag) give the location fix, as a text log's
    fix = rec.meta["location"]
    assert fix["fixes"] == rec.meta["ignored_records"]["Gnss"] > 0
    assert pos.origin_lat_lon_deg is not None and abs(fix["lat_deg"] - pos.origin_lat_lon_deg[0]) < 0.01
    assert 2023.0 < 1970 + fix["unix_time_s"] / 3.15576e7 < 2024.0
    q = rec.values("orientation")
    idx = np.clip(np.searchsorted(rec.t_s("orientation"), rec.t_s("acc")), 0, len(q) - 1)
    np.testing.assert_allclose(np.median(quat.rotate(q[idx], rec.values("acc")), axis=0), [0, 0, 9.8], atol=0.2)


@pytest.mark.data
@pytest.mark.parametrize("key", ["ipin:txt", "ipin:mat"])
def test_detect_format_picks_ipin(key):
    assert detect_or_skip(sample_path(key)) == "ipin"


@pytest.mark.data
@pytest.mark.parametrize("key", foreign_to("ipin"))
def test_sniff_rejects_other_datasets(key):
    assert ipin.sniff(sample_path(key)) is False


def test_samples_table_lists_ipin():
    assert samples_of("ipin") == ["ipin:txt", "ipin:mat"]


# ---------------------------------------------------------------------------------------------------------
# synthetic files

def _write(tmp_path: Path, text: str | bytes, name: str = "log.txt") -> Path:
    p = tmp_path / name
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return p


def test_minimal_log_and_gzip_read_the_same(tmp_path):
    plain = ipin.read(_write(tmp_path, GOOD))
    gz = tmp_path / "log.txt.gz"
    gz.write_bytes(gzip.compress(GOOD.encode()))
    assert ipin.sniff(gz)
    zipped = ipin.read(gz)
    assert plain == zipped
    assert plain.device.model == "SM-TEST"
    # offset = median(App - Sensor) = -99.95 for ACCE -> t_s = Sensor - 99.95
    np.testing.assert_allclose(plain.t_s("acc"), [0.05, 0.07], atol=1e-9)
    np.testing.assert_array_equal(plain.values("orientation"), [[1.0, 0.0, 0.0, 0.0]])
    pos = plain.truth.positions
    assert pos is not None
    np.testing.assert_allclose(pos.pos_m, [[0.0, 0.0, 0.0]], atol=1e-9)


def test_rotation_vector_conversion_matches_a_known_rotation():
    # 90 deg about z: rotation vector (0, 0, sin 45deg); device x -> ENU north
    q = rotation_vector_to_q_nb(np.array([[0.0, 0.0, np.sin(np.pi / 4)]]))
    np.testing.assert_allclose(quat.rotate(q, [1.0, 0.0, 0.0]), [[0.0, 1.0, 0.0]], atol=1e-12)


@pytest.mark.parametrize(("body", "match"), [
    ("", "no ACCE"),
    ("% only a header\n", "no ACCE"),
    ("ACCE;0.05;100.0;0.1;0.2\n", r"line 1: expected 6 fields"),
    ("ACCE;0.05;100.0;0.1;0.2;9.8;3\nACCE;0.07;100.0\n", r"line 2: expected 6 fields"),
    ("ACCE;0.05;100.0;0.1;0.2;9.8;3;7\n", r"line 1: expected 6 fields"),
    ("ACCE;0.05;100.0;0.1;abc;9.8;3\n", r"line 1, field 'y': 'abc' is not a number"),
    ("ACCE;0.05;100.0;0.1;nan;9.8;3\n", r"line 1, field 'y': value nan is not finite"),
    ("ACCE;0.05;100.0;0.1;0.2;9.8;3\nACCE;0.07;99.9;0.1;0.2;9.8;3\nACCE;0.09;99.8;0.1;0.2;9.8;3\n",
     r"line 2, field 'ACCE SensorTimestamp': ACCE time goes backwards in 2 of 3 samples .*clock is broken"),
    ("ACCE;0.05;100.0;0.1;0.2;9.8;3\nPOSI;9.0;1;49.4;11.1;0;100\nPOSI;8.0;2;49.4;11.1;0;100\n",
     r"line 3: POSI time goes backwards"),
    ("ACCE;0.05;100.0;0.1;0.2;9.8;3\ngarbage here\n", r"line 2: not a GetSensorData record"),
])
@pytest.mark.parametrize("compiled", [True, False])
def test_bad_text_input_names_file_and_line(tmp_path, body, match, compiled, monkeypatch):
    monkeypatch.setattr(ipin, "_use_compiled", lambda size: compiled)   # numba's parser or numpy's text reader
    p = _write(tmp_path, body)
    with pytest.raises(InputError, match=match) as info:
        ipin.read(p)
    assert str(p) in str(info.value)


def test_binary_garbage_is_rejected(tmp_path):
    p = _write(tmp_path, bytes(range(256)) * 8, "garbage.txt")
    assert ipin.sniff(p) is False
    with pytest.raises(InputError, match="binary"):
        ipin.read(p)


def test_sniff_never_raises(tmp_path):
    assert ipin.sniff(tmp_path) is False
    assert ipin.sniff(tmp_path / "missing.txt") is False
    assert ipin.sniff(_write(tmp_path, b"MATLAB 5.0 MAT-file garbage", "x.mat")) is False
    assert ipin.sniff(_write(tmp_path, b"\x1f\x8bnot gzip", "x.txt.gz")) is False
    assert ipin.sniff(_write(tmp_path, "time,x,y,z\n1,2,3,4\n", "x.csv")) is False


def test_folder_is_rejected(tmp_path):
    with pytest.raises(InputError, match="not a folder"):
        ipin.read(tmp_path)


def _savemat(tmp_path: Path, **arrays) -> Path:
    from scipy.io import savemat
    p = tmp_path / "trial.mat"
    savemat(p, arrays)
    return p


def test_mat_roundtrip_and_bad_mat(tmp_path):
    acce = np.array([[0.05, 100.0, 0.1, 0.2, 9.8], [0.07, 100.02, 0.1, 0.2, 9.8]])
    posi = np.array([[0.06, 49.4611, 11.1110, -1.0]])
    p = _savemat(tmp_path, Acce=acce, Gyro=acce, Posi=posi)
    assert ipin.sniff(p)
    rec = ipin.read(p)
    np.testing.assert_allclose(rec.t_s("gyro"), [0.05, 0.07], atol=1e-9)
    assert rec.truth.positions is not None and rec.truth.positions.floor is not None
    assert rec.truth.positions.floor[0] == -1.0

    bad = acce.copy()
    bad[1, 3] = np.nan
    with pytest.raises(InputError, match=r"field 'Acce row 2'.*not finite"):
        ipin.read(_savemat(tmp_path, Acce=bad, Gyro=acce, Posi=posi))
    back = np.r_[acce, acce[:1]]
    back[1, 1] = 99.0  # one sample back: dropped, with a warning naming the row
    rec = ipin.read(_savemat(tmp_path, Acce=acce, Gyro=back, Posi=posi))
    assert len(rec.stream("gyro")) == 1 and any("GYRO" in w and "Gyro[1]" in w for w in rec.warnings)
    broken = np.array([[0.05, 100.0, 0.1, 0.2, 9.8], [0.07, 99.0, 0.1, 0.2, 9.8], [0.09, 98.0, 0.1, 0.2, 9.8]])
    with pytest.raises(InputError, match=r"field 'Gyro\[1\]'.*GYRO time goes backwards in 2 of 3 samples"):
        ipin.read(_savemat(tmp_path, Acce=acce, Gyro=broken, Posi=posi))
    with pytest.raises(InputError, match=r"field 'Acce'.*shape"):
        ipin.read(_savemat(tmp_path, Acce=acce[:, :3], Gyro=acce, Posi=posi))
    junk = _write(tmp_path, b"MATLAB 5.0 MAT-file" + bytes(200), "junk.mat")
    with pytest.raises(InputError, match=r"junk.mat: not a readable MATLAB \.mat file"):
        ipin.read(junk)


def _same_recording(a, b) -> None:
    assert a.streams.keys() == b.streams.keys()
    for k in a.streams:
        assert a.streams[k].t_ns.tobytes() == b.streams[k].t_ns.tobytes(), k
        assert a.streams[k].values.tobytes() == b.streams[k].values.tobytes(), k
    assert a.meta == b.meta and list(a.meta["ignored_records"]) == list(b.meta["ignored_records"])
    pa, pb = a.truth.positions, b.truth.positions
    assert (pa is None) == (pb is None)
    if pa is not None:
        assert pa.pos_m.tobytes() == pb.pos_m.tobytes() and pa.t_s.tobytes() == pb.t_s.tobytes()


EDGES = HEADER + """WIFI;0.01;100.0;net;00:11;2412;-60;
ACCE;0.050;100.000;-0.00000;.5;9.;3;
BLE4;0.05;iBeacon;x;-70;
AB;1;2

ACCE;0.070;100.020;-12.345678901234;0.20000;9.81000;3
 \t
GYRO;0.052;100.001;0.01000;-0.02000;0.03000;3
LIGH;0.06;100.0;12.0;3
POSI;0.080;1;49.4611;11.1110;0;100;
"""


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("crlf", [False, True])
def test_array_reader_equals_the_line_by_line_reader(tmp_path, crlf, compiled):
    text = EDGES.replace("\n", "\r\n") if crlf else EDGES
    p = tmp_path / "edges.txt"
    p.write_bytes(text.encode())
    raw = p.read_bytes()
    fast = ipin._read_text_fast(p, raw, compiled)
    assert fast is not None
    _same_recording(fast, ipin._read_text_exact(p, raw))
    assert fast.meta["ignored_records"] == {"WIFI": 1, "BLE4": 1, "AB": 1, "LIGH": 1}
    assert np.signbit(fast.streams["acc"].values[0, 0])


@pytest.mark.parametrize("line", ["ACCE;0.090;100.030;1e-30;0.2;9.8;3",           # power of ten beyond 1e22
                                  "ACCE;0.090;100.030;0.12345678901234567;0.2;9.8;3",  # 17 digits
                                  "ACCE;0.090;100.030;+0.1;0.2;9.8;3"])            # plus sign
def test_numbers_out_of_the_plain_form_take_the_exact_path_with_the_same_values(tmp_path, line):
    p = tmp_path / "unusual.txt"
    p.write_text(GOOD + line + "\n")
    raw = p.read_bytes()
    assert ipin._read_text_fast(p, raw) is None
    _same_recording(ipin.read(p), ipin._read_text_exact(p, raw))
    text_reader = ipin._read_text_fast(p, raw, compiled=False)    # numpy's reader takes them, correctly rounded
    assert text_reader is not None
    _same_recording(text_reader, ipin._read_text_exact(p, raw))


@pytest.mark.parametrize("line", ["ACCE;0.090;100.030;0.1; 0.2;9.8;3",            # a blank in a field
                                  "ACCE;0.090;100.030;0.1;0x1p3;9.8;3",           # hexadecimal
                                  "ACCE;0.090;100.030;0.1;inf;9.8;3",             # not finite
                                  "ACCE;0.090;100.030;0.1;1_0;9.8;3",             # float() takes it, C readers do not
                                  "ACCE;0.090;100.030;0.1;;9.8;3",                # an empty field
                                  "ACCE;0.090;100.030;0.1;0.2;9.8;3;;",           # a field too many
                                  "ACCE;0.090;100.030;0.1;0.2;9.8"])              # a field too few
def test_numpy_text_reader_leaves_anything_but_plain_decimals_to_the_exact_path(tmp_path, line):
    p = tmp_path / "unusual.txt"
    p.write_text(GOOD + line + "\n")
    assert ipin._read_text_fast(p, p.read_bytes(), compiled=False) is None


def test_plain_decimals_parse_to_the_values_float_gives() -> None:
    from pdr.io.text import ascii_lines
    rng = np.random.default_rng(7)
    texts = []
    for _ in range(3000):
        digits = int(rng.integers(1, 16))
        m = "".join(str(d) for d in rng.integers(0, 10, digits))
        dot = int(rng.integers(0, digits + 1))
        exponent = f"{'eE'[int(rng.integers(0, 2))]}{['', '-', '+'][int(rng.integers(0, 3))]}{rng.integers(0, 8)}"
        texts.append(("-" if rng.random() < 0.5 else "") + m[:dot] + "." + m[dot:]
                     + (exponent if rng.random() < 0.3 else ""))      # Java's Float.toString: 7.171631E-4
    rows = [texts[i:i + 3] for i in range(0, len(texts), 3)]
    lines = ascii_lines("\n".join(";".join(r) for r in rows).encode())
    assert lines is not None
    want = np.array([[float(v) for v in r] for r in rows]).tobytes()
    for compiled in (True, False):
        got = lines.fields(np.ones(len(rows), bool), 3, compiled=compiled)
        assert got is not None
        assert got.tobytes() == want


def test_first_gnss_fix_passes_over_bad_records_and_lines_that_only_contain_the_tag():
    log = (b"ACCE;1.0;2.0;0;0;9.8;3\nWIFI;1;GNSS;x\nGNSS;1.1;1686732686;not-a-number;11.1;365;0;20;0;1;1\n"
           b"GNSS;1.2;1686732687;95.0;11.1;365;0;20;0;1;1\nGNSS;1.3;1686732688;49.4614;11.1115;365;0;12;0;9;7")
    assert ipin.first_gnss_fix(log) == {"lat_deg": 49.4614, "lon_deg": 11.1115, "alt_m": 365.0,
                                        "horizontal_accuracy_m": 12.0, "unix_time_s": 1686732688.0}
    assert ipin.first_gnss_fix(b"ACCE;1.0;2.0;0;0;9.8;3\nGNSS;1.1\n") is None


def test_attitude_of_a_corrupt_rotation_vector_names_file_and_stream(tmp_path):
    """An AHRS row whose quaternion component is 1e308 (finite: the reader took it) was read as the zero quaternion,
    no attitude, without a word (`pdr inspect` printed numpy's overflow warning, "s = (x.conj() * x).real")."""
    from pdr.io import read_recording

    p = _write(tmp_path, GOOD.replace("AHRS;0.073;100.020;1.0;2.0;3.0;0.0;0.0;0.0;3",
                                      "AHRS;0.073;100.020;1.0;2.0;3.0;1e308;0.0;0.0;3"))
    with pytest.raises(InputError, match=r"sample 0 \(t 0.073 s\) is a quaternion of norm 0 .*not an attitude") as err:
        read_recording(p)
    assert (err.value.source, err.value.field) == (str(p), "orientation")


@pytest.mark.parametrize("source", ["text", "mat"])
def test_sensor_times_a_tenth_of_a_nanosecond_apart_are_a_repeat_dropped_with_a_warning(tmp_path, source):
    """SensorTimestamps 0.1 ns apart (in order in seconds, one nanosecond once rounded) refused the whole log:
    "stream 'acc': timestamp of sample 2 (...) duplicates sample 1"; the later record is a repeat now, dropped with a
    warning as exact repeats are (pdr.io.time_order on the int64 nanoseconds)."""
    from pdr.io import read_recording

    rows = [[0.050, 100.0, 0.1, 0.2, 9.8], [0.060, 100.0 + 1e-10, 0.1, 0.2, 9.8], [0.070, 100.02, 0.1, 0.2, 9.8]]
    posi = [0.06, 49.4611, 11.1110, 0.0]
    if source == "text":
        p = _write(tmp_path, HEADER + "".join(f"ACCE;{';'.join(map(repr, r))};3\n" for r in rows)
                   + "POSI;0.060;1;49.4611;11.1110;0;100\n")
    else:
        p = _savemat(tmp_path, Acce=np.array(rows), Gyro=np.array(rows), Posi=np.array([posi]))
    rec = read_recording(p)
    assert len(rec.stream("acc")) == 2
    assert any("ACCE dropped 1 of 3 samples whose time repeats (1)" in w for w in rec.warnings), rec.warnings
