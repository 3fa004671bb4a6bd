"""Microsoft indoor-location trace reader: real traces, reference-reader agreement, quirks, bad input."""

from __future__ import annotations

import gzip
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.io import ms_indoor
from tests.conftest import SHARED_DATA
from tests.pdr.io.dataset_samples import detect_or_skip, foreign_to, sample_path, samples_of

HEADER = "#\tstartTime:1574142011992\n#\tSiteID:abc\tFloorName:B1\n#\tBrand:OPPO\tModel:PBCM10\n"
ACC1 = "1574142012137\tTYPE_ACCELEROMETER\t0.1\t0.2\t9.8\t2"
ACC2 = "1574142012157\tTYPE_ACCELEROMETER\t0.1\t0.3\t9.8\t2"
RV1 = "1574142012137\tTYPE_ROTATION_VECTOR\t0.0\t0.0\t0.0\t3"
WP1 = "1574142012005\tTYPE_WAYPOINT\t165.0\t100.5"
WP2 = "1574142013005\tTYPE_WAYPOINT\t160.0\t97.5"


def _write(tmp_path: Path, lines: list[str] | bytes, name: str = "trace.txt") -> Path:
    p = tmp_path / name
    p.write_bytes(lines if isinstance(lines, bytes) else (HEADER + "\n".join(lines) + "\n").encode())
    return p


# ---------------------------------------------------------------------------------------------------------
# real data

@pytest.mark.data
def test_real_trace_rates_units_and_waypoints():
    path = sample_path("ms_indoor:trace")
    rec = ms_indoor.read(path)
    assert rec.format == "ms_indoor" and rec.warnings == ()
    assert rec.device.model == "PBCM10" and rec.device.platform == "android" and rec.device.placement == "hand"
    assert set(rec.streams) == {"acc", "gyro", "mag", "orientation", "acc_uncal", "gyro_uncal", "mag_uncal"}
    for kind in rec.streams:
        assert len(rec.stream(kind)) == 1403
        assert rec.stream(kind).median_rate_hz() == pytest.approx(50.0, rel=0.01)
    assert rec.duration_s == pytest.approx(27.68, abs=0.05)
    assert rec.meta["clock"] == "unix_epoch"
    assert rec.t0_ns == 1574142012005 * 1_000_000  # the first waypoint comes first
    assert rec.meta["ignored_records"]["TYPE_WIFI"] == 3885
    # walking: the mean specific force is gravity, ~ (0, 0, +g) in ENU after rotating by q_nb
    acc = rec.values("acc")
    assert np.mean(np.linalg.norm(acc, axis=1)) == pytest.approx(10.0, abs=0.6)
    acc_n = quat.rotate(rec.values("orientation"), acc)
    np.testing.assert_allclose(np.mean(acc_n, axis=0), [0.0, 0.0, 9.8], atol=0.4)
    pos = rec.truth.positions
    assert pos is not None and len(pos) == 6
    assert pos.kind == "waypoint" and pos.frame == "map" and np.all(pos.floor == 3.0)
    np.testing.assert_allclose(pos.pos_m[0], [165.0072, 100.43866, 0.0])
    assert pos.t_s[0] == 0.0 and pos.t_s[-1] == pytest.approx(27.332)


@pytest.mark.data
def test_agrees_with_reference_reader():
    path = SHARED_DATA.parent / "tools" / "ms_ref.py"
    if not path.exists():
        pytest.skip(f"reference reader not available: {path}")
    spec = importlib.util.spec_from_file_location("ms_ref", path)
    assert spec is not None and spec.loader is not None
    ref = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ref)
    trace = sample_path("ms_indoor:trace")
    tr = ref.read_trace(str(trace))
    rec = ms_indoor.read(trace)
    t0 = rec.origin_ns / 1e9
    np.testing.assert_allclose(t0 + rec.t_s("acc"), tr["TYPE_ACCELEROMETER"][:, 0], atol=1e-6)
    np.testing.assert_allclose(rec.values("acc"), tr["TYPE_ACCELEROMETER"][:, 1:4])
    np.testing.assert_allclose(rec.values("orientation")[:, 1:], tr["TYPE_ROTATION_VECTOR"][:, 1:4], atol=1e-6)
    pos = rec.truth.positions
    assert pos is not None
    np.testing.assert_allclose(t0 + pos.t_s, tr["WAYPOINT"][:, 0], atol=1e-6)
    np.testing.assert_allclose(pos.pos_m[:, :2], tr["WAYPOINT"][:, 1:3])


