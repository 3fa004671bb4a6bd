"""Tyrex attitude-benchmark reader: synthetic recordings written here, and the real shared folders."""

from __future__ import annotations

import gzip
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from pdr import quaternion as quat
from pdr.errors import InputError, UnknownFormatError
from pdr.frames import GRAVITY_MPS2, wrap_angle
from pdr.io import detect_format, tyrex
from tests.pdr.io.dataset_samples import detect_or_skip, foreign_to, sample_path, samples_of

NAME = "Alice_Nexus5_NoDist_FrontPocket"
T_START = 3.0          # phone seconds since boot of the first sample
DURATION = 30.0
ALIGN_TRUE = -2.5      # mocap time = phone time + ALIGN_TRUE
WALK_YAW = math.radians(30.0)   # ENU yaw of the synthetic walk
SPEED = 1.2


def yaw_angle(t):
    """Rotation angle (rad) about the device z axis at phone time t: a rate that varies, so the lag shows."""
    t = np.asarray(t, dtype=np.float64)
    return (-2.0 / (2 * np.pi * 0.7)) * np.cos(2 * np.pi * 0.7 * t) - (1.5 / (2 * np.pi * 1.3)) * np.cos(
        2 * np.pi * 1.3 * t)


def yaw_rate(t):
    return 2.0 * np.sin(2 * np.pi * 0.7 * t) + 1.5 * np.sin(2 * np.pi * 1.3 * t)


def walker_pos(t):
    """(N, 3) phone position (m): a straight walk at WALK_YAW with sway at the stride and step frequencies."""
    s = SPEED * (t - T_START)
    fwd = np.array([math.cos(WALK_YAW), math.sin(WALK_YAW)])
    left = np.array([-fwd[1], fwd[0]])
    xy = s[:, None] * fwd + 0.05 * np.sin(2 * np.pi * 1.0 * t)[:, None] * left \
        + 0.03 * np.sin(2 * np.pi * 2.0 * t)[:, None] * fwd
    return np.column_stack([xy, 0.8 + 0.02 * np.sin(2 * np.pi * 2.0 * t)])


def _lines(rows) -> str:
    return "".join(" ".join(repr(float(v)) for v in r) + "\n" for r in rows)


