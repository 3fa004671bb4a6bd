import copy
import gzip
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import sensor_logger
from tests.pdr.io._registry import detect_or_skip

FIXTURES = Path(__file__).parent / "fixtures" / "sensor_logger"
EXPORTS = ["android_face_up", "ios_face_up", "ios_face_up_standardised"]
FACE_UP = np.array([0.0, 0.0, 9.81])


def _zip_folder(folder: Path, out: Path, top: str | None = None) -> Path:
    with zipfile.ZipFile(out, "w") as zf:
        for f in sorted(folder.iterdir()):
            zf.write(f, f"{top}/{f.name}" if top else f.name)
    return out


def _assert_face_up(rec):
    for kind in ("acc", "gravity", "acc_uncal"):
        mean = rec.values(kind).mean(axis=0)
        np.testing.assert_allclose(mean, FACE_UP, atol=0.15, err_msg=kind)
    # the attitude rotates the device's up (its z axis) onto ENU up
    from pdr import quaternion
    up = quaternion.rotate(rec.values("orientation"), np.array([0.0, 0.0, 1.0]))
    assert np.all(up[:, 2] > 0.99)


@pytest.mark.parametrize("name", EXPORTS)
@pytest.mark.parametrize("packaging", ["folder", "zip", "zip_with_top_folder"])
def test_face_up_reads_plus_g_whatever_the_platform(name, packaging, tmp_path):
    path = FIXTURES / name
    if packaging == "zip":
        path = _zip_folder(path, tmp_path / f"{name}.zip")
    elif packaging == "zip_with_top_folder":
        path = _zip_folder(path, tmp_path / f"{name}.zip", top="2024-05-29_16-26-40")
    assert sensor_logger.sniff(path)
    rec = sensor_logger.read(path)
    _assert_face_up(rec)
    assert rec.warnings == ("Location.csv: header only, no fixes: the recording is not geo-referenced",)
    assert rec.device.platform == name.split("_")[0]
    assert rec.device.model in ("Pixel 7", "iPhone 14")
    assert rec.meta["convention"] == ("ios" if name == "ios_face_up" else "android")
    assert rec.format == "sensor_logger"
    for kind in ("lin_acc", "gyro", "mag", "baro", "gyro_uncal", "mag_uncal"):
        assert rec.has(kind), kind
    assert rec.values("baro").mean() == pytest.approx(1009.7, abs=0.1)


@pytest.mark.parametrize("name", ["android_push.json", "ios_push_list.json"])
def test_push_files_read_plus_g(name, tmp_path):
    p = FIXTURES / name
    assert sensor_logger.sniff(p)
    rec = sensor_logger.read(p)
    _assert_face_up(rec)
    assert rec.meta["session_id"].endswith("session-7f3a")
    gz = tmp_path / (name + ".gz")
    gz.write_bytes(gzip.compress(p.read_bytes()))
    assert sensor_logger.sniff(gz)
    assert sensor_logger.read(gz) == rec


def test_columns_are_read_by_name_not_position():
    """The export writes z,y,x: a reader going by position would swap x and z."""
    first = (FIXTURES / "android_face_up" / "Gravity.csv").read_text().splitlines()
    assert first[0] == "time,seconds_elapsed,z,y,x"
    rec = sensor_logger.read(FIXTURES / "android_face_up")
    z, y, x = (float(v) for v in first[1].split(",")[2:])
    np.testing.assert_array_equal(rec.values("gravity")[0], [x, y, z])
    assert rec.stream("gravity").t_ns[0] == int(first[1].split(",")[0])


