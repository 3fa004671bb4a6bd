"""``pdr inspect`` and ``pdr convert`` on synthetic native logs: reported figures, round trips, errors."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest

from pdr.cli import main
from pdr.cli.convert import excerpt
from pdr.io import native
from pdr.recording import DeviceInfo, GroundTruth, Labels, PositionTruth, Recording, SensorStream

T0_NS = 1_700_000_000_000_000_000


def _recording() -> Recording:
    rng = np.random.default_rng(0)
    t_acc = np.arange(0, 20, 0.01)                       # 100 Hz, 20 s
    t_gyro = np.arange(0, 20, 0.005)
    t_gyro = t_gyro[(t_gyro < 8.0) | (t_gyro >= 9.5)]    # 200 Hz with one 1.5 s gap
    acc = np.tile([0.0, 0.0, 9.81], (t_acc.size, 1)) + 0.01 * rng.standard_normal((t_acc.size, 3))
    gyro = 0.01 * rng.standard_normal((t_gyro.size, 3))
    streams = {
        "acc": SensorStream("acc", T0_NS + np.round(t_acc * 1e9).astype(np.int64), acc),
        "gyro": SensorStream("gyro", T0_NS + np.round(t_gyro * 1e9).astype(np.int64), gyro),
    }
    steps = np.arange(1.0, 19.0, 0.5)
    truth = GroundTruth(
        positions=PositionTruth(np.array([0.0, 10.0, 19.0]), np.array([[0, 0, 0], [7, 0, 0], [13, 0, 0.0]]),
                                kind="waypoint"),
        step_times_s=steps, step_lengths_m=np.full(steps.size, 0.7),
        modes=Labels(np.array([0.0, 12.0]), np.array([12.0, 20.0]), ("walk", "stand")),
        extra={"zero_velocity_t_s": t_acc, "zero_velocity": (t_acc > 12).astype(np.int8),
               "calibration": np.eye(3), "step_times_left_s": steps[::2]},
    )
    return Recording(streams, device=DeviceInfo("android", "Pixel 7", "phone", "hand"), t0_ns=T0_NS,
                     truth=truth, source="synthetic", format="native")


@pytest.fixture
def native_log(tmp_path):
    return native.write(_recording(), tmp_path / "rec")


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_inspect_json_reports_rates_durations_gaps_and_truth(capsys, native_log):
    code, out, err = _run(capsys, "inspect", str(native_log), "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["format"] == "native"
    assert s["device"] == {"platform": "android", "model": "Pixel 7", "role": "phone", "placement": "hand",
                           "device_id": ""}
    assert s["duration_s"] == pytest.approx(19.995)
    st = {x["kind"]: x for x in s["streams"]}
    assert st["acc"]["samples"] == 2000 and st["acc"]["rate_hz"] == pytest.approx(100.0)
    assert st["acc"]["duration_s"] == pytest.approx(19.99) and st["acc"]["gaps"] == 0
    assert st["acc"]["longest_gap_s"] is None and st["acc"]["unit"] == "m/s^2"
    assert st["acc"]["median_norm"] == pytest.approx(9.81, abs=0.01)
    assert st["gyro"]["rate_hz"] == pytest.approx(200.0)
    assert st["gyro"]["gaps"] == 1 and st["gyro"]["longest_gap_s"] == pytest.approx(1.505)
    assert st["gyro"]["mean_rate_hz"] < 200 * 0.95  # the gap shows in the mean rate
    assert st["gyro"]["first_s"] == 0.0 and st["gyro"]["last_s"] == pytest.approx(19.995)
    truth = s["truth"]
    assert truth["positions"] == {"points": 3, "kind": "waypoint", "frame": "enu", "floors": []}
    assert truth["step_times_s"] == {"steps": 36} and truth["step_count"] == 36
    assert truth["modes"] == {"intervals": 2, "labels": ["stand", "walk"]}
    assert truth["extra"]["calibration"] == {"shape": [3, 3], "dtype": "float64"}
    assert s["warnings"] == []


def test_inspect_text_output(capsys, native_log):
    code, out, _ = _run(capsys, "inspect", str(native_log))
    assert code == 0
    assert "format:    native" in out
    assert "android Pixel 7, role phone, placement hand" in out
    gyro_line = next(line for line in out.splitlines() if line.strip().startswith("gyro"))
    assert "200.00" in gyro_line and "rad/s" in gyro_line and gyro_line.split()[-1] == "1.505"
    assert "step_times_s: steps 36" in out
    assert "warnings:  none" in out


def test_inspect_lists_formats(capsys):
    code, out, _ = _run(capsys, "inspect", "--formats")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert "native" in names and "ipin" in names
    code, out, _ = _run(capsys, "inspect", "--formats", "--json")
    assert code == 0 and "native" in json.loads(out)


@pytest.mark.parametrize("content", [b"\x00\x01\x02\xff" * 200, b"just some text\nthat is no log\n", b""])
def test_inspect_unrecognised_input_is_a_clean_error(capsys, tmp_path, content):
    bad = tmp_path / "mystery.dat"
    bad.write_bytes(content)
    code, out, err = _run(capsys, "inspect", str(bad))
    assert code == 2 and out == ""
    assert err.startswith(f"error: {bad}")
    assert "Traceback" not in err


def test_inspect_missing_file_and_unknown_forced_format(capsys, tmp_path, native_log):
    missing = tmp_path / "nope.txt"
    code, _, err = _run(capsys, "inspect", str(missing))
    assert code == 2 and err.startswith(f"error: {missing}") and "no such file" in err
    code, _, err = _run(capsys, "inspect", str(native_log), "--format", "klingon")
    assert code == 2 and err.startswith(f"error: {native_log}") and "unknown format 'klingon'" in err


def test_inspect_forced_wrong_format_is_a_clean_error(capsys, tmp_path):
    garbage = tmp_path / "garbage.bin"
    garbage.write_bytes(bytes(range(256)) * 20)
    code, _, err = _run(capsys, "inspect", str(garbage), "--format", "native")
    assert code == 2 and err.startswith(f"error: {garbage}") and "Traceback" not in err


@pytest.mark.parametrize("fmt", [None, "ipin", "xio"])
def test_inspect_named_pipe_is_a_clean_error(capsys, tmp_path, fmt):
    """A named pipe (or /dev/zero) given with --format was opened and read: it waited for a writer without end (and
    /dev/zero was read until a MemoryError traceback). A writer is opened here so that the old code ends too."""
    import os
    import threading

    fifo = tmp_path / "log.txt"
    os.mkfifo(fifo)

    def writer() -> None:      # unblocks a reader that opens the pipe; left waiting when none does
        with open(fifo, "wb"):
            pass

    threading.Thread(target=writer, daemon=True).start()
    code, _, err = _run(capsys, "inspect", str(fifo), *(("--format", fmt) if fmt else ()))
    os.close(os.open(fifo, os.O_RDONLY | os.O_NONBLOCK))        # releases the writer when nothing read the pipe
    assert code == 2 and err.startswith(f"error: {fifo}: not a regular file or folder (a device, pipe or socket)")


@pytest.mark.parametrize("target", ["log.txt", "missing.txt"])
def test_inspect_symbolic_link_to_nothing_says_so(capsys, tmp_path, target):
    """A symbolic link to itself (a loop) or to a missing file was "no such file or folder", of a name that is there."""
    link = tmp_path / "log.txt"
    link.symlink_to(tmp_path / target)
    code, _, err = _run(capsys, "inspect", str(link))
    assert code == 2 and err.startswith(f"error: {link}: a symbolic link that leads nowhere (a loop, or its target")


def test_inspect_without_log(capsys):
    code, _, err = _run(capsys, "inspect")
    assert code == 2 and err.startswith("error:")


# ----------------------------------------------------------------------------------------- convert

@pytest.mark.parametrize("target", ["out_folder", "out.zip", "out.json", "out.json.gz"])
def test_convert_round_trips(capsys, tmp_path, native_log, target):
    out = tmp_path / target
    code, stdout, err = _run(capsys, "convert", str(native_log), "--to", "native", str(out))
    assert code == 0, err
    assert stdout.startswith(f"wrote {out}")
    assert native.read(out) == native.read(native_log)


def test_convert_sets_the_device_role(capsys, tmp_path, native_log):
    """Issue 32 item 4: the role written is the one asked for (a PyShoe file does not say which foot)."""
    out = tmp_path / "left.json"
    code, _, err = _run(capsys, "convert", str(native_log), "--to", "native", str(out), "--role", "left_foot")
    assert code == 0, err
    back, source = native.read(out), native.read(native_log)
    assert back.device.role == "left_foot" and source.device.role == "phone"
    assert back.streams == source.streams and json.loads(out.read_text())["device"]["role"] == "left_foot"
    with pytest.raises(SystemExit, match="2"):
        main(["convert", str(native_log), "--to", "native", str(out), "--role", "toe"])
    assert "argument --role: invalid choice: 'toe'" in capsys.readouterr().err


def test_convert_excerpt_cuts_streams_and_truth(capsys, tmp_path, native_log):
    out = tmp_path / "cut"
    code, _, err = _run(capsys, "convert", str(native_log), "--to", "native", str(out),
                        "--start", "5", "--end", "15")
    assert code == 0, err
    rec = native.read(out)
    assert rec.origin_ns == T0_NS + 5_000_000_000
    assert rec.t_s("acc")[0] == pytest.approx(0.0) and rec.t_s("acc")[-1] == pytest.approx(9.99)
    assert len(rec.stream("acc")) == 1000
    assert rec.truth.step_times_s is not None
    np.testing.assert_allclose(rec.truth.step_times_s, np.arange(0.0, 10.0, 0.5))
    assert rec.truth.step_count == 20
    assert rec.truth.positions is not None and rec.truth.modes is not None
    np.testing.assert_allclose(rec.truth.positions.t_s, [5.0])
    np.testing.assert_allclose(rec.truth.modes.t_start_s, [0.0, 7.0])
    np.testing.assert_allclose(rec.truth.modes.t_end_s, [7.0, 10.0])
    assert rec.truth.extra["zero_velocity"].shape == (1000,)
    np.testing.assert_allclose(rec.truth.extra["zero_velocity_t_s"][[0, -1]], [0.0, 9.99])
    assert "calibration" not in rec.truth.extra
    np.testing.assert_allclose(rec.truth.extra["step_times_left_s"], np.arange(0.0, 10.0, 1.0))
    assert any("'calibration' is not time-indexed: dropped" in w for w in rec.warnings)
    assert rec.meta["excerpt"]["start_s"] == 5.0 and rec.meta["excerpt"]["end_s"] == 15.0


def test_excerpt_drops_a_bare_step_count_with_a_warning():
    rec = _recording()
    rec = Recording(rec.streams, t0_ns=rec.t0_ns, truth=GroundTruth(step_count=40))
    part = excerpt(rec, 2.0, 4.0)
    assert part.truth.step_count is None
    assert any("step_count" in w for w in part.warnings)


def test_convert_errors(capsys, tmp_path, native_log):
    code, _, err = _run(capsys, "convert", str(tmp_path / "missing"), "--to", "native", str(tmp_path / "o"))
    assert code == 2 and err.startswith(f"error: {tmp_path / 'missing'}")
    code, _, err = _run(capsys, "convert", str(native_log), "--to", "native", str(tmp_path / "o"),
                        "--start", "30", "--end", "40")
    assert code == 2 and "no samples between" in err
    code, _, err = _run(capsys, "convert", str(native_log), "--to", "native", str(tmp_path / "o"),
                        "--start", "5", "--end", "5")
    assert code == 2 and "empty window" in err
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    code, _, err = _run(capsys, "convert", str(native_log), "--to", "native", str(blocker))
    assert code == 2 and err.startswith(f"error: {blocker}")



@pytest.mark.parametrize("name", ["out.csv", "out.csv.gz", "walk.txt"])
def test_convert_to_a_file_name_of_another_format_is_refused_before_reading(capsys, tmp_path, name):
    """'pdr convert LOG --to native out.csv' made a folder named out.csv (exit 0): the native format is a folder,
    .zip, .json or .json.gz, so a name ending in another file extension is refused, naming it, before the log is
    read (the log here does not exist), and nothing is made. An existing folder of that name is still written into.
    """
    out = tmp_path / name
    code, stdout, err = _run(capsys, "convert", str(tmp_path / "no_such_log"), "--to", "native", str(out))
    assert code == 2 and stdout == ""
    assert err.strip() == (f"error: {out}, field 'OUT': the native format is a folder, .zip, .json or .json.gz, "
                           f"not a .{out.suffix[1:]} file: name a folder without an extension, or one of those files")
    assert not out.exists()
    out.mkdir()
    code, _, err = _run(capsys, "convert", str(tmp_path / "no_such_log"), "--to", "native", str(out))
    assert code == 2 and "no_such_log" in err

def test_inspect_shows_the_location_fix_and_the_earths_field_there(capsys, tmp_path):
    """A log with a location fix: ``pdr inspect`` prints it with the World Magnetic Model's field there (the dip the
    magnetometer gate checks); a fix without a date says the field is unknown; a log without a fix prints nothing."""
    from dataclasses import replace

    fix = {"lat_deg": 49.4614, "lon_deg": 11.1115, "unix_time_s": 1686732686.0, "alt_m": 365.0, "fixes": 3}
    with_fix = native.write(replace(_recording(), meta={"location": fix}), tmp_path / "fix")
    code, out, _ = _run(capsys, "inspect", str(with_fix))
    assert code == 0
    assert "location:  49.46140, 11.11150, 2023-06-14 08:51 UTC (first of 3 fixes)" in out
    assert "dip 65.5 deg, declination +4.0 deg, 49.0 uT" in out
    code, out, _ = _run(capsys, "inspect", str(with_fix), "--json")
    assert json.loads(out)["location"]["earth_field"]["inclination_deg"] == pytest.approx(65.47, abs=0.05)
    undated = native.write(replace(_recording(), meta={"location": {"lat_deg": 49.46, "lon_deg": 11.11}}),
                           tmp_path / "undated")
    _, out, _ = _run(capsys, "inspect", str(undated))
    assert "location:  49.46000, 11.11000" in out and "unknown (no date" in out
    _, out, _ = _run(capsys, "inspect", str(native.write(_recording(), tmp_path / "none")))
    assert "location:" not in out


def _bad_deflate(text: bytes, at: int) -> bytes:
    """A gzip of ``text`` whose deflate stream is good up to ``text[:at]`` and then holds a block of the reserved type
    3: gzip.decompress raises zlib.error ("invalid block type"), not the gzip layer's OSError."""
    import zlib

    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    good = c.compress(text[:at]) + c.flush(zlib.Z_FULL_FLUSH)          # ends on a byte boundary
    return b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xff" + good + b"\x07" + b"\x00" * 16