def write_recording(root: Path, name: str = NAME, *, align_file: float = ALIGN_TRUE + 0.02, mocap: bool = True,
                    gz: bool = True, hidden: tuple[int, int] | None = None) -> Path:
    """A recording folder ``root/android/name`` (and ``root/qualisys/name.mat``) of a phone turning about its z
    axis while carried along a straight walk; ``timeAlignment.txt`` holds ``align_file``."""
    folder = root / "android" / name
    folder.mkdir(parents=True)
    t = T_START + np.arange(0, DURATION, 1 / 200)
    tm = T_START + np.arange(0, DURATION, 1 / 50)
    q = np.column_stack([np.cos(yaw_angle(t) / 2), 0 * t, 0 * t, np.sin(yaw_angle(t) / 2)])
    gyro = np.column_stack([0 * t + 0.001, 0 * t, yaw_rate(t)])
    mag_b = quat.rotate(quat.conjugate(q[::4][:tm.size]), np.broadcast_to([0.0, 22.0, -38.0], (tm.size, 3)))
    gyro_bias, mag_bias = np.tile([0.01, 0.0, 0.02], (t.size, 1)), np.tile([60.0, -76.0, 412.0], (tm.size, 1))
    files = {
        "accelerometer.txt": _lines(np.column_stack([t, 0 * t, 0 * t, 0 * t + GRAVITY_MPS2])),
        "gyroscope-calibrated.txt": _lines(np.column_stack([t, gyro])),
        "gyroscope.txt": _lines(np.column_stack([t, gyro + gyro_bias, gyro_bias])),
        "magnetometer-calibrated.txt": _lines(np.column_stack([tm, mag_b])),
        "magnetometer.txt": _lines(np.column_stack([tm, mag_b + mag_bias, mag_bias])),
        "rotation-vector.txt": _lines(np.column_stack([t, q[:, 1:], q[:, 0], 0 * t + 0.1745])),
    }
    for fname, text in files.items():
        if gz:
            (folder / (fname + ".gz")).write_bytes(gzip.compress(text.encode()))
        else:
            (folder / fname).write_text(text)
    (folder / "record.properties").write_text("[Device]\nManufacturer = LGE\nModel = Nexus 5\nOSVersion = 23\n"
                                              "ID = abc123\n\n[Time]\nStartTime = 1464964787\n")
    (folder / "timeAlignment.txt").write_text(f"  {align_file:.7e}\n")
    if mocap:
        k = np.arange(int((T_START + DURATION + ALIGN_TRUE) * 60) - 1)
        tp = k / 60.0 - ALIGN_TRUE                      # phone time of each frame
        pos = walker_pos(tp) * 1000.0
        a = yaw_angle(tp)
        rot = np.zeros((k.size, 3, 3))
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = (
            np.cos(a), -np.sin(a), np.sin(a), np.cos(a), 1.0)
        rot9 = rot.transpose(0, 2, 1).reshape(-1, 9).T   # column-major per frame
        if hidden is not None:
            pos[hidden[0]:hidden[1]] = np.nan
            rot9[:, hidden[0]:hidden[1]] = np.nan
        (root / "qualisys").mkdir(exist_ok=True)
        savemat(root / "qualisys" / f"{name}.mat", {name: {
            "FrameRate": 60.0, "Frames": float(k.size), "StartFrame": 1.0,
            "RigidBodies": {"Bodies": 1.0, "Name": "Nexus5-Handler", "Positions": pos.T, "Rotations": rot9}}})
    return folder


# ---------------------------------------------------------------------------------------------------------
# synthetic recordings


def test_synthetic_recording_streams_clock_and_meta(tmp_path):
    folder = write_recording(tmp_path)
    assert tyrex.sniff(folder)
    rec = tyrex.read(folder)
    assert set(rec.streams) == {"acc", "gyro", "gyro_uncal", "mag", "mag_uncal", "orientation"}
    assert rec.stream("acc").median_rate_hz() == pytest.approx(200.0, rel=1e-6)
    assert rec.stream("mag").median_rate_hz() == pytest.approx(50.0, rel=1e-6)
    # t_s on the phone's own clock: t0_ns / 1e9 + t_s is the files' first column.
    assert rec.origin_ns / 1e9 + rec.t_s("acc")[0] == pytest.approx(T_START, abs=1e-9)
    assert rec.origin_ns / 1e9 + rec.t_s("acc")[-1] == pytest.approx(T_START + DURATION - 1 / 200, abs=1e-6)
    # The rotation vector with its logged w is the attitude q_nb.
    t = rec.origin_ns / 1e9 + rec.t_s("orientation")
    want = np.column_stack([np.cos(yaw_angle(t) / 2), 0 * t, 0 * t, np.sin(yaw_angle(t) / 2)])
    assert np.max(quat.angle_between(rec.values("orientation"), want)) < 1e-6
    np.testing.assert_allclose(rec.values("gyro_uncal") - rec.values("gyro"), np.tile([0.01, 0, 0.02], (len(t), 1)),
                               atol=1e-12)
    assert rec.meta["gyro_os_bias"] == [[T_START, 0.01, 0.0, 0.02]]
    assert rec.meta["mag_os_bias"][0][1:] == [60.0, -76.0, 412.0]
    assert rec.device.model == "Nexus 5" and rec.device.device_id == "abc123" and rec.device.platform == "android"
    # The carriage is a label for evaluations, never handed to the pipeline as the device's placement.
    assert rec.device.placement is None
    assert rec.meta["carriage"] == "FrontPocket" and rec.meta["placement_label"] == "trouser_pocket_front"
    assert rec.meta["walker"] == "Alice" and rec.meta["disturbed"] is False