@pytest.mark.data
def test_detect_format_picks_ms_indoor():
    assert detect_or_skip(sample_path("ms_indoor:trace")) == "ms_indoor"


@pytest.mark.data
@pytest.mark.parametrize("key", foreign_to("ms_indoor"))
def test_sniff_rejects_other_datasets(key):
    assert ms_indoor.sniff(sample_path(key)) is False


def test_samples_table_lists_ms_indoor():
    assert samples_of("ms_indoor") == ["ms_indoor:trace"]


# ---------------------------------------------------------------------------------------------------------
# synthetic traces

def test_minimal_trace_plain_and_gzip(tmp_path):
    p = _write(tmp_path, [WP1, ACC1, RV1, ACC2, WP2])
    gz = tmp_path / "trace.txt.gz"
    gz.write_bytes(gzip.compress(p.read_bytes()))
    assert ms_indoor.sniff(p) and ms_indoor.sniff(gz)
    rec = ms_indoor.read(p)
    assert rec == ms_indoor.read(gz)
    assert rec.t0_ns == 1574142012005 * 1_000_000
    np.testing.assert_allclose(rec.t_s("acc"), [0.132, 0.152])
    np.testing.assert_array_equal(rec.values("orientation"), [[1.0, 0.0, 0.0, 0.0]])
    pos = rec.truth.positions
    assert pos is not None and np.all(pos.floor == -1.0)  # B1
    np.testing.assert_allclose(pos.t_s, [0.0, 1.0])


def test_run_on_line_is_split(tmp_path):
    # the accuracy '2' of the first record runs into the next record's timestamp
    run_on = ACC1 + ACC2
    rec = ms_indoor.read(_write(tmp_path, [WP1, run_on, RV1]))
    assert len(rec.stream("acc")) == 2
    np.testing.assert_allclose(rec.values("acc")[1], [0.1, 0.3, 9.8])
    assert any("split 1 line" in w for w in rec.warnings)


def test_run_on_fragment_that_lost_fields_is_dropped(tmp_path):
    broken = "1574142012137\tTYPE_ACCELEROMETER\t0.1\t0.2" + ACC2
    rec = ms_indoor.read(_write(tmp_path, [WP1, broken, RV1]))
    assert len(rec.stream("acc")) == 1
    assert any("dropped 1 malformed fragment" in w and "(lines 5)" in w for w in rec.warnings)


def test_repeated_timestamps_keep_the_first_sample(tmp_path):
    other = ACC1.replace("\t0.2\t", "\t0.5\t")
    rec = ms_indoor.read(_write(tmp_path, [ACC1, ACC1, other, ACC2]))
    np.testing.assert_allclose(rec.values("acc")[:, 1], [0.2, 0.3])
    (warning,) = rec.warnings
    assert "TYPE_ACCELEROMETER dropped 2 of 4 samples whose time repeats (2)" in warning
    assert "first at line 5" in warning


@pytest.mark.parametrize(("lines", "match"), [
    ([], "no accelerometer"),
    ([WP1], "no accelerometer"),
    ([ACC1, "15741420"], r"line 5: expected '<unix_ms>"),
    ([ACC1, "1574142012157\tTYPE_ACCELEROMETER\t0.1\t0.3"], r"line 5: expected 5 fields"),
    ([ACC1, ACC2 + "\t7"], r"line 5: expected 5 fields"),
    ([ACC1, ACC2.replace("0.3", "abc")], r"line 5, field 'y': 'abc' is not a number"),
    ([ACC1, ACC2.replace("0.3", "NaN")], r"line 5, field 'y': value nan is not finite"),
    ([ACC2, ACC1, ACC1], r"line 5, field 'timestamp_ms': TYPE_ACCELEROMETER time goes backwards in 2 of 3"),
    ([ACC1, WP2, WP1], r"line 6, field 'timestamp_ms': waypoint time goes backwards"),
])
def test_bad_input_names_file_and_line(tmp_path, lines, match):
    p = _write(tmp_path, lines)
    with pytest.raises(InputError, match=match) as info:
        ms_indoor.read(p)
    assert str(p) in str(info.value)