def test_ios_acc_is_user_acceleration_plus_gravity_sign_flipped():
    folder = FIXTURES / "ios_face_up"
    rec = sensor_logger.read(folder)
    lin = np.loadtxt(folder / "Accelerometer.csv", delimiter=",", skiprows=1)
    grav = np.loadtxt(folder / "Gravity.csv", delimiter=",", skiprows=1)
    # same device-motion timestamps: exact sums, negated into the specific-force convention
    np.testing.assert_array_equal(rec.stream("acc").t_ns, rec.stream("lin_acc").t_ns)
    expected = -(lin[:, [4, 3, 2]] + grav[:, [4, 3, 2]])
    np.testing.assert_allclose(rec.values("acc"), expected, rtol=0, atol=1e-12)


def test_android_prefers_total_acceleration():
    rec = sensor_logger.read(FIXTURES / "android_face_up")
    total = np.loadtxt(FIXTURES / "android_face_up" / "TotalAcceleration.csv", delimiter=",", skiprows=1)
    assert len(rec.stream("acc")) == total.shape[0]
    np.testing.assert_array_equal(rec.values("acc")[:, 2], total[:, 2])


def _ios_message():
    return json.loads((FIXTURES / "ios_push_list.json").read_text())[0]


def test_parse_push_message_api():
    msg = _ios_message()
    rec = sensor_logger.parse_push_message(msg, source="message 0")
    assert rec.source == "message 0"
    assert rec.meta["message_id"] == 0 and rec.meta["device_id"] == "ios-0a1b2c"
    assert rec.meta["convention"] == "ios"
    _assert_face_up(rec)
    explicit = sensor_logger.parse_push_message(msg, platform="ios", standardised=False)
    assert dict(explicit.streams) == dict(rec.streams)
    assert explicit.device.platform == "ios" and rec.device.platform == "unknown"


def test_convention_inferred_from_gravity_and_orientation():
    msg = _ios_message()
    msg["payload"] = [e for e in msg["payload"] if e["name"] != "accelerometeruncalibrated"]
    rec = sensor_logger.parse_push_message(msg)
    assert rec.meta["convention"] == "ios" and "points down" in rec.meta["convention_reason"]
    _assert_face_up_minus_uncal(rec)


def _assert_face_up_minus_uncal(rec):
    np.testing.assert_allclose(rec.values("acc").mean(axis=0), FACE_UP, atol=0.15)


def test_unknown_convention_assumes_android_with_warning():
    msg = _ios_message()
    msg["payload"] = [e for e in msg["payload"] if e["name"] in ("gyroscope", "magnetometer")]
    rec = sensor_logger.parse_push_message(msg)
    assert rec.meta["convention"] == "android"
    assert any("platform unknown" in w for w in rec.warnings)


def test_wrong_orientation_convention_is_dropped():
    msg = copy.deepcopy(_ios_message())
    for e in msg["payload"]:
        if e["name"] == "orientation":  # a quaternion tilted by 90 degrees: cannot be this phone's attitude
            e["values"].update({"qw": 0.7071, "qx": 0.7071, "qy": 0.0, "qz": 0.0})
    rec = sensor_logger.parse_push_message(msg, platform="ios", standardised=False)
    assert not rec.has("orientation")
    assert any("orientation dropped" in w for w in rec.warnings)


def test_payload_order_and_repeats():
    msg = _ios_message()
    msg["payload"] = list(reversed(msg["payload"]))
    gyro = next(e for e in msg["payload"] if e["name"] == "gyroscope")
    msg["payload"].append(copy.deepcopy(gyro))
    rec = sensor_logger.parse_push_message(msg)
    assert np.all(np.diff(rec.stream("gyro").t_ns) > 0)
    assert any("gyroscope dropped 1 of" in w and "repeats (1)" in w and "payload[" in w for w in rec.warnings)


def test_string_times_and_ignored_readings():
    msg = _ios_message()
    for e in msg["payload"]:
        e["time"] = str(e["time"])
    msg["payload"].append({"name": "location", "time": "1717000000123456789", "values": {"latitude": 51.5}})
    rec = sensor_logger.parse_push_message(msg)
    assert rec.meta["ignored_readings"] == {"location": 1}
    assert rec.stream("acc").t_ns[0] > 1_700_000_000_000_000_000


