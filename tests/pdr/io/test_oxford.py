"""Oxford Step Counter reader: real trials, contact-switch step truth, validation files, jitter, bad input."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import oxford
from tests.pdr.io.dataset_samples import detect_or_skip, foreign_to, sample_path, samples_of

T0 = 25468484780100


def _acc_lines(n: int, dt_ns: int = 5_000_000) -> list[str]:
    return [f"{T0 + i * dt_ns},3,0.1,0.2,9.8" for i in range(n)]


def _trial(tmp_path: Path, acc: list[str], steps: list[str] | None = None,
           name: str = "Pixel_Test_Hard_BackPocket_1", gz: bool = False) -> Path:
    folder = tmp_path / name
    folder.mkdir()

    def put(fname: str, lines: list[str]) -> None:
        data = ("\n".join(lines) + "\n").encode() if lines else b""
        if gz:
            (folder / (fname + ".gz")).write_bytes(gzip.compress(data))
        else:
            (folder / fname).write_bytes(data)

    put("accelerometer.csv", acc)
    if steps is not None:
        put("stepcounter.csv", steps)
    return folder


STEPS = [f"{T0 + i * 100_000_000},{a},{b}" for i, (a, b) in
         enumerate([(0, 0), (1, 0), (1, 0), (0, 1), (0, 1), (1, 0), (0, 0)])]


# ---------------------------------------------------------------------------------------------------------
# real data

@pytest.mark.data
def test_samsung_front_pocket_trial():
    rec = oxford.read(sample_path("oxford:folder"))
    assert rec.format == "oxford" and rec.warnings == ()
    assert rec.device.placement == "trouser_pocket_front" and rec.device.model == "Samsung"
    assert list(rec.streams) == ["acc"]
    assert rec.stream("acc").median_rate_hz() == pytest.approx(201.6, abs=1.0)
    assert rec.duration_s == pytest.approx(190.1, abs=0.2)
    assert np.median(np.linalg.norm(rec.values("acc"), axis=1)) == pytest.approx(9.8, abs=0.3)
    truth = rec.truth
    # SOURCE.md: 139 + 138 rising edges (notes.txt says 271 steps)
    assert len(truth.extra["step_times_chan1_s"]) == 139 and len(truth.extra["step_times_chan2_s"]) == 138
    assert truth.step_count == 277 and truth.step_times_s is not None
    assert np.all(np.diff(truth.step_times_s) >= 0)
    assert 0.0 < truth.step_times_s[0] and truth.step_times_s[-1] < rec.duration_s
    assert rec.meta["notes_step_count"] == 271


@pytest.mark.data
def test_accelerometer_file_reads_like_its_folder():
    folder = sample_path("oxford:folder")
    assert oxford.read(sample_path("oxford:acc")) == oxford.read(folder)


@pytest.mark.data
def test_pixel_trial_rate_and_steps():
    folder = sample_path("oxford:folder").parent / "Pixel_Jamie_Hard_InHand_3"
    if not folder.exists():
        pytest.skip(f"not available: {folder}")
    rec = oxford.read(folder)
    assert rec.device.placement == "hand"
    assert rec.stream("acc").median_rate_hz() == pytest.approx(405.0, abs=2.0)
    assert rec.truth.step_count == 162 + 161


@pytest.mark.data
@pytest.mark.parametrize("key", ["oxford:folder", "oxford:acc"])
def test_detect_format_picks_oxford(key):
    assert detect_or_skip(sample_path(key)) == "oxford"


@pytest.mark.data
@pytest.mark.parametrize("key", foreign_to("oxford"))
def test_sniff_rejects_other_datasets(key):
    assert oxford.sniff(sample_path(key)) is False


def test_samples_table_lists_oxford():
    assert samples_of("oxford") == ["oxford:folder", "oxford:acc"]


# ---------------------------------------------------------------------------------------------------------
# synthetic trials

@pytest.mark.parametrize("gz", [False, True])
def test_step_truth_is_rising_edges_of_both_channels(tmp_path, gz):
    folder = _trial(tmp_path, _acc_lines(200), STEPS, gz=gz)
    assert oxford.sniff(folder)
    rec = oxford.read(folder)
    assert rec.device.placement == "trouser_pocket_back"
    np.testing.assert_allclose(rec.truth.extra["step_times_chan1_s"], [0.1, 0.5])
    np.testing.assert_allclose(rec.truth.extra["step_times_chan2_s"], [0.3])
    assert rec.truth.step_times_s is not None
    np.testing.assert_allclose(rec.truth.step_times_s, [0.1, 0.3, 0.5])
    assert rec.stream("acc").median_rate_hz() == pytest.approx(200.0)


def test_missing_stepcounter_is_a_warning(tmp_path):
    folder = _trial(tmp_path, _acc_lines(10))
    assert oxford.sniff(folder) is False  # a trial folder has both files
    rec = oxford.read(folder)
    assert rec.truth.is_empty() and "no stepcounter" in rec.warnings[0]


def test_isolated_jitter_is_dropped_with_a_warning(tmp_path):
    lines = _acc_lines(300)
    lines[100] = lines[99]  # duplicate timestamp
    t = T0 + 199 * 5_000_000 - 7_000_000  # one sample back in time
    lines[200] = f"{t},3,0.1,0.2,9.8"
    rec = oxford.read(_trial(tmp_path, lines, STEPS))
    assert len(rec.stream("acc")) == 298
    (warning,) = rec.warnings
    assert "dropped 2 of 300 samples whose time repeats (1) or goes backwards (1)" in warning
    assert "accelerometer.csv" in warning and "first at line 101" in warning


@pytest.mark.parametrize("name,placement", [
    ("Samsung_Dario_Hard_FrontPocket_2", "trouser_pocket_front"),
    ("Samsung_Dario_Hard_Backpocket_2", "trouser_pocket_back"),
    ("Pixel_Jamie_Carpet_InHand_4", "hand"),
    ("Samsung_Carmelo_Hard_NeckPouch_1", "neck"),
    ("Samsung_Dario_Hard_ArmBand_1", "armband"),
    ("Pixel_Jamie_Hard_Purse_1", "bag"),
    ("Pixel_Jamie_Hard_SwingingArm_1", "hand"),
    ("user1_bag_1500000000000.csv", "bag"),
    ("user2_hand_1500000000000.csv", "hand"),
    ("_Patient_3", None),
])
def test_placement_from_name(name, placement):
    assert oxford.placement_from_name(name) == placement


def _validation(tmp_path: Path, gt_counts: list[int], name: str = "user1_frontpocket_1500000000000.csv") -> Path:
    p = tmp_path / name
    lines = [f"{T0 + i * 10_000_000},0.1,0.2,9.8,{c + 1},{c},0" for i, c in enumerate(gt_counts)]
    p.write_text("\n".join(lines) + "\n")
    return p


def test_validation_file_steps_are_count_increments(tmp_path):
    p = _validation(tmp_path, [5, 5, 6, 6, 8, 8, 9])
    assert oxford.sniff(p)
    rec = oxford.read(p)
    assert rec.device.placement == "trouser_pocket_front"
    assert rec.truth.step_times_s is not None
    np.testing.assert_allclose(rec.truth.step_times_s, [0.02, 0.04, 0.04, 0.06])
    assert rec.truth.step_count == 4
    assert rec.stream("acc").median_rate_hz() == pytest.approx(100.0)


def test_validation_count_going_down_is_an_error(tmp_path):
    p = _validation(tmp_path, [5, 6, 5])
    with pytest.raises(InputError, match=r"line 3, field 'steps_ground_truth'.*decreases"):
        oxford.read(p)


@pytest.mark.parametrize(("acc", "match"), [
    ([], "empty file"),
    (["25468484780100,3,0.1,0.2"], r"line 1: expected 5 fields"),
    ([*_acc_lines(2), "25468494780100,3,0.1"], r"line 3: expected 5 fields"),
    (["25468484780100,3,0.1,0.2,9.8,1"], r"line 1: expected 5 fields"),
    ([*_acc_lines(2), "25468494780100,3,0.1,x,9.8"], r"line 3, field 'ay': 'x' is not a number"),
    ([*_acc_lines(2), "25468494780100,3,0.1,nan,9.8"], r"line 3, field 'ay': value nan is not finite"),
    ([*_acc_lines(3)[::-1]], r"line 2, field 'timestamp_ns': time goes backwards"),
])
def test_bad_accelerometer_file_names_file_and_line(tmp_path, acc, match):
    folder = _trial(tmp_path, acc, STEPS)
    with pytest.raises(InputError, match=match) as info:
        oxford.read(folder)
    assert "accelerometer.csv" in str(info.value)


def test_bad_contact_switch_value(tmp_path):
    steps = [*STEPS[:3], f"{T0 + 400_000_000},2,0"]
    with pytest.raises(InputError, match=r"stepcounter.csv, line 4, field 'chan1'.*not 0 or 1"):
        oxford.read(_trial(tmp_path, _acc_lines(10), steps))


def test_binary_garbage_and_sniffing(tmp_path):
    folder = tmp_path / "Trial_FrontPocket_1"
    folder.mkdir()
    (folder / "accelerometer.csv").write_bytes(bytes(range(256)) * 8)
    (folder / "stepcounter.csv").write_text("\n".join(STEPS))
    assert oxford.sniff(folder) is False
    with pytest.raises(InputError, match="binary"):
        oxford.read(folder)
    assert oxford.sniff(tmp_path / "missing") is False
    assert oxford.sniff(folder / "stepcounter.csv") is False
    with pytest.raises(InputError, match="no accelerometer"):
        oxford.read(tmp_path)
    with pytest.raises(InputError, match="step-counter file alone"):
        oxford.read(folder / "stepcounter.csv")


@pytest.mark.parametrize(("acc", "match"), [
    (None, "without accelerometer.csv, the accelerometer it is read from"),
    ([], "whose accelerometer.csv is empty"),
    (["time,x,y,z", "1,2,3,4"], "whose accelerometer.csv has lines that are not 'timestamp_ns,accuracy,x,y,z'"),
])
def test_trial_folder_without_a_readable_accelerometer_says_so(tmp_path, acc, match):
    """A trial folder whose accelerometer.csv is missing (as _Patient_1 of the dataset), empty or of another layout was
    "not a supported log format (supported: ...); pass --format to force one"."""
    from pdr.errors import UnknownFormatError
    from pdr.io import read_recording

    folder = _trial(tmp_path, acc or [], STEPS)
    if acc is None:
        (folder / "accelerometer.csv").unlink()
    with pytest.raises(UnknownFormatError, match=f"not a readable log: an Oxford step-counter trial "
                                                 rf"\(stepcounter.csv\) {match}") as err:
        read_recording(folder)
    assert err.value.source == str(folder)


# ---------------------------------------------------------------------------------------------------------
# zipped trial folders, renamed files, a log cut off mid-line

@pytest.mark.parametrize("layout", ["folder at the top", "flat"])
def test_zipped_trial_folder_reads_as_the_folder(tmp_path, layout):
    folder = _trial(tmp_path, _acc_lines(50), STEPS, gz=True)
    (folder / "notes.txt").write_text("12 steps\n")
    z = tmp_path / ("trial.zip" if layout == "flat" else "upload.zip")
    import zipfile

    with zipfile.ZipFile(z, "w") as zf:
        for f in sorted(folder.iterdir()):
            zf.write(f, f.name if layout == "flat" else f"{folder.name}/{f.name}")
    assert oxford.sniff(z) and detect_or_skip(z) == "oxford"
    rec, ref = oxford.read(z), oxford.read(folder)
    assert rec.stream("acc") == ref.stream("acc") and rec.truth.step_count == ref.truth.step_count == 3
    assert rec.meta["notes_step_count"] == 12 and rec.warnings == ()
    if layout == "folder at the top":  # the trial's name (phone, placement) comes from its folder
        assert rec.meta["trial"] == folder.name and rec.device.model == "Pixel"
        assert rec.device.placement == "trouser_pocket_back"
    else:
        assert rec.meta["trial"] == "trial" and rec.device.placement is None


def test_renamed_accelerometer_file_is_detected_by_its_content(tmp_path):
    from pdr.io import detect_format

    p = tmp_path / "my walk.csv"
    p.write_text("\n".join(_acc_lines(20)) + "\n")
    assert detect_format(p) == "oxford"
    rec = oxford.read(p)
    assert len(rec.stream("acc")) == 20 and rec.truth.step_count is None
    assert rec.device.model == "" and "trial" not in rec.meta  # no name taken from the folder it sits in
    assert any("read alone" in w for w in rec.warnings)
    other = tmp_path / "table.csv"
    other.write_text("1,2,3\n4,5,6\n")
    assert not oxford.sniff(other)


def test_cut_off_last_line_dropped_with_a_warning(tmp_path):
    lines = _acc_lines(30)
    folder = _trial(tmp_path, lines, STEPS)
    (folder / "accelerometer.csv").write_text("\n".join(lines) + "\n" + lines[0][:16])  # the phone stopped mid-line
    rec = oxford.read(folder)
    assert len(rec.stream("acc")) == 30
    assert any("accelerometer.csv: dropped the cut-off last line 31 (2 of 5 fields)" in w for w in rec.warnings)
    (folder / "accelerometer.csv").write_text("\n".join(lines) + "\n" + lines[0][:16] + "\n")  # not at the end: bad
    with pytest.raises(InputError, match="line 31: expected 5 fields"):
        oxford.read(folder)