def test_time_alignment_is_applied_and_refined(tmp_path):
    rec = tyrex.read(write_recording(tmp_path, align_file=ALIGN_TRUE + 0.02))
    assert rec.meta["time_alignment_file_s"] == pytest.approx(ALIGN_TRUE + 0.02)
    assert rec.meta["time_alignment_s"] == pytest.approx(ALIGN_TRUE, abs=0.002)
    tt = rec.origin_ns / 1e9 + rec.truth.extra["trajectory_t_s"]
    # Frame k is at phone time k / 60 - alignment.
    assert tt[0] == pytest.approx(-rec.meta["time_alignment_s"], abs=1e-9)
    # The mocap attitude at the frame times is the phone's true attitude there.
    q = rec.truth.extra["q_nb"]
    want = np.column_stack([np.cos(yaw_angle(tt) / 2), 0 * tt, 0 * tt, np.sin(yaw_angle(tt) / 2)])
    assert np.degrees(np.max(quat.angle_between(q, want))) < 0.5
    # The magnetic field written along the mocap Y axis comes out at azimuth 0 through the mocap attitude.
    assert rec.meta["field_azimuth_mocap_deg"] == pytest.approx(0.0, abs=0.5)
    pos = rec.truth.positions
    assert pos is not None and pos.kind == "dense" and pos.frame == "enu"
    np.testing.assert_allclose(pos.pos_m, walker_pos(rec.origin_ns / 1e9 + pos.t_s), atol=2e-3)


def test_time_alignment_as_in_the_file_without_gyroscope(tmp_path):
    folder = write_recording(tmp_path, align_file=ALIGN_TRUE + 0.02, gz=False)
    for name in ("gyroscope-calibrated.txt", "gyroscope.txt"):
        (folder / name).unlink()
    rec = tyrex.read(folder)
    assert rec.meta["time_alignment_s"] == pytest.approx(ALIGN_TRUE + 0.02)
    assert any("not refined" in w for w in rec.warnings)


def test_walking_direction_truth_recovers_the_walk(tmp_path):
    rec = tyrex.read(write_recording(tmp_path, hidden=(300, 315)))   # 0.25 s of hidden frames: bridged
    yaw = rec.truth.extra["walking_heading_rad"]
    ok = np.isfinite(yaw)
    assert ok.mean() > 0.95
    # The sway at the stride and step frequencies averages out over one stride.
    assert np.degrees(np.max(np.abs(wrap_angle(yaw[ok] - WALK_YAW)))) < 1.0
    assert np.any(np.isnan(rec.truth.extra["q_nb"][300:315]))
    assert rec.meta["mocap_hidden_frames"] == 15


def test_walking_path_leaves_long_gaps_and_ends_undefined():
    t = np.arange(600) / 60.0
    pos = np.column_stack([t, 0 * t, 0 * t])
    pos[200:260] = np.nan          # 1 s hidden: longer than MAX_GAP_S
    walk = tyrex.walking_path(t, pos)
    half = round(0.5 * tyrex.WALK_SMOOTHING_S * 60)
    assert np.all(np.isnan(walk[:half])) and np.all(np.isnan(walk[-half:]))
    assert np.all(np.isnan(walk[200 - half:260 + half]))
    good = np.isfinite(walk[:, 0])
    np.testing.assert_allclose(walk[good, 0], t[good], atol=1e-9)   # a straight line is its own average


def test_walking_heading_of_a_circle():
    # Walking a circle of radius 3 m at 1.2 m/s counter-clockwise: heading = angle + 90 deg.
    t = np.arange(0, 60, 1 / 60)
    ang = 1.2 / 3.0 * t
    pos = np.column_stack([3 * np.cos(ang), 3 * np.sin(ang)])
    walk = tyrex.walking_path(t, pos)
    yaw = tyrex.walking_heading(t, walk)
    ok = np.isfinite(yaw)
    assert np.degrees(np.max(np.abs(wrap_angle(yaw[ok] - (ang[ok] + np.pi / 2))))) < 0.5
    # Standing still: no direction.
    assert np.all(np.isnan(tyrex.walking_heading(t, np.zeros((t.size, 2)))))