@pytest.mark.parametrize("command", ["inspect", "track", "convert"])
def test_a_gzip_log_with_a_bad_deflate_block_is_a_clean_error(capsys, tmp_path, command):
    """A ``.gz`` log whose compressed data is damaged past its first bytes (the sniffer reads its start, the reader
    then meets the damage) is an error naming the file, exit code 2; it was zlib.error's traceback."""
    from tests.conftest import REPO_ROOT

    text = gzip.decompress((REPO_ROOT / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz")
                           .read_bytes())
    bad = tmp_path / "trace.txt.gz"
    bad.write_bytes(_bad_deflate(text, len(text) * 2 // 3))
    tail = {"inspect": [], "track": ["--out", str(tmp_path / "t.csv")],
            "convert": ["--to", "native", str(tmp_path / "n")]}[command]
    code, out, err = _run(capsys, command, str(bad), *tail)
    assert code == 2 and out == ""
    assert err.startswith(f"error: {bad}: corrupt gzip data") and "Traceback" not in err


def test_a_zipped_log_with_a_bad_deflate_member_is_a_clean_error(tmp_path):
    """The same damage in a ``.gz`` member of a zip (Bundle.get) names the member."""
    import zipfile

    from pdr.errors import InputError
    from pdr.io.bundle import Bundle

    z = tmp_path / "log.zip"
    with zipfile.ZipFile(z, "w") as zf:
        zf.writestr("Accelerometer.csv.gz", _bad_deflate(b"t,x\n1,2\n" * 100, 400))
    with pytest.raises(InputError, match="corrupt gzip data") as err:
        Bundle(z).get("Accelerometer.csv")
    assert "log.zip:Accelerometer.csv" in str(err.value)


@pytest.mark.parametrize("damage", ["bad first block", "cut after the header"])
def test_a_gzip_damaged_at_its_start_says_corrupt_gzip_not_unsupported_format(capsys, tmp_path, damage):
    """A ``.gz`` whose first bytes no longer decompress gives the sniffers nothing to recognise; the error is the
    damaged gzip, not 'not a supported log format' (what it said before)."""
    bad = tmp_path / "trace.txt.gz"
    text = b"1574142012005\tTYPE_ACCELEROMETER\t0.1\t0.2\t9.8\t3\n" * 200
    bad.write_bytes(_bad_deflate(text, 0) if damage == "bad first block" else gzip.compress(text)[:14])
    code, out, err = _run(capsys, "inspect", str(bad))
    assert code == 2 and out == ""
    assert err.startswith(f"error: {bad}: corrupt gzip data"), err
    plain = tmp_path / "other.txt.gz"                   # an intact gzip of no log format is still that
    plain.write_bytes(gzip.compress(b"just some text\n"))
    code, _, err = _run(capsys, "inspect", str(plain))
    assert code == 2 and "not a supported log format" in err


@pytest.mark.parametrize("forced", [[], ["--format", "ms_indoor"]])
def test_a_plain_text_named_gz_says_it_is_not_gzip_data(capsys, tmp_path, forced):
    """A trace saved as text under a ``.gz`` name was 'not a supported log format (...); pass --format to force one'
    (and, forced, 'corrupt gzip data (Not a gzipped file ...)'); both now say it is not gzip data."""
    bad = tmp_path / "trace.txt.gz"
    bad.write_bytes(b"1574142012005\tTYPE_ACCELEROMETER\t0.1\t0.2\t9.8\t3\n" * 20)
    code, out, err = _run(capsys, "inspect", str(bad), *forced)
    assert code == 2 and out == ""
    assert err == f"error: {bad}: not gzip data, though named .gz: it starts with b'15741420', gzip with bytes 1f 8b\n"


@pytest.mark.parametrize("command", ["convert", "track"])
def test_an_output_path_that_cannot_be_written_is_a_one_line_error(capsys, tmp_path, native_log, command):
    """--out (or convert's OUT) inside a folder that is a file: 'error: PATH: reason', exit 2; it was the OSError's
    traceback (exit 1) for every command that writes (track, foot, classify, convert, allan)."""
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    out = blocker / "out.csv"
    argv = ["convert", str(native_log), "--to", "native", str(out)] if command == "convert" else \
        ["track", str(native_log), "--out", str(out)]
    code, stdout, err = _run(capsys, *argv)
    assert code == 2
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"error: {out}") or last.startswith(f"error: {blocker}"), err
    assert "Traceback" not in err


def test_a_folder_of_several_logs_says_so_instead_of_unsupported_format(capsys, tmp_path):
    """``pdr inspect pyshoe_vicon/`` (a dataset folder) said 'not a supported log format ...; pass --format to force
    one', which no --format fixes; it now names logs it holds and asks for one. A folder of no logs is unchanged."""
    from tests.conftest import REPO_ROOT

    ms = (REPO_ROOT / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz").read_bytes()
    trials = tmp_path / "trials"
    trials.mkdir()
    for name in ("a.txt.gz", "b.txt.gz"):
        (trials / name).write_bytes(ms)
    (trials / "notes.md").write_text("two walks\n")
    code, out, err = _run(capsys, "inspect", str(trials))
    assert code == 2 and out == ""
    assert err.strip() == (f"error: {trials}: not one log but a folder that holds logs (2 of its entries: a.txt.gz, "
                           "b.txt.gz); pass one of them")
    empty = tmp_path / "nothing"
    empty.mkdir()
    (empty / "notes.md").write_text("no walks\n")
    code, _, err = _run(capsys, "inspect", str(empty))
    assert code == 2 and "not a supported log format" in err


@pytest.mark.parametrize("command", ["track", "foot"])
def test_an_output_that_cannot_be_written_is_refused_before_the_log_is_read(capsys, tmp_path, native_log, command):
    """pdr track and pdr foot check their outputs first: an unwritable --plot is reported before any work (the log
    given here does not even exist), and the --out that could be written is not left behind as an empty file."""
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    out, plot = tmp_path / "runs" / "walk.csv", blocker / "walk.png"
    code, _, err = _run(capsys, command, str(tmp_path / "no_such_log.csv"), "--out", str(out), "--plot", str(plot))
    assert code == 2
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"error: {blocker}") and "no_such_log" not in err, err
    assert not out.exists() and blocker.read_text() == "x"
    # An existing --out is left as it was when another output fails.
    out.write_text("previous run\n")
    assert _run(capsys, command, str(native_log), "--out", str(out), "--plot", str(plot))[0] == 2
    assert out.read_text() == "previous run\n"


@pytest.mark.parametrize("command", ["track", "classify", "convert"])
def test_commands_say_what_the_reader_dropped(capsys, tmp_path, native_log, command):
    """A log cut off mid-line: its last line is dropped by the reader, and 'pdr track', 'pdr classify' and 'pdr
    convert' say so on stderr as 'pdr foot' does (they said nothing; only 'pdr inspect' listed it)."""
    acc = native_log / "acc.csv"
    acc.write_text(acc.read_text() + "1700000020000000000,0.1")       # no line break: the phone stopped here
    line = acc.read_text().count("\n") + 1
    out = tmp_path / "out"
    argv = {"track": ["track", str(native_log), "--out", str(out / "t.csv")],
            "classify": ["classify", str(native_log), "--out", str(out / "m.csv")],
            "convert": ["convert", str(native_log), "--to", "native", str(out / "c.zip")]}[command]
    code, _, err = _run(capsys, *argv)
    assert code == 0, err
    assert f"warning: acc.csv: dropped the cut-off last line {line} (2 of 4 fields): the log ends mid-line" in err


@pytest.mark.parametrize("command", ["inspect", "track", "classify", "convert"])
def test_an_empty_file_or_folder_is_said_to_be_empty(capsys, tmp_path, command):
    """An empty file (a recording that never started) or folder was 'not a supported log format (supported: ...);
    pass --format to force one', which no --format fixes; it is now named for what it is."""
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / ".hidden").write_text("")
    (tmp_path / "walk.csv").write_bytes(b"")
    for name, what in (("walk.csv", "an empty file (0 bytes): no log in it"),
                       ("empty", "an empty folder: no log in it")):
        log = str(tmp_path / name)
        argv = {"inspect": ["inspect", log], "track": ["track", log, "--out", str(tmp_path / "t.csv")],
                "classify": ["classify", log, "--out", str(tmp_path / "m.csv")],
                "convert": ["convert", log, "--to", "native", str(tmp_path / "c.zip")]}[command]
        code, out, err = _run(capsys, *argv)
        assert code == 2 and out == ""
        assert err.strip() == f"error: {log}: {what}"


def test_a_dataset_folder_with_its_logs_further_down_names_them(capsys, tmp_path):
    """``pdr inspect ipin2023_t3/`` (its logs in ``logfiles/``) or an MS floor folder (``path_data_files/``) said 'not
    a supported log format ...; pass --format to force one'; the logs a level or two down are named now, as a
    folder's own logs were."""
    from tests.conftest import REPO_ROOT

    ms = (REPO_ROOT / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz").read_bytes()
    root = tmp_path / "dataset"
    (root / "logfiles").mkdir(parents=True)
    (root / "supplementary").mkdir()
    for name in ("a.txt.gz", "b.txt.gz"):
        (root / "logfiles" / name).write_bytes(ms)
    (root / "supplementary" / "README.txt").write_text("a map\n")
    (root / "SOURCE.md").write_text("two walks\n")
    code, out, err = _run(capsys, "inspect", str(root))
    assert code == 2 and out == ""
    assert err.strip() == (f"error: {root}: not one log but a folder that holds logs (2 of its entries: "
                           "logfiles/a.txt.gz, logfiles/b.txt.gz); pass one of them")