def test_binary_garbage_and_sniffing(tmp_path):
    p = _write(tmp_path, bytes(range(256)) * 8, "garbage.txt")
    assert ms_indoor.sniff(p) is False
    with pytest.raises(InputError, match="binary"):
        ms_indoor.read(p)
    assert ms_indoor.sniff(tmp_path) is False
    assert ms_indoor.sniff(tmp_path / "missing.txt") is False
    assert ms_indoor.sniff(_write(tmp_path, b"\x1f\x8bbroken", "x.txt.gz")) is False
    with pytest.raises(InputError, match="not a folder"):
        ms_indoor.read(tmp_path)


def test_a_dataset_folder_says_the_layout_and_names_a_trace(tmp_path):
    """The dataset's root, a site or a floor folder (traces 4, 3 or 2 levels down: <site>/<floor>/path_data_files/)
    given as a log: the root got the generic 'not a supported log format ...; pass --format to force one', and with
    --format ms_indoor every folder 'a ... trace is a single .txt file, not a folder'; both now say the layout and
    name a trace below the folder. path_data_files/ itself keeps its message (the traces it holds)."""
    from pdr.errors import UnknownFormatError
    from pdr.io import read_recording
    from tests.conftest import REPO_ROOT

    trace = (REPO_ROOT / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz").read_bytes()
    root = tmp_path / "ms_indoor_location"
    (root / "site2" / "F3" / "path_data_files").mkdir(parents=True)
    (root / "site2" / "F3" / "path_data_files" / "5dd5.txt.gz").write_bytes(trace)
    (root / "site2" / "F3" / "floor_info.json").write_text("{}")
    (root / "SOURCE.md").write_text("traces\n")
    for folder, below in ((root, "site2/F3/"), (root / "site2", "F3/"), (root / "site2" / "F3", "")):
        why = ("a folder of the Microsoft indoor-location dataset, not one trace: its traces are "
               f"<site>/<floor>/path_data_files/<trace>.txt[.gz] ({below}path_data_files/5dd5.txt.gz here); give one "
               "trace file, or the folder to 'pdr eval ms'")
        with pytest.raises(UnknownFormatError) as err:
            read_recording(folder)
        assert err.value.message == f"not a readable log: {why}" and err.value.source == str(folder)
        with pytest.raises(InputError) as refused:
            ms_indoor.read(folder)
        assert refused.value.message == why
    with pytest.raises(UnknownFormatError, match="not one log but a folder that holds logs"):
        read_recording(root / "site2" / "F3" / "path_data_files")
    assert ms_indoor.near_miss(tmp_path / "elsewhere") is None and ms_indoor.near_miss(root / "SOURCE.md") is None


def test_floor_names():
    assert ms_indoor.floor_number("F3") == 3.0
    assert ms_indoor.floor_number("2F") == 2.0
    assert ms_indoor.floor_number("B2") == -2.0
    assert np.isnan(ms_indoor.floor_number("L"))


# ---------------------------------------------------------------------------------------------------------
# array path against the line-by-line path

def _same_parse(fast, exact) -> None:  # noqa: ANN001
    assert fast is not None
    assert list(fast[0]) == list(exact[0])
    for tag, (arr, lines) in exact[0].items():
        assert fast[0][tag][0].tobytes() == arr.tobytes() and list(fast[0][tag][1]) == lines
    assert fast[1] == exact[1] and list(fast[1]) == list(exact[1])       # ignored records, first-seen order
    assert fast[2] == exact[2] and fast[3] == exact[3]


def test_array_path_equals_line_by_line_path(tmp_path):
    text = ("\ufeff#\tSiteID:x\tSiteName:杭州大悦城\tFloorName:F4\n" + "\n".join([
        WP1, "1574142012100\tTYPE_WIFI\tcafé\t-50", ACC1, "1574142012137\tTYPE_BEACON\t1\t2", RV1,
        "1574142012140\tTYPE_GYROSCOPE_UNCALIBRATED\t0.81\t0.086\t0.14\t-0.0024\t-0.0022\t7.171631E-4\t3",
        "", "1574142012141\tTYPE_GYROSCOPE\t1e-30\t0.1234567890123456\t-0\t3\t", ACC2,
        "1574142012150\tTYPE_WIFI\tx\t-60", WP2]) + "\r\n").encode()
    p = _write(tmp_path, text)
    raw = p.read_bytes()
    fast, exact = ms_indoor._parse_fast(raw), ms_indoor._parse_exact(str(p), raw)
    _same_parse(fast, exact)
    assert fast is not None
    assert exact[1] == {"TYPE_WIFI": 2, "TYPE_BEACON": 1} and exact[2]["SiteName"] == "杭州大悦城"
    assert np.signbit(fast[0]["TYPE_GYROSCOPE"][0][0, 3])


@pytest.mark.parametrize("line", ["1574142012157\tTYPE_ACCELEROMETER\t0.1\t0.3\t9.8\t2\t\t",         # two tabs
                                  "1574142012157\tTYPE_ACCELEROMETER\t0.1\tx\t9.8\t2",               # text
                                  "1574142012157\tTYPE_ACCELEROMETER\t0.1\t0.3\t9.8",                # short
                                  "1574142012157",                                                   # no tag
                                  " 1574142012157\tTYPE_ACCELEROMETER\t0.1\t0.3\t9.8\t2",            # blank first
                                  "1574142012157\tTYPE_ACCELEROMETER\t0.1\t0.3\t9.8\t2" + ACC2])     # run-on
def test_array_path_leaves_unusual_lines_to_the_line_by_line_path(tmp_path, line):
    raw = _write(tmp_path, [ACC1, line]).read_bytes()
    assert ms_indoor._parse_fast(raw) is None


@pytest.mark.parametrize("record", [ACC1, "1574142012001\tTYPE_DIST1\t11.6\t-6.5\t6.3", WP1],
                         ids=["accelerometer", "digit in its tag", "waypoint"])
@pytest.mark.parametrize("bom", [b"", b"\xef\xbb\xbf"], ids=["plain", "BOM"])
def test_a_trace_of_one_record_is_recognised(tmp_path, record, bom):
    """A trace of one record was 'not a supported log format (...); pass --format to force one' when its record's
    tag holds a digit (TYPE_DIST1, the first record of the dataset's traces) or the file starts with a BOM (a second
    record's line matched): it is a trace, read or refused saying why."""
    from pdr.io import detect_format, read_recording

    p = _write(tmp_path, bom + record.encode() + b"\n")
    assert detect_format(p) == "ms_indoor"
    if record == ACC1:
        assert len(read_recording(p).stream("acc")) == 1
    else:
        with pytest.raises(InputError, match="no accelerometer, gyroscope, magnetometer or rotation-vector records"):
            read_recording(p)


@pytest.mark.parametrize("tail", ["", "1574142012137\tTYPE_ACCELEROMETER"], ids=["header only", "record cut"])
def test_a_trace_header_without_a_whole_record_says_so(tmp_path, tail):
    """A trace cut in or before its first record was 'not a supported log format (...)'; it says what it lacks."""
    from pdr.errors import UnknownFormatError
    from pdr.io import read_recording

    p = _write(tmp_path, (HEADER + tail).encode())
    with pytest.raises(UnknownFormatError) as err:
        read_recording(p)
    assert err.value.message == ("not a readable log: a Microsoft indoor-location trace (its header "
                                 "'#<TAB>startTime:...') without a whole record ('<13-digit ms><TAB>TYPE_<NAME><TAB>"
                                 "<values>') after it: it needs at least one")
    assert ms_indoor.near_miss(_write(tmp_path, [ACC1], "whole.txt")) is None
