"""MobiFall v2 reader: real acc/gyro trial pairs, activity labels, bad input."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import mobifall
from tests.pdr.io.dataset_samples import detect_or_skip, foreign_to, sample_path, samples_of

HEADER = """#Acceleration force along the x y z axes (including gravity).
#timestamp(ns),x,y,z(m/s^2)
##########################################
#Activity: 5 - STU - Stairs up - 10s
#Subject ID: 9
#Age: 30
##########################################

@DATA
"""
ROWS = ["939489614000, 0.57, 10.4, -1.08", "939499614000, 0.46, 10.3, -1.00", "939509614000, 0.30, 10.0, -0.84"]


def _write(folder: Path, name: str, rows: list[str], header: str = HEADER, gz: bool = False) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    data = (header + "\n".join(rows) + "\n").encode()
    p = folder / (name + (".gz" if gz else ""))
    p.write_bytes(gzip.compress(data) if gz else data)
    return p


# ---------------------------------------------------------------------------------------------------------
# real data

@pytest.mark.data
def test_walking_trial_reads_acc_and_gyro():
    rec = mobifall.read(sample_path("mobifall:acc"))
    assert rec.format == "mobifall" and rec.warnings == ()
    assert rec.device.placement == "trouser_pocket" and rec.device.platform == "android"
    assert set(rec.streams) == {"acc", "gyro"}
    assert rec.stream("acc").median_rate_hz() == pytest.approx(94.9, abs=1.0)
    assert rec.stream("gyro").median_rate_hz() == pytest.approx(200.0, abs=1.0)
    assert len(rec.stream("acc")) == 27224 and len(rec.stream("gyro")) == 59996
    assert rec.duration_s == pytest.approx(300.0, abs=0.1)
    assert np.median(np.linalg.norm(rec.values("acc"), axis=1)) == pytest.approx(10.0, abs=0.6)
    modes = rec.truth.modes
    assert modes is not None and modes.label == ("walking",)
    assert modes.t_start_s[0] == 0.0 and modes.t_end_s[0] > rec.duration_s
    assert rec.meta["activity_code"] == "WAL" and rec.meta["subject"] == 2 and rec.meta["trial"] == 1


@pytest.mark.data
def test_standing_trial_reads_gravity_at_rest():
    path = sample_path("mobifall:acc").parents[1] / "STD" / "STD_acc_2_1.txt.gz"
    if not path.exists():
        pytest.skip(f"not available: {path}")
    rec = mobifall.read(path)
    norm = np.linalg.norm(rec.values("acc"), axis=1)
    assert np.median(norm) == pytest.approx(9.81, abs=0.25)
    assert np.median(np.linalg.norm(rec.values("gyro"), axis=1)) < 0.1
    assert rec.truth.modes is not None and rec.truth.modes.label == ("stationary",)


@pytest.mark.data
def test_gyro_file_reads_the_same_trial():
    assert mobifall.read(sample_path("mobifall:gyro")) == mobifall.read(sample_path("mobifall:acc"))


@pytest.mark.data
@pytest.mark.parametrize("key", ["mobifall:acc", "mobifall:gyro"])
def test_detect_format_picks_mobifall(key):
    assert detect_or_skip(sample_path(key)) == "mobifall"


@pytest.mark.data
@pytest.mark.parametrize("key", foreign_to("mobifall"))
def test_sniff_rejects_other_datasets(key):
    assert mobifall.sniff(sample_path(key)) is False


@pytest.mark.data
def test_activity_folder_with_many_trials_is_not_one_recording():
    folder = sample_path("mobifall:acc").parents[1] / "STU"
    if not folder.exists():
        pytest.skip(f"not available: {folder}")
    assert mobifall.sniff(folder) is False
    with pytest.raises(InputError, match="exactly one MobiFall trial"):
        mobifall.read(folder)


def test_samples_table_lists_mobifall():
    assert samples_of("mobifall") == ["mobifall:acc", "mobifall:gyro"]


# ---------------------------------------------------------------------------------------------------------
# synthetic files

@pytest.mark.parametrize(("code", "mode"), sorted(mobifall.MODE_BY_CODE.items()))
def test_every_code_maps_to_a_mode(tmp_path, code, mode):
    header = HEADER.replace("5 - STU - Stairs up", f"1 - {code} - x")
    rec = mobifall.read(_write(tmp_path, f"{code}_acc_9_1.txt", ROWS, header))
    assert rec.truth.modes is not None and rec.truth.modes.label == (mode,)
    assert rec.meta["activity_code"] == code


def test_single_file_pair_and_folder(tmp_path):
    acc = _write(tmp_path / "t", "STU_acc_9_1.txt", ROWS, gz=True)
    gyro_rows = [r.replace("939", "940", 1) for r in ROWS]
    _write(tmp_path / "t", "STU_gyro_9_1.txt", gyro_rows, HEADER.replace("(m/s^2)", "(rad/s)"))
    rec = mobifall.read(acc)
    assert set(rec.streams) == {"acc", "gyro"}
    np.testing.assert_allclose(rec.t_s("acc"), [0.0, 0.01, 0.02])
    modes = rec.truth.modes
    assert modes is not None
    assert modes.t_end_s[0] == pytest.approx(rec.time_span_s()[1] + 0.01)
    assert mobifall.sniff(tmp_path / "t")
    assert mobifall.read(tmp_path / "t") == rec


def test_file_without_standard_name_uses_the_header(tmp_path):
    rec = mobifall.read(_write(tmp_path, "renamed.txt", ROWS))
    assert list(rec.streams) == ["acc"] and rec.meta["activity_code"] == "STU" and rec.meta["subject"] == 9


def test_unknown_code_is_a_warning(tmp_path):
    header = HEADER.replace("5 - STU - Stairs up", "9 - FOL - Forward lying")
    rec = mobifall.read(_write(tmp_path, "FOL_acc_9_1.txt", ROWS, header))
    assert rec.truth.modes is None and "unknown activity code 'FOL'" in rec.warnings[0]


@pytest.mark.parametrize(("rows", "match"), [
    ([], r"no samples after '@DATA'"),
    ([*ROWS, "939519614000, 0.30"], r"line 13: expected 4 fields"),
    ([*ROWS, "939519614000, 0.30, 10.0, -0.84, 7"], r"line 13: expected 4 fields"),
    ([*ROWS, "939519614000, 0.30, ten, -0.84"], r"line 13, field 'y': 'ten' is not a number"),
    ([*ROWS, "939519614000, 0.30, NaN, -0.84"], r"line 13, field 'y': value nan is not finite"),
    ([*ROWS, "939409614000, 0.30, 10.0, -0.84", "939409614001, 0.30, 10.0, -0.84"],
     r"line 13, field 'timestamp_ns': time goes backwards in 2 of"),
])
def test_bad_rows_name_file_and_line(tmp_path, rows, match):
    p = _write(tmp_path, "STU_acc_9_1.txt", rows)
    with pytest.raises(InputError, match=match) as info:
        mobifall.read(p)
    assert str(p) in str(info.value)


def test_bad_structure(tmp_path):
    empty = tmp_path / "STU_acc_9_1.txt"
    empty.write_text("")
    with pytest.raises(InputError, match="no '@DATA' line"):
        mobifall.read(empty)
    stray = _write(tmp_path / "s", "STU_acc_9_2.txt", ROWS, header="#Activity: 5 - STU\nstray text\n@DATA\n")
    with pytest.raises(InputError, match=r"line 2: expected a '#' header line"):
        mobifall.read(stray)
    garbage = tmp_path / "g" / "STU_acc_9_3.txt"
    garbage.parent.mkdir()
    garbage.write_bytes(bytes(range(256)) * 8)
    assert mobifall.sniff(garbage) is False
    with pytest.raises(InputError, match="binary"):
        mobifall.read(garbage)
    assert mobifall.sniff(tmp_path / "missing.txt") is False


@pytest.mark.parametrize(("value", "field"), [("1e308", "acc"), ("-2e4", "acc")])
def test_value_beyond_any_sensor_names_file_and_stream(tmp_path, value, field):
    """An accelerometer row of 1e308 m/s^2 (finite: the reader took it) made `pdr track` and `pdr classify` fail
    with a traceback (numpy.linalg.LinAlgError: Array must not contain infs or NaNs) once the filters squared it."""
    from pdr.io import read_recording

    folder = tmp_path / "STU"
    rows = [*ROWS[:2], ROWS[2].replace("10.0", value)]
    _write(folder, "STU_acc_9_1.txt", rows)
    _write(folder, "STU_gyro_9_1.txt", [r.replace("10.", "0.") for r in ROWS], HEADER.replace("Acceleration", "Rate"))
    assert np.isfinite(mobifall.read(folder).values("acc")).all()      # the reader's own check: finite
    with pytest.raises(InputError, match=r"sample 2 \(t 0.020 s\) holds a value of magnitude .* m/s\^2, beyond any "
                                         r"sensor \(limit 10000\)") as err:
        read_recording(folder)
    assert (err.value.source, err.value.field) == (str(folder), field)


def test_a_trial_file_that_is_a_folder_is_said_not_skipped_silently(tmp_path):
    """A trial folder whose gyro file is a folder (or a second trial's acc file is a named pipe) read as if they were
    absent, without a word; read_recording now says each (pdr.io.notices)."""
    import os

    from pdr.io import read_recording

    _write(tmp_path / "t", "STU_acc_9_1.txt", ROWS)
    (tmp_path / "t" / "STU_gyro_9_1.txt").mkdir()
    os.mkfifo(tmp_path / "t" / "WAL_acc_9_2.txt")
    rec = read_recording(tmp_path / "t")
    assert set(rec.streams) == {"acc"}
    assert rec.warnings[:2] == ("STU_gyro_9_1.txt: not read: a folder, not a file",
                                "WAL_acc_9_2.txt: not read: a named pipe (FIFO), not a file")