def test_rotation_glitch_is_flagged():
    t = np.arange(300) / 60.0
    a = 0.5 * t
    q = np.column_stack([np.cos(a / 2), 0 * t, 0 * t, np.sin(a / 2)])
    q[100:110] = quat.multiply(q[100:110], np.array([0.0, 1.0, 0.0, 0.0]))   # fitted upside down for 10 frames
    bad = tyrex.rotation_glitches(t, q)
    assert bad[100:110].all()
    assert bad.sum() <= 12 and not bad[:99].any() and not bad[111:].any()


@pytest.mark.parametrize("top_folder", [True, False])
def test_a_zip_of_the_folder_is_read_without_truth(tmp_path, top_folder):
    folder = write_recording(tmp_path)
    archive = tmp_path / "upload.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for f in folder.iterdir():
            z.write(f, f"{NAME}/{f.name}" if top_folder else f.name)
    assert tyrex.sniff(archive) and detect_format(archive) == "tyrex"
    rec = tyrex.read(archive)
    direct = tyrex.read(folder)
    assert dict(rec.streams) == dict(direct.streams)
    assert rec.truth.is_empty() and direct.truth.positions is not None
    assert rec.meta.get("carriage") == ("FrontPocket" if top_folder else None)
    lines = gzip.decompress((folder / "accelerometer.txt.gz").read_bytes()).decode().splitlines()
    lines[9] = "x 1 2 3"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("accelerometer.txt", "\n".join(lines))
        z.writestr("record.properties", "[Device]\nModel = Nexus 5\n")
    with pytest.raises(InputError, match=r"upload.zip:accelerometer.txt, line 10, field 't'"):
        tyrex.read(archive)


def test_no_mocap_gives_a_recording_without_truth(tmp_path):
    rec = tyrex.read(write_recording(tmp_path, mocap=False))
    assert rec.truth.is_empty()
    assert any("no motion-capture file" in w for w in rec.warnings)


@pytest.mark.parametrize(("file", "line", "text", "match"), [
    ("accelerometer.txt", 3, "3.01 0.0 abc 9.8", r"accelerometer.txt, line 3, field 'y': 'abc' is not a number"),
    ("accelerometer.txt", 5, "3.02 0.0 0.0", r"accelerometer.txt, line 5: expected 4 fields"),
    ("rotation-vector.txt", 2, "3.005 0 0 nan 1 0.17", r"rotation-vector.txt, line 2, field 'z': value nan"),
])
def test_bad_lines_name_file_line_and_field(tmp_path, file, line, text, match):
    folder = write_recording(tmp_path, gz=False)
    lines = (folder / file).read_text().splitlines()
    lines[line - 1] = text
    (folder / file).write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=match):
        tyrex.read(folder)


def test_times_a_tenth_of_a_nanosecond_apart_are_a_repeat_dropped_with_a_warning(tmp_path):
    """Two rows 0.1 ns apart are in order in seconds but one nanosecond once rounded: the stream refused the whole
    recording ("timestamp of sample 2 (...) duplicates sample 1 (...)"); the later row is now a repeat, dropped with a
    warning naming file and line, as exact repeats are (pdr.io.time_order on the int64 nanoseconds)."""
    from pdr.io import read_recording

    folder = write_recording(tmp_path, gz=False)
    whole = read_recording(folder)
    lines = (folder / "accelerometer.txt").read_text().splitlines()
    lines[2] = " ".join([repr(float(lines[1].split()[0]) + 1e-10), *lines[2].split()[1:]])
    (folder / "accelerometer.txt").write_text("\n".join(lines) + "\n")
    rec = read_recording(folder)
    assert len(rec.stream("acc")) == len(whole.stream("acc")) - 1
    np.testing.assert_array_equal(rec.stream("acc").t_ns, np.delete(whole.stream("acc").t_ns, 2))
    assert any(w.startswith("accelerometer.txt: dropped 1 of ") and "repeats (1)" in w and "line 3" in w
               for w in rec.warnings), rec.warnings