@pytest.mark.parametrize(("mutate", "field", "match"), [
    (lambda m: m.__setitem__("payload", {}), "payload", "list of readings"),
    (lambda m: m["payload"][3]["values"].pop("x"), r"payload[3].values.x", "missing"),
    (lambda m: m["payload"][3]["values"].__setitem__("y", "abc"), "payload[3].values.y", "not a number"),
    (lambda m: m["payload"][3]["values"].__setitem__("z", float("nan")), "payload[3].values.z", "not finite"),
    (lambda m: m["payload"][5].__setitem__("time", True), "payload[5].time", "boolean"),
    (lambda m: m["payload"][5].pop("time"), "payload[5].time", "missing"),
    (lambda m: m["payload"][2].__setitem__("values", [1, 2, 3]), "payload[2].values", "object of values"),
    (lambda m: m["payload"].__setitem__(1, "accelerometer"), "payload[1]", "string 'name'"),
])
def test_bad_push_message_names_json_path(mutate, field, match):
    msg = _ios_message()
    msg["payload"] = [e for e in msg["payload"] if e["name"] in sensor_logger.READINGS]
    mutate(msg)
    with pytest.raises(InputError, match=match) as err:
        sensor_logger.parse_push_message(msg, source="message 7")
    assert err.value.field == field and err.value.source == "message 7"


def test_push_without_sensor_readings_and_mixed_sessions(tmp_path):
    with pytest.raises(InputError, match="no supported sensor readings"):
        sensor_logger.parse_push_message({"messageId": 1, "sessionId": "s", "deviceId": "d", "payload": [
            {"name": "location", "time": 1, "values": {}}]})
    msgs = json.loads((FIXTURES / "ios_push_list.json").read_text())
    msgs[1]["sessionId"] = "another"
    p = tmp_path / "mixed.json"
    p.write_text(json.dumps(msgs))
    with pytest.raises(InputError, match="2 recording sessions"):
        sensor_logger.read(p)


def test_json_export_records(tmp_path):
    folder = FIXTURES / "ios_face_up"
    records = [{"sensor": "Metadata", "platform": "ios", "standardisation": "false", "device name": "iPhone 14"}]
    for name in ("Accelerometer", "Gravity", "Orientation"):
        lines = (folder / f"{name}.csv").read_text().splitlines()
        header = lines[0].split(",")
        for line in lines[1:]:
            records.append({"sensor": name, **dict(zip(header, line.split(","), strict=True))})
    p = tmp_path / "export.json"
    p.write_text(json.dumps(records))
    assert sensor_logger.sniff(p)
    rec = sensor_logger.read(p)
    np.testing.assert_allclose(rec.values("acc").mean(axis=0), FACE_UP, atol=0.15)
    assert rec.device.platform == "ios"


def _copy_export(tmp_path, name="ios_face_up"):
    dst = tmp_path / name
    shutil.copytree(FIXTURES / name, dst)
    return dst


