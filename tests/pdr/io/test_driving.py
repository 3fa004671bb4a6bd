"""driverBehaviorDataset trip reader: real trip, Earth-frame warning, event labels, repeated times, bad input."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from pdr.errors import InputError, UnknownFormatError
from pdr.io import detect_format, driving
from tests.conftest import data_path
from tests.pdr.io.dataset_samples import detect_or_skip, foreign_to, sample_path, samples_of

HEADER = "timestamp,uptimeNanos,x,y,z"
T0 = 12892910069993


def _rows(n: int, start: int = T0 + 1_000_000, dt: int = 20_000_000, z: float = 9.8) -> list[str]:
    return [f"14/05/2016 11:17:09,{start + i * dt},0.1,0.0,{z}" for i in range(n)]


def _trip(tmp_path: Path, acc: list[str] | None = None, gz: bool = False, trip: object | None = None,
          events: str | None = "evento, inicio, fim\nfreada_agressiva,0.5,0.8\ncurva_esquerda_agressiva,0.1,0.3\n",
          **files: list[str]) -> Path:
    folder = tmp_path / "17"
    folder.mkdir(parents=True, exist_ok=True)
    contents = {"acelerometro_terra.csv": acc if acc is not None else _rows(60), **files}
    for name, rows in contents.items():
        data = "\n".join([HEADER, *rows]).encode() + b"\n"
        if gz:
            (folder / (name + ".gz")).write_bytes(gzip.compress(data))
        else:
            (folder / name).write_bytes(data)
    if trip is None:
        trip = {"firstCollectionUptimeNanos": T0, "lastCollectionUptimeNanos": T0 + 1_500_000_000,
                "smartphoneModel": "XT1058", "androidVersion": "5.1"}
    (folder / "viagem.json").write_text(trip if isinstance(trip, str) else json.dumps(trip))
    if events is not None:
        (folder / "groundTruth.csv").write_text(events)
    return folder


# ---------------------------------------------------------------------------------------------------------
# real data

@pytest.mark.data
def test_trip_17():
    rec = driving.read(sample_path("driving:folder"))
    assert rec.format == "driving" and rec.meta["frame"] == "earth"
    assert driving.EARTH_FRAME_WARNING in rec.warnings
    assert any("averaged 20664 row(s)" in w for w in rec.warnings)  # the doubled magnetometer rows
    assert rec.device.placement == "vehicle_mount" and rec.device.model == "XT1058"
    assert set(rec.streams) == {"acc", "lin_acc", "gyro", "mag"}
    for kind in rec.streams:
        assert len(rec.stream(kind)) == 20675
        assert rec.stream(kind).median_rate_hz() == pytest.approx(51.0, abs=0.5)
    assert rec.t0_ns == 12892910069993
    assert rec.duration_s == pytest.approx(405.9, abs=0.2)  # SOURCE.md: 406 s
    # Earth frame: gravity on z whatever the mounting; linear acceleration has it removed
    np.testing.assert_allclose(np.median(rec.values("acc"), axis=0), [0.0, 0.0, 9.75], atol=0.1)
    np.testing.assert_allclose(np.median(rec.values("lin_acc"), axis=0), [0.0, 0.0, 0.0], atol=0.1)
    modes = rec.truth.modes
    assert modes is not None and modes.label == ("vehicle",)
    assert modes.t_start_s[0] == 0.0 and modes.t_end_s[0] == pytest.approx(406.17, abs=0.01)
    marks = rec.truth.landmarks
    assert marks is not None and len(marks) == 14
    assert marks.label[0] == "aggressive_right_lane_change" and marks.t_start_s[0] == 16.1
    assert set(marks.label) <= set(driving.EVENT_NAMES.values())


@pytest.mark.data
def test_a_trip_file_reads_its_folder():
    assert driving.read(sample_path("driving:acc")) == driving.read(sample_path("driving:folder"))


@pytest.mark.data
@pytest.mark.parametrize("key", ["driving:folder", "driving:acc"])
def test_detect_format_picks_driving(key):
    assert detect_or_skip(sample_path(key)) == "driving"


@pytest.mark.data
@pytest.mark.parametrize("key", foreign_to("driving"))
def test_sniff_rejects_other_datasets(key):
    assert driving.sniff(sample_path(key)) is False


def test_samples_table_lists_driving():
    assert samples_of("driving") == ["driving:folder", "driving:acc"]


# ---------------------------------------------------------------------------------------------------------
# synthetic trips

@pytest.mark.parametrize("gz", [False, True])
def test_minimal_trip(tmp_path, gz):
    folder = _trip(tmp_path, gz=gz)
    assert driving.sniff(folder)
    rec = driving.read(folder)
    assert list(rec.streams) == ["acc"]
    np.testing.assert_allclose(rec.t_s("acc")[:2], [0.001, 0.021])
    marks = rec.truth.landmarks
    assert marks is not None
    assert marks.label == ("aggressive_left_turn", "aggressive_braking")  # sorted by start
    assert rec.meta["events_raw"] == ["curva_esquerda_agressiva", "freada_agressiva"]
    modes = rec.truth.modes
    assert modes is not None and modes.t_end_s[0] == pytest.approx(1.5)


def test_repeated_timestamps_are_averaged():
    t, v, merged = driving.average_repeated_times(np.array([1, 2, 2, 3]), np.array([[0.0], [1.0], [3.0], [5.0]]))
    np.testing.assert_array_equal(t, [1, 2, 3])
    np.testing.assert_array_equal(v, [[0.0], [2.0], [5.0]])
    assert merged == 1


def test_without_trip_json_or_events(tmp_path):
    folder = _trip(tmp_path, events=None)
    (folder / "viagem.json").unlink()
    rec = driving.read(folder)
    assert rec.t0_ns == T0 + 1_000_000 and rec.truth.landmarks is None
    assert any("no viagem.json" in w for w in rec.warnings)


@pytest.mark.parametrize(("acc", "match"), [
    ([], "no samples after the header"),
    (["14/05/2016 11:17:09,12892911069993,0.1,0.0"], r"line 2: expected 5 fields"),
    ([*_rows(2), "14/05/2016 11:17:09,12892911069993,0.1,0.0,9.8,1"], r"line 4: expected 5 fields"),
    ([*_rows(2), "14/05/2016 11:17:09,12892991069993,0.1,abc,9.8"], r"line 4, field 'y': 'abc' is not a number"),
    ([*_rows(2), "14/05/2016 11:17:09,12892991069993,0.1,nan,9.8"], r"line 4, field 'y': value nan is not finite"),
    ([*_rows(2), "14/05/2016 11:17:09,12892000000000,0.1,0.0,9.8", "14/05/2016 11:17:09,12892000000001,0.1,0.0,9.8"],
     r"line 4, field 'uptimeNanos': time goes backwards in 2 of 4 samples"),
])
@pytest.mark.parametrize("pandas_path", [False, True])
def test_bad_sensor_rows_name_file_and_line(tmp_path, monkeypatch, acc, match, pandas_path):
    if pandas_path:
        monkeypatch.setattr(driving, "PANDAS_MIN_BYTES", 0)
    folder = _trip(tmp_path, acc)
    with pytest.raises(InputError, match=match) as info:
        driving.read(folder)
    assert "acelerometro_terra.csv" in str(info.value)


def _both_paths(raw: bytes) -> tuple[tuple[np.ndarray, list[int]], tuple[np.ndarray, list[int]] | None]:
    return driving._numbers_exact(raw, "f.csv"), driving._numbers_fast(raw)


def test_pandas_path_gives_the_line_by_line_values_bit_for_bit():
    """17-digit decimals (as the trips write them), exponents, CR LF, blank lines: the same float64 bits and line
    numbers by both paths; a file of another form is left to the line-by-line path (None).
    """
    rng = np.random.default_rng(5)
    v = rng.normal(0.0, 10.0, (500, 3)) * 10.0 ** rng.integers(-8, 3, (500, 3))
    rows = [f"14/05/2016 11:17:09,{T0 + 19_624_599 * i},{a!r},{b!r},{c!r}" for i, (a, b, c) in enumerate(v.tolist())]
    rows[10] = rows[10].replace(",", ", ", 1)            # a blank before a number, as float() allows
    text = "\n".join([HEADER, *rows[:200], "", *rows[200:]]) + "\n"
    for raw in (text.encode(), text.replace("\n", "\r\n").encode()):
        (exact, lines), fast = _both_paths(raw)
        assert fast is not None
        assert fast[0].tobytes() == exact.tobytes() and fast[1] == lines
        assert lines[199:201] == [201, 203]
    assert driving._numbers_fast((HEADER + "\n" + rows[0] + ",1\n").encode()) is None      # six fields
    assert driving._numbers_fast((HEADER + "\n  \n" + rows[0] + "\n").encode()) is None   # a blank-only line
    quoted = f'14/05/2016 11:17:09,{T0},"0.5",0.0,9.8'       # float() refuses the quotes: the exact path names it
    assert driving._numbers_fast((HEADER + "\n" + quoted + "\n").encode()) is None


@pytest.mark.data
def test_pandas_path_on_trip_17_is_the_line_by_line_path():
    for name in driving.SENSOR_FILES:
        member = Path(sample_path("driving:folder")) / name
        if not member.is_file():
            continue
        (exact, lines), fast = _both_paths(member.read_bytes())
        assert fast is not None and fast[0].tobytes() == exact.tobytes() and fast[1] == lines


def test_bad_files(tmp_path):
    folder = _trip(tmp_path)
    (folder / "acelerometro_terra.csv").write_text("")
    with pytest.raises(InputError, match="line 1: empty file"):
        driving.read(folder)
    (folder / "acelerometro_terra.csv").write_text("time,x,y,z\n1,2,3,4\n")
    assert driving.sniff(folder) is False
    with pytest.raises(InputError, match="line 1: expected the header"):
        driving.read(folder)
    (folder / "acelerometro_terra.csv").write_bytes(bytes(range(256)) * 8)
    with pytest.raises(InputError, match="binary"):
        driving.read(folder)
    folder = _trip(tmp_path / "b", trip="{not json")
    with pytest.raises(InputError, match=r"viagem.json, line 1: not valid JSON"):
        driving.read(folder)
    folder = _trip(tmp_path / "c", trip={"firstCollectionUptimeNanos": "soon"})
    with pytest.raises(InputError, match="field 'firstCollectionUptimeNanos'"):
        driving.read(folder)
    folder = _trip(tmp_path / "d", events="evento, inicio, fim\nfreada_agressiva,5,4\n")
    with pytest.raises(InputError, match=r"groundTruth.csv, line 2, field 'fim'"):
        driving.read(folder)
    folder = _trip(tmp_path / "e", events="evento, inicio, fim\nfreada_agressiva,x,4\n")
    with pytest.raises(InputError, match=r"groundTruth.csv, line 2, field 'inicio'"):
        driving.read(folder)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert driving.sniff(empty) is False
    with pytest.raises(InputError, match="no \\*_terra.csv"):
        driving.read(empty)
    assert driving.sniff(tmp_path / "missing.csv") is False


def test_a_trip_folder_without_its_accelerometer_says_what_is_missing(tmp_path):
    folder = _trip(tmp_path)
    (folder / "acelerometro_terra.csv").unlink()
    with pytest.raises(UnknownFormatError, match=r"without acelerometro_terra\.csv.*no sensor file at all"):
        detect_format(folder)
    (folder / "giroscopio_terra.csv").write_text(HEADER + "\n" + "\n".join(_rows(5)) + "\n")
    with pytest.raises(UnknownFormatError, match=r"without acelerometro_terra\.csv.*\(it has giroscopio_terra\.csv\)"):
        detect_format(folder)
    (folder / "acelerometro_terra.csv").write_text("time,x,y,z\n1,0,0,9.8\n")
    with pytest.raises(UnknownFormatError, match=r"does not start with the header timestamp,uptimeNanos,x,y,z"):
        detect_format(folder)
    # A folder without viagem.json is nobody's near miss: the generic message.
    (folder / "viagem.json").unlink()
    with pytest.raises(UnknownFormatError, match="not a supported log format"):
        detect_format(folder)


@pytest.mark.data
def test_trip_16_of_the_shared_data_names_its_missing_sensor_files():
    with pytest.raises(UnknownFormatError, match="trip folder .* without acelerometro_terra.csv"):
        detect_format(data_path("driving_phone_mount", "16"))