def test_members_that_are_no_files_are_said_not_skipped_silently(tmp_path):
    """A member that is a folder, a named pipe or a link that loops was skipped as if absent, without a word; each is
    now a warning of the recording, and a required one (the accelerometer) is named in the error."""
    import os

    from pdr.io import read_recording

    folder = write_recording(tmp_path, mocap=False, gz=False)
    whole = read_recording(folder)
    (folder / "gyroscope.txt").unlink()
    (folder / "gyroscope.txt").mkdir()
    (folder / "magnetometer.txt").unlink()
    os.mkfifo(folder / "magnetometer.txt")
    (folder / "rotation-vector.txt").unlink()
    (folder / "rotation-vector.txt").symlink_to("rotation-vector.txt")
    rec = read_recording(folder)
    assert set(rec.streams) == set(whole.streams) - {"gyro_uncal", "mag_uncal", "orientation"}
    np.testing.assert_array_equal(rec.values("acc"), whole.values("acc"))
    assert rec.warnings[:3] == ("gyroscope.txt: not read: a folder, not a file",
                                "magnetometer.txt: not read: a named pipe (FIFO), not a file",
                                "rotation-vector.txt: not read: a symbolic link that leads nowhere (a loop, or its "
                                "target is missing)")
    (folder / "accelerometer.txt").unlink()
    os.mkfifo(folder / "accelerometer.txt")
    for forced in (None, "tyrex"):
        with pytest.raises(InputError, match=r"accelerometer.* \(accelerometer\.txt: not read: a named pipe \(FIFO\)"):
            read_recording(folder, format=forced)


@pytest.mark.parametrize(("content", "match"), [("", "expected one number"), ("abc", "expected one number"),
                                                ("1 2", "expected one number"),
                                                ("1e300", r"time alignment 1e\+300 s is not a plausible offset"),
                                                ("-500", "no motion-capture frame falls within the phone's")])
def test_bad_time_alignment(tmp_path, content, match):
    folder = write_recording(tmp_path, gz=False)
    (folder / "timeAlignment.txt").write_text(content)
    with pytest.raises(InputError, match=rf"timeAlignment.txt, line 1: {match}"):
        tyrex.read(folder)


def test_bad_properties_and_missing_files(tmp_path):
    folder = write_recording(tmp_path, gz=False)
    (folder / "record.properties").write_text("[Device]\nModel Nexus 5\n")
    with pytest.raises(InputError, match=r"record.properties, line 2: expected"):
        tyrex.read(folder)
    (folder / "record.properties").write_text("[Device]\nModel = Nexus 5\n")
    (folder / "timeAlignment.txt").unlink()
    with pytest.raises(InputError, match="no timeAlignment.txt"):
        tyrex.read(folder)
    (folder / "accelerometer.txt").unlink()
    assert not tyrex.sniff(folder)
    with pytest.raises(InputError, match=r"no accelerometer.txt\[.gz\]"):
        tyrex.read(folder)
    with pytest.raises(InputError, match="is a folder"):
        tyrex.read(folder / "record.properties")