def _edit_line(path: Path, line: int, new: str | None):
    lines = path.read_text().splitlines()
    if new is None:
        del lines[line - 1:]
    else:
        lines[line - 1] = new
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(("edit", "line", "field", "match"), [
    (lambda p: p.write_text(p.read_text()[:-25]), None, None, None),  # cut-off last line: dropped, see below
    (lambda p: _edit_line(p, 4, "1717000000150000000,0.03,0.1"), 4, None, "expected 5 fields"),
    (lambda p: _edit_line(p, 4, "1717000000150000000,0.03,0.1,0.2,0.3,0.4"), 4, None, "expected 5 fields"),
    (lambda p: _edit_line(p, 5, "1717000000160000000,0.04,0.1,abc,0.3"), 5, "y", "not a number"),
    (lambda p: _edit_line(p, 5, "1717000000160000000,0.04,0.1,NaN,0.3"), 5, "y", "not finite"),
    (lambda p: (_edit_line(p, 6, "1717000000000000000,0.05,0.1,0.2,0.3"),
                _edit_line(p, 7, "1717000000000000001,0.05,0.1,0.2,0.3")), 6, "time", "backwards in 2 of"),
    (lambda p: _edit_line(p, 6, "1.7e18,0.05,0.1,0.2,0.3"), 6, "time", "not an integer"),
    (lambda p: p.write_text("time,seconds_elapsed,z,y\n1,0,1,2\n"), 1, "x", "missing column 'x'"),
    (lambda p: p.write_bytes(b"\x00\x01garbage" * 30), None, None, "binary"),
])
def test_bad_csv_names_file_line_field(tmp_path, edit, line, field, match):
    folder = _copy_export(tmp_path)
    target = folder / "Gyroscope.csv"
    edit(target)
    if match is None:  # a cut-off last line (the app stopped mid-line) is dropped with a warning naming it
        n = len(target.read_text().splitlines())
        rec = sensor_logger.read(folder)
        assert len(rec.stream("gyro")) == n - 2
        assert any(f"Gyroscope.csv: dropped the cut-off last line {n}" in w for w in rec.warnings), rec.warnings
        return
    with pytest.raises(InputError, match=match) as err:
        sensor_logger.read(folder)
    assert "Gyroscope.csv" in str(err.value.source)
    assert err.value.line == line and err.value.field == field


def test_repeated_timestamps_in_csv_are_dropped(tmp_path):
    folder = _copy_export(tmp_path)
    target = folder / "Gyroscope.csv"
    lines = target.read_text().splitlines()
    lines.insert(3, lines[2])
    target.write_text("\n".join(lines) + "\n")
    rec = sensor_logger.read(folder)
    assert len(rec.stream("gyro")) == len(lines) - 2
    assert any(w.startswith("Gyroscope.csv: dropped 1 of") and "first at line 4" in w for w in rec.warnings)


def test_missing_metadata_infers_convention(tmp_path):
    folder = _copy_export(tmp_path)
    (folder / "Metadata.csv").unlink()
    rec = sensor_logger.read(folder)
    assert rec.meta["convention"] == "ios" and rec.meta["metadata"] == "missing"
    _assert_face_up(rec)


def test_foreign_inputs_are_not_sniffed(tmp_path):
    assert not sensor_logger.sniff(tmp_path)  # empty folder
    (tmp_path / "Accelerometer.csv").write_text('"Time (s)","Acceleration x (m/s^2)"\n0,1\n')  # phyphox
    assert not sensor_logger.sniff(tmp_path)
    g = tmp_path / "g.json"
    g.write_bytes(bytes(range(256)))
    assert not sensor_logger.sniff(g)
    with pytest.raises(InputError):
        sensor_logger.read(g)
    other = tmp_path / "o.json"
    other.write_text('{"format": "pdr-batch/1"}')
    assert not sensor_logger.sniff(other)
    bad = tmp_path / "b.zip"
    bad.write_bytes(b"PK\x03\x04junk")
    assert not sensor_logger.sniff(bad)
    with pytest.raises(InputError, match="zip"):
        sensor_logger.read(bad)
    no_sensors = tmp_path / "empty_export"
    no_sensors.mkdir()
    (no_sensors / "Metadata.csv").write_text("platform\nios\n")
    with pytest.raises(InputError, match="no supported sensor CSV"):
        sensor_logger.read(no_sensors)


@pytest.mark.parametrize("name", [*EXPORTS, "android_push.json", "ios_push_list.json"])
def test_detect_format(name):
    assert detect_or_skip(FIXTURES / name) == "sensor_logger"