def test_a_logger_folder_without_its_accelerometer_says_what_is_missing(tmp_path):
    # Detection said only "not a supported log format": sniff needs accelerometer.txt, read() alone named it.
    folder = write_recording(tmp_path, mocap=False)
    (folder / "accelerometer.txt.gz").unlink()
    with pytest.raises(UnknownFormatError, match=r"Tyrex .* without accelerometer\.txt\[\.gz\].*\(it has gyroscope"):
        detect_format(folder)
    (folder / "accelerometer.txt").write_text("time,x,y,z\n1,0,0,9.8\n")
    with pytest.raises(UnknownFormatError, match=r"accelerometer\.txt does not start with a row of numbers"):
        detect_format(folder)
    (folder / "record.properties").unlink()     # nobody's near miss: the generic message
    with pytest.raises(UnknownFormatError, match="not a supported log format"):
        detect_format(folder)


def test_bad_mocap_file_is_named(tmp_path):
    folder = write_recording(tmp_path)
    mat = tmp_path / "qualisys" / f"{NAME}.mat"
    savemat(mat, {"x": np.zeros((3, 3))})
    with pytest.raises(InputError, match=r"qualisys/.*\.mat: expected one Qualisys export struct"):
        tyrex.read(folder)
    mat.write_bytes(b"MATLAB 5.0 MAT-file garbage")
    with pytest.raises(InputError, match=r"\.mat: not a readable MATLAB"):
        tyrex.read(folder)


def test_sniff_rejects_foreign_folders_and_files(tmp_path):
    (tmp_path / "empty").mkdir()
    assert not tyrex.sniff(tmp_path / "empty")
    other = tmp_path / "other"
    other.mkdir()
    (other / "record.properties").write_text("[Device]\n")
    (other / "accelerometer.txt").write_text("time,x,y,z\n")
    assert not tyrex.sniff(other)
    (tmp_path / "file.txt").write_text("1 2 3 4\n")
    assert not tyrex.sniff(tmp_path / "file.txt")


# ---------------------------------------------------------------------------------------------------------
# the shared recordings


@pytest.mark.data
def test_real_recording_truth_agrees_with_the_phone():
    folder = sample_path("tyrex:folder")
    assert detect_or_skip(folder) == "tyrex"
    rec = tyrex.read(folder)
    # SOURCE.md: accelerometer and gyroscope about 199 Hz, magnetometer 50 Hz, about 2 minutes.
    assert rec.stream("acc").median_rate_hz() == pytest.approx(199, abs=2)
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(199, abs=2)
    assert rec.stream("mag").median_rate_hz() == pytest.approx(50, abs=1)
    assert 110 <= rec.duration_s <= 140
    assert rec.meta["mocap_frames"] == 7200 and rec.meta["carriage"] == "Texting"
    # The refinement moves timeAlignment.txt by at most two frames.
    assert abs(rec.meta["time_alignment_s"] - rec.meta["time_alignment_file_s"]) <= 2 / 60
    # Specific force rotated by the mocap attitude points up with 1 g: attitude convention and clock agree.
    tt = rec.truth.extra["trajectory_t_s"]
    q = rec.truth.extra["q_nb"]
    ok = np.all(np.isfinite(q), axis=1) & (tt > rec.t_s("acc")[0]) & (tt < rec.t_s("acc")[-1])
    acc = np.column_stack([np.interp(tt[ok], rec.t_s("acc"), rec.values("acc")[:, k]) for k in range(3)])
    f_n = quat.rotate(q[ok], acc)
    assert np.mean(f_n, axis=0) == pytest.approx([0, 0, GRAVITY_MPS2], abs=0.3)
    # SOURCE.md: the mocap Y axis is within about 2 degrees of magnetic north (clean field).
    assert abs(rec.meta["field_azimuth_mocap_deg"]) < 3.0
    # The walking path is defined almost everywhere while the walker loops the room.
    assert np.mean(np.isfinite(rec.truth.extra["walking_heading_rad"])) > 0.8


@pytest.mark.data
@pytest.mark.parametrize("key", foreign_to("tyrex"))
def test_sniff_rejects_other_datasets(key):
    assert tyrex.sniff(sample_path(key)) is False


def test_samples_table_lists_tyrex():
    assert samples_of("tyrex") == ["tyrex:folder"]