def test_empty_sensor_csv_is_skipped_with_a_warning(tmp_path):
    # Sensor Logger writes 0-byte files for streams that recorded nothing (Annotation.csv, Barometer.csv).
    folder = _copy_export(tmp_path)
    (folder / "Barometer.csv").write_text("")
    rec = sensor_logger.read(folder)
    assert not rec.has("baro") and rec.has("acc") and rec.has("gyro")
    assert any("Barometer.csv: empty file" in w for w in rec.warnings)


@pytest.mark.parametrize(("content", "match"), [("", "empty file"),
                                               ("time,seconds_elapsed,z,y,x\n", "header only, no samples")])
def test_every_sensor_csv_empty_is_refused_naming_them(tmp_path, content, match):
    folder = tmp_path / "export"
    folder.mkdir()
    (folder / "Metadata.csv").write_text("version,device name,recording time,platform\n2,SM-N960F,x,android\n")
    (folder / "Accelerometer.csv").write_text(content)
    with pytest.raises(InputError, match=f"Accelerometer.csv: {match}"):
        sensor_logger.read(folder)


def _write_v2_export(folder: Path) -> Path:
    """A Sensor Logger export of early 2021 (Metadata version 2): ``time,z,y,x``, no ``seconds_elapsed``."""
    folder.mkdir()
    (folder / "Metadata.csv").write_text("version,device name,recording time,platform\n2,SM-N960F,"
                                         "2021-00-12_21-13-19,android")      # no final newline, as the app
    t0 = 1610478799122730000
    rows = [f"{t0 + i * 10_000_000},{9.8 + 0.01 * i},{0.1},{-0.2}" for i in range(50)]
    grav = [f"{t0 + i * 10_000_000},9.81,0.0,0.0" for i in range(50)]
    lin = [f"{t0 + i * 10_000_000},{0.01 * i},0.1,-0.2" for i in range(50)]
    (folder / "Gyroscope.csv").write_text("time,z,y,x\n" + "\n".join(rows) + "\n")
    (folder / "Gravity.csv").write_text("time,z,y,x\n" + "\n".join(grav) + "\n")
    (folder / "Accelerometer.csv").write_text("time,z,y,x\n" + "\n".join(lin) + "\n")
    (folder / "Barometer.csv").write_text("time,relativeAltitude,pressure\n"
                                          f"{t0},0,1017.08\n{t0 + 100_000_000},0,1017.09\n")
    (folder / "Location.csv").write_text("")
    return folder


def test_metadata_version_2_export_is_read(tmp_path):
    folder = _write_v2_export(tmp_path / "walk")
    assert sensor_logger.sniff(folder)
    rec = sensor_logger.read(folder)
    assert rec.device.platform == "android" and rec.device.model == "SM-N960F"
    assert rec.meta["convention"] == "android"
    np.testing.assert_allclose(rec.values("gyro")[0], [-0.2, 0.1, 9.8])        # x, y, z read by name
    np.testing.assert_allclose(rec.values("acc")[3], [-0.2, 0.1, 9.81 + 0.03])  # accelerometer + gravity
    assert rec.values("baro")[1, 0] == pytest.approx(1017.09)
    assert rec.warnings == ("Location.csv: empty file (no header, no fixes): the recording is not geo-referenced",)


def test_time_and_components_without_metadata_are_not_sniffed(tmp_path):
    # Without Metadata.csv and seconds_elapsed, a folder of time,x,y,z files is someone else's format.
    folder = _write_v2_export(tmp_path / "walk")
    (folder / "Metadata.csv").unlink()
    assert not sensor_logger.sniff(folder)


@pytest.mark.data
@pytest.mark.parametrize("walk", ["inhand-20-steps-Zyf", "inhand-30-steps-Zyf", "texting-30-steps-Zyf",
                                  "inpocket-27-steps-Matan"])
def test_real_sensor_logger_walks_are_read(walk):
    from pdr.io.registry import detect_format, read_recording
    from tests.conftest import data_path
    path = data_path("sensor_logger_walks", walk)
    assert detect_format(path) == "sensor_logger"
    rec = read_recording(path)
    assert rec.device.platform == "android"
    for kind in ("acc", "gyro", "mag", "gravity"):
        assert rec.has(kind), kind
    # at rest at the start the specific force is gravity, in m/s^2 and the Android sign
    assert np.linalg.norm(rec.values("acc")[:20].mean(axis=0)) == pytest.approx(9.81, abs=0.5)


def test_location_fixes_geo_reference_the_recording(tmp_path):
    """The first fix of Location.csv (the export's column set; blanks where the phone had no value) or of the
    push's ``location`` readings goes to meta['location']; a fix without a position is ignored, never refused."""
    folder = _copy_export(tmp_path)
    (folder / "Location.csv").write_text(
        "time,seconds_elapsed,bearingAccuracy,speedAccuracy,verticalAccuracy,horizontalAccuracy,speed,bearing,"
        "altitude,longitude,latitude\n"
        "1717000000200000000,0.2,,,3.0,4.5,0.1,,301.5,11.1110,49.4611\n"
        "1717000000100000000,0.1,,,3.0,,0.1,,301.5,11.1109,49.4610\n")
    loc = sensor_logger.read(folder).meta["location"]
    assert loc == {"lat_deg": 49.4610, "lon_deg": 11.1109, "t_ns": 1717000000100000000,
                   "horizontal_accuracy_m": None, "unix_time_s": 1717000000.1, "fixes": 2}
    msg = _ios_message()
    t = msg["payload"][0]["time"]
    msg["payload"] += [{"name": "location", "time": t, "values": {"latitude": 91.0, "longitude": 0.0}},
                       {"name": "location", "time": t, "values": {"latitude": 51.5, "longitude": -0.12,
                                                                  "horizontalAccuracy": "7"}}]
    rec = sensor_logger.parse_push_message(msg)
    assert rec.meta["location"] == {"lat_deg": 51.5, "lon_deg": -0.12, "t_ns": int(t), "horizontal_accuracy_m": 7.0,
                                    "unix_time_s": int(t) / 1e9, "fixes": 1}
    assert rec.meta["ignored_readings"] == {"location": 1}


@pytest.mark.parametrize(("content", "why"), [
    ("", "empty file (no header, no fixes)"),
    ("time,seconds_elapsed,horizontalAccuracy,longitude,latitude\n", "header only, no fixes"),
    ("time,seconds_elapsed,horizontalAccuracy,longitude,latitude\n1717000000100000000,0.1,3.0,11.1,91.0\n",
     "none of its 1 rows is a position fix")])
@pytest.mark.parametrize("gz", [False, True])
def test_location_csv_without_a_fix_is_said_in_a_warning(tmp_path, content, why, gz):
    """A Location.csv (or .gz, named as the export's member) without a fix (the app leaves it empty when the phone
    had none, e.g. indoors; a latitude beyond 90 deg) left the recording without geo-reference and without a word;
    the sensor streams are read as before."""
    folder = _copy_export(tmp_path)
    whole = sensor_logger.read(folder)
    (folder / "Location.csv").unlink()
    loc = folder / ("Location.csv.gz" if gz else "Location.csv")
    loc.write_bytes(gzip.compress(content.encode()) if gz else content.encode())
    rec = sensor_logger.read(folder)
    assert "location" not in rec.meta and rec.streams.keys() == whole.streams.keys()
    assert f"Location.csv: {why}: the recording is not geo-referenced" in rec.warnings, rec.warnings


def test_header_only_sensor_csv_is_skipped_with_a_warning_naming_it(tmp_path):
    # A header and no rows (an export whose accelerometer recorded nothing) was dropped without a word.
    folder = _copy_export(tmp_path)
    acc = folder / "Accelerometer.csv"
    acc.write_text(acc.read_text().splitlines()[0] + "\n")
    rec = sensor_logger.read(folder)
    assert not rec.has("lin_acc") and rec.has("gyro")
    assert any("Accelerometer.csv: header only, no samples" in w for w in rec.warnings), rec.warnings



@pytest.mark.parametrize("pack", ["folder", "zip"])
def test_an_export_with_a_member_gzip_cut_short_names_that_member(tmp_path, pack):
    """An export whose Accelerometer.csv.gz was cut short (a copy or download stopped) was 'not a supported log
    format': the sniffer read the whole member and the damage made it look like no export. The sniffer reads the
    member's header only. The reader called alone refuses the member, naming it; read_recording reads what
    decompresses (it refused the whole export), with a warning naming the member."""
    from pdr.io import read_recording

    rec = tmp_path / "rec"
    shutil.copytree(FIXTURES / "android_face_up", rec)
    acc = rec / "Accelerometer.csv"
    packed = gzip.compress(acc.read_bytes())
    acc.unlink()
    (rec / "Accelerometer.csv.gz").write_bytes(packed[:len(packed) // 2])
    log = rec
    if pack == "zip":
        log = tmp_path / "rec.zip"
        with zipfile.ZipFile(log, "w") as z:
            for f in sorted(rec.iterdir()):
                z.write(f, f"rec/{f.name}")
    assert detect_or_skip(log) == "sensor_logger"
    with pytest.raises(InputError, match=r"corrupt gzip data") as err:
        sensor_logger.read(log)
    assert "Accelerometer.csv" in str(err.value.source)
    whole = sensor_logger.read(FIXTURES / "android_face_up")
    cut = read_recording(log)
    assert cut.warnings[0].startswith("Accelerometer.csv.gz: cut short (the gzip stream ends before its end marker)")
    assert 0 < len(cut.stream("lin_acc")) < len(whole.stream("lin_acc"))
    np.testing.assert_array_equal(cut.values("gyro"), whole.values("gyro"))
    n = len(cut.stream("lin_acc"))
    np.testing.assert_array_equal(cut.values("lin_acc"), whole.values("lin_acc")[:n])


@pytest.mark.parametrize("name", ["Accelerometer.csv", "Gyroscope.csv.gz"])
def test_one_reading_of_an_export_alone_says_to_give_the_export(tmp_path, name):
    """One CSV of an export (what a user picks out of the folder) was 'not a supported log format ...; pass --format
    to force one', and no --format reads it; the error now says the export is read whole, from its folder or zip."""
    from pdr.errors import UnknownFormatError
    from pdr.io import read_recording

    raw = (FIXTURES / "android_face_up" / name.removesuffix(".gz")).read_bytes()
    one = tmp_path / name
    one.write_bytes(gzip.compress(raw) if name.endswith(".gz") else raw)
    with pytest.raises(UnknownFormatError, match=rf"one reading \({name.removesuffix('.gz')}\) of a Sensor Logger "
                                                 r"export, which is read as a whole: give the export's folder or zip"):
        read_recording(one)


def test_a_reading_that_is_a_named_pipe_is_said_not_skipped_silently(tmp_path):
    """An export folder whose Magnetometer.csv is a named pipe (or a link that loops) read without it, unsaid: it is
    still not read (never opened) and now a warning of the recording (pdr.io.notices, through Bundle.members)."""
    import os

    from pdr.io import read_recording

    rec = tmp_path / "export"
    shutil.copytree(FIXTURES / "android_face_up", rec)
    whole = read_recording(rec)
    (rec / "Magnetometer.csv").unlink()
    os.mkfifo(rec / "Magnetometer.csv")
    (rec / "Barometer.csv").unlink()
    (rec / "Barometer.csv").symlink_to("Barometer.csv")
    got = read_recording(rec)
    assert set(got.streams) == set(whole.streams) - {"mag", "baro"}
    assert got.warnings[:2] == ("Barometer.csv: not read: a symbolic link that leads nowhere (a loop, or its target "
                                "is missing)", "Magnetometer.csv: not read: a named pipe (FIFO), not a file")
