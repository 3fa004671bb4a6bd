import gzip
import json
import zipfile
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pdr.errors import InputError
from pdr.io import native
from pdr.recording import (
    DEVICE_ROLES,
    PLACEMENTS,
    PLATFORMS,
    STREAM_KINDS,
    DeviceInfo,
    GroundTruth,
    Labels,
    PositionTruth,
    Recording,
    SensorStream,
)
from tests.pdr.io._registry import detect_or_skip, read_or_skip

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
# any text a file can hold (no NUL: it marks binary data), including separators, quotes and line breaks
text = st.text(alphabet=st.characters(codec="utf-8", exclude_characters="\x00"), max_size=8)
T_BASE = 1_700_000_000_000_000_000


@st.composite
def streams(draw):
    kinds = draw(st.lists(st.sampled_from(sorted(STREAM_KINDS)), min_size=1, max_size=4, unique=True))
    out = {}
    for kind in kinds:
        n = draw(st.integers(1, 12))
        base = draw(st.integers(-(2**62), 2**62))
        steps = draw(st.lists(st.integers(1, 10**12), min_size=n, max_size=n))
        t = base + np.cumsum(steps)
        ncol = len(STREAM_KINDS[kind].columns)
        v = draw(st.lists(st.lists(finite, min_size=ncol, max_size=ncol), min_size=n, max_size=n))
        out[kind] = SensorStream(kind, t, np.array(v, dtype=np.float64))
    return out


def _sorted_floats(draw, n):
    return np.sort(np.array(draw(st.lists(st.floats(-1e6, 1e6), min_size=n, max_size=n)), dtype=np.float64))


@st.composite
def truths(draw):
    kw: dict[str, Any] = {}
    if draw(st.booleans()):
        n = draw(st.integers(0, 6))
        floor = np.array(draw(st.lists(st.one_of(st.just(float("nan")), finite), min_size=n, max_size=n)))
        origin = draw(st.one_of(st.none(), st.tuples(st.floats(-90, 90), st.floats(-180, 180))))
        kw["positions"] = PositionTruth(
            _sorted_floats(draw, n), np.array(draw(st.lists(st.lists(finite, min_size=3, max_size=3),
                                                            min_size=n, max_size=n))).reshape(n, 3),
            floor.astype(np.float64), kind=draw(st.sampled_from(["landmark", "waypoint", "stride", "dense"])),
            frame=draw(st.sampled_from(["enu", "map"])), origin_lat_lon_deg=origin)
    if draw(st.booleans()):
        n = draw(st.integers(0, 6))
        kw["step_times_s"] = _sorted_floats(draw, n)
        if draw(st.booleans()):
            kw["step_lengths_m"] = np.array(draw(st.lists(finite, min_size=n, max_size=n)), dtype=np.float64)
    elif draw(st.booleans()):
        kw["step_count"] = draw(st.integers(0, 10**6))
    for name in ("modes", "landmarks"):
        if draw(st.booleans()):
            n = draw(st.integers(0, 4))
            a = _sorted_floats(draw, n)
            kw[name] = Labels(a, a + np.array(draw(st.lists(st.floats(0, 100), min_size=n, max_size=n))),
                              tuple(draw(st.lists(text, min_size=n, max_size=n))))
    extra: dict[str, np.ndarray] = {}
    for name in draw(st.lists(text.filter(bool), max_size=3, unique=True)):
        n = draw(st.integers(0, 5))
        extra[name] = draw(st.sampled_from([
            np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool),
            np.array(draw(st.lists(st.integers(-(2**63), 2**63 - 1), min_size=n, max_size=n)), dtype=np.int64),
            np.array(draw(st.lists(st.floats(allow_infinity=False), min_size=2 * n, max_size=2 * n)),
                     dtype=np.float64).reshape(n, 2),
            np.array(draw(st.lists(text, min_size=n, max_size=n)), dtype=np.str_),
        ]))
    kw["extra"] = extra
    return GroundTruth(**kw)


@st.composite
def recordings(draw):
    s = draw(streams())
    device = DeviceInfo(platform=draw(st.sampled_from(PLATFORMS)), model=draw(text),
                        role=draw(st.sampled_from(DEVICE_ROLES)),
                        placement=draw(st.one_of(st.none(), st.sampled_from(PLACEMENTS))),
                        device_id=draw(text))
    t0 = draw(st.one_of(st.none(), st.integers(-(2**62), 2**62)))
    meta = draw(st.dictionaries(text, st.one_of(st.integers(-100, 100), text,
                                                               finite, st.lists(st.integers(), max_size=3)),
                                max_size=3))
    warnings = tuple(draw(st.lists(text, max_size=2)))
    return Recording(s, device=device, t0_ns=t0, truth=draw(truths()), warnings=warnings, meta=meta,
                     format="sim", source="hypothesis")


def _assert_same(a: Recording, b: Recording) -> None:
    assert a == b
    assert a.warnings == b.warnings
    assert dict(a.meta) == dict(b.meta)
    for k in a.truth.extra:
        assert a.truth.extra[k].shape == b.truth.extra[k].shape
        assert a.truth.extra[k].dtype.kind == b.truth.extra[k].dtype.kind


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(rec=recordings(), as_zip=st.booleans())
def test_folder_round_trip_is_exact(rec, as_zip, tmp_path_factory):
    out = tmp_path_factory.mktemp("native") / ("rec.zip" if as_zip else "rec")
    native.write(rec, out)
    assert native.sniff(out)
    back = native.read(out)
    _assert_same(rec, back)
    assert back.format == "native"


@settings(max_examples=60, deadline=None)
@given(rec=recordings())
def test_batch_round_trip_is_exact(rec):
    obj = native.batch_to_json(rec, session_id="s1", batch_id="b7")
    text = json.dumps(obj)  # must be plain JSON (no NaN outside extra truth; those become null)
    back = native.batch_from_json(json.loads(text))
    assert back.meta["session_id"] == "s1" and back.meta["batch_id"] == "b7"
    assert back == rec
    again = native.batch_to_json(back)
    assert again == obj


def _simple(n=5) -> Recording:
    t = T_BASE + np.arange(n) * 10_000_000
    return Recording({"acc": SensorStream("acc", t, np.tile([0.1, -0.2, 9.81], (n, 1))),
                      "baro": SensorStream("baro", t[:2], np.array([1013.25, 1013.2]))},
                     device=DeviceInfo("android", "Pixel", "phone", "hand", "dev1"),
                     truth=GroundTruth(step_times_s=np.array([0.1, 0.2])))


def test_folder_layout_is_human_readable(tmp_path):
    native.write(_simple(), tmp_path / "r")
    lines = (tmp_path / "r" / "acc.csv").read_text().splitlines()
    assert lines[0] == "t_ns,x,y,z"
    assert lines[1] == f"{T_BASE},0.1,-0.2,9.81"
    assert (tmp_path / "r" / "baro.csv").read_text().splitlines()[0] == "t_ns,p"
    meta = json.loads((tmp_path / "r" / "meta.json").read_text())
    assert meta["format"] == "pdr-native/1" and meta["t0_ns"] == T_BASE
    assert (tmp_path / "r" / "truth" / "steps.csv").read_text() == "t_s\n0.1\n0.2\n"


def test_gz_members_zip_with_top_folder_and_registry(tmp_path):
    rec = _simple()
    folder = native.write(rec, tmp_path / "r")
    acc = folder / "acc.csv"
    (folder / "acc.csv.gz").write_bytes(gzip.compress(acc.read_bytes()))
    acc.unlink()
    assert native.read(folder) == rec
    zpath = tmp_path / "wrapped.zip"
    with zipfile.ZipFile(zpath, "w") as zf:
        for f in folder.rglob("*"):
            if f.is_file():
                zf.write(f, "top/" + str(f.relative_to(folder)))
    assert detect_or_skip(zpath) == "native"
    assert read_or_skip(zpath) == rec
    batch = native.write_batch(rec, tmp_path / "b.json.gz")
    assert detect_or_skip(batch) == "native"
    assert read_or_skip(batch) == rec


def test_batch_schema_matches_data_model():
    schema = native.batch_schema()
    props = schema["properties"]["streams"]["properties"]
    assert set(props) == set(STREAM_KINDS)
    for kind, spec in STREAM_KINDS.items():
        ref = props[kind]["$ref"].rsplit("/", 1)[-1]
        row = schema["$defs"][ref]["properties"]["values"]["items"]
        assert row["minItems"] == row["maxItems"] == len(spec.columns)
    dev = schema["properties"]["device"]["properties"]
    assert set(dev["platform"]["enum"]) == set(PLATFORMS)
    assert set(dev["role"]["enum"]) == set(DEVICE_ROLES)
    assert set(dev["placement"]["enum"]) == {*PLACEMENTS, None}


def _batch():
    return {"format": "pdr-batch/1", "device": {"platform": "android"},
            "streams": {"acc": {"t_ns": [1, 2, 3, 4], "values": [[0, 0, 9.8], [0, 0, 9.8], [0, 0, 9.8], [0, 0, 9.8]]}}}


@pytest.mark.parametrize(("t_ns", "kept", "counts"), [
    ([1, 2, 2, 4], [1, 2, 4], "repeats (1) or goes backwards (0)"),
    ([1, 3, 2, 4], [1, 3, 4], "repeats (0) or goes backwards (1)"),
])
def test_repeated_or_backward_sample_dropped_with_a_warning(t_ns, kept, counts):
    b = _batch()
    b["streams"]["acc"]["t_ns"] = t_ns
    rec = native.batch_from_json(b, source="upload")
    assert rec.streams["acc"].t_ns.tolist() == kept
    assert len(rec.warnings) == 1 and counts in rec.warnings[0] and "streams.acc.t_ns[2]" in rec.warnings[0]


@pytest.mark.parametrize(("mutate", "field", "match"), [
    (lambda b: b["streams"]["acc"]["values"][3].__setitem__(1, "x"), r"streams\.acc\.values\[3\]\[1\]", "number"),
    (lambda b: b["streams"]["acc"]["values"][2].pop(), r"streams\.acc\.values\[2\]", "at least 3"),
    (lambda b: b["streams"]["acc"].__setitem__("t_ns", [1, 2, 1, 0]), r"streams\.acc\.t_ns\[2\]",
     "goes backwards in 2 of 4 samples"),
    (lambda b: b["streams"]["acc"]["values"][1].__setitem__(0, float("nan")), r"streams\.acc\.values\[1\]\[0\]",
     "not finite"),
    (lambda b: b["streams"]["acc"]["t_ns"].pop(), r"streams\.acc\.values", "3 timestamps but 4 rows"),
    (lambda b: b["streams"].__setitem__("accel", b["streams"]["acc"]), r"streams", "unexpected.*accel"),
    (lambda b: b["device"].__setitem__("role", "hat"), r"device\.role", "one of"),
    (lambda b: b.__setitem__("format", "other/1"), r"format", "pdr-batch/1"),
    (lambda b: b.pop("streams"), r"\$", "missing.*streams"),
    (lambda b: b["streams"]["acc"]["t_ns"].__setitem__(0, "1"), r"streams\.acc\.t_ns\[0\]", "integer"),
    (lambda b: b.__setitem__("truth", {"positions": {"t_s": [1.0], "pos_m": [[1, 2]]}}),
     r"truth\.positions\.pos_m\[0\]", "at least 3"),
    (lambda b: b.__setitem__("truth", {"step_times_s": [2.0, 1.0]}), r"truth\.step_times_s", "goes back"),
])
def test_bad_batch_names_json_path(mutate, field, match):
    b = _batch()
    mutate(b)
    with pytest.raises(InputError, match=match) as err:
        native.batch_from_json(b, source="upload")
    assert err.value.source == "upload"
    assert err.value.field is not None and __import__("re").fullmatch(field, err.value.field), err.value.field


def test_batch_not_an_object():
    with pytest.raises(InputError, match="JSON object"):
        native.batch_from_json([1, 2], source="upload")  # type: ignore[arg-type]


def test_large_batch_validates():
    n = 100_000
    t = (T_BASE + np.arange(n) * 5_000_000).tolist()
    v = np.random.default_rng(0).normal(size=(n, 3)).tolist()
    b: dict[str, Any] = {"format": "pdr-batch/1", "device": {},
                         "streams": {"acc": {"t_ns": t, "values": v}, "gyro": {"t_ns": t, "values": v}}}
    rec = native.batch_from_json(b)
    assert len(rec.stream("gyro")) == n
    b["streams"]["gyro"]["values"][n - 7][2] = True
    with pytest.raises(InputError) as err:
        native.batch_from_json(b)
    assert err.value.field == f"streams.gyro.values[{n - 7}][2]"


def test_large_folder_round_trip(tmp_path):
    n = 200_000
    rng = np.random.default_rng(1)
    rec = Recording({"acc": SensorStream("acc", T_BASE + np.arange(n) * 5_000_000, rng.normal(size=(n, 3)))})
    native.write(rec, tmp_path / "big")
    assert native.read(tmp_path / "big") == rec


@pytest.mark.parametrize(("content", "line", "field", "match"), [
    ("t_ns,x,y,z\n", None, None, None),  # header only: an empty stream is fine
    ("", 1, None, "empty file"),
    ("t_ns,x,y,z\n1,0,0,9.8\n2,0,0\n", 3, None, "expected 4 fields"),
    ("t_ns,x,y,z\n1,0,0,9.8\n2,0,0,9.8,5\n", 3, None, "expected 4 fields"),
    ("t_ns,x,y,z\n1,0,0,9.8\n2,0,abc,9.8\n", 3, "y", "not a number"),
    ("t_ns,x,y,z\n1,0,0,9.8\n2,0,nan,9.8\n", 3, "y", "not finite"),
    ("t_ns,x,y,z\n1,0,0,9.8\n2.5,0,0,9.8\n", 3, "t_ns", "not an integer"),
    ("t_ns,x,y,z\n5,0,0,9.8\n2,0,0,9.8\n1,0,0,9.8\n", 3, "t_ns", "backwards in 2 of 3"),
    ("t_ns,x,y\n5,0,0\n", 1, None, "header must be"),
])
def test_bad_stream_csv_names_file_line_field(tmp_path, content, line, field, match):
    folder = native.write(_simple(), tmp_path / "r")
    (folder / "acc.csv").write_text(content)
    if match is None:
        assert len(native.read(folder).stream("acc")) == 0
        return
    with pytest.raises(InputError, match=match) as err:
        native.read(folder)
    assert err.value.source is not None and err.value.source.endswith("acc.csv")
    assert err.value.line == line and err.value.field == field


def test_binary_garbage_and_foreign_input(tmp_path):
    garbage = tmp_path / "g.json"
    garbage.write_bytes(bytes(range(256)) * 10)
    assert not native.sniff(garbage)
    with pytest.raises(InputError, match="binary"):
        native.read(garbage)
    folder = native.write(_simple(), tmp_path / "r")
    (folder / "acc.csv").write_bytes(b"\x00\x01\x02garbage")
    with pytest.raises(InputError, match="acc.csv.*binary"):
        native.read(folder)
    bad_zip = tmp_path / "x.zip"
    bad_zip.write_bytes(b"PK\x03\x04 truncated")
    assert not native.sniff(bad_zip)
    with pytest.raises(InputError, match="zip"):
        native.read(bad_zip)
    for foreign in (tmp_path / "missing", tmp_path):
        assert not native.sniff(foreign)
    other = tmp_path / "other.json"
    other.write_text('{"format": "something"}')
    assert not native.sniff(other)
    broken = tmp_path / "broken.json"
    broken.write_text('{"format": "pdr-batch/1",\n "streams": {')
    assert native.sniff(broken)
    with pytest.raises(InputError, match="invalid JSON") as err:
        native.read(broken)
    assert err.value.line == 2


@pytest.mark.parametrize(("body", "match"), [
    ('{"format": "pdr-batch/1", "t0_ns": ' + "9" * 5000 + "}", r"invalid JSON: Exceeds the limit \(4300 digits\)"),
    ('{"format": "pdr-batch/1", "streams": ' + "[" * 100_000 + "]" * 100_000 + "}",
     "invalid JSON: arrays or objects nested too deeply"),
])
def test_json_beyond_the_parser_names_the_file(tmp_path, body, match):
    """A batch with an integer of 5000 digits or arrays nested 100 000 deep failed with a traceback (ValueError:
    Exceeds the limit (4300 digits) for integer string conversion; RecursionError)."""
    from pdr.io import sensor_logger

    p = tmp_path / "batch.json"
    p.write_text(body)
    with pytest.raises(InputError, match=match) as err:
        native.read(p)
    assert err.value.source == str(p)
    with pytest.raises(InputError, match=match):
        sensor_logger.read(p)


def test_meta_json_problems(tmp_path):
    folder = native.write(_simple(), tmp_path / "r")
    meta = json.loads((folder / "meta.json").read_text())
    meta["streams"]["accel"] = "acc.csv"
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="'accel' is invalid: expected one of \\['acc', ") as err:
        native.read(folder)
    assert err.value.field == "streams.accel"
    meta["streams"] = {"acc": "nope.csv"}
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="missing member 'nope.csv'"):
        native.read(folder)


@pytest.mark.parametrize(("edit", "field", "message"), [
    (lambda m: m["truth"].update(positions={"kind": "dense"}), "truth.positions", "missing: \\['file'\\]"),
    (lambda m: m["truth"].update(extra={"q": {}}), "truth.extra.q", "missing: \\['file'\\]"),
    (lambda m: m["truth"].update(steps="steps.csv"), "truth.steps", "expected type object"),
    (lambda m: m.update(t0_ns=float("nan")), "t0_ns", "expected type integer"),
    (lambda m: m.update(meta=[1, 2]), "meta", "expected type object"),
    (lambda m: m.update(warnings="x"), "warnings", "expected type array"),
])
def test_meta_json_structure_is_checked_by_the_folder_schema(tmp_path, edit, field, message):
    """Hostile meta.json contents (found by fuzzing) give an InputError naming the JSON path, never a crash."""
    folder = native.write(_simple(), tmp_path / "r")
    meta = json.loads((folder / "meta.json").read_text())
    meta.setdefault("truth", {})
    edit(meta)
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match=message) as err:
        native.read(folder)
    assert err.value.field == field


def test_recording_rejects_a_non_integer_time_origin():
    rec = _simple()
    not_an_int: Any = float("nan")   # deliberately ill-typed: the runtime check is what is tested
    with pytest.raises(InputError, match="t0_ns must be an integer"):
        Recording(dict(rec.streams), t0_ns=not_an_int)


@pytest.mark.parametrize("container", ["zip", "zip with a top folder", "folder"])
def test_a_native_recording_without_its_meta_json_says_so(tmp_path, container):
    """A native zip (or folder) without meta.json was 'not a supported log format (...); pass --format to force one':
    it now says the stream CSVs it found and what it lacks (native.near_miss); an untagged meta.json likewise."""
    from pdr.errors import UnknownFormatError
    from pdr.io import read_recording

    folder = native.write(_simple(), tmp_path / "r")
    (folder / "meta.json").unlink()
    log = folder
    if container != "folder":
        log = tmp_path / "r.zip"
        with zipfile.ZipFile(log, "w") as zf:
            for f in folder.rglob("*"):
                if f.is_file():
                    zf.write(f, ("top/" if "top" in container else "") + str(f.relative_to(folder)))
    with pytest.raises(UnknownFormatError) as err:
        read_recording(log)
    assert err.value.source == str(log)
    assert err.value.message == (f"not a readable log: a pdr native recording (acc.csv, baro.csv: t_ns columns) whose "
                                 f"{container.split()[0]} has no meta.json, which tags it pdr-native/1 and holds its "
                                 "device and t0_ns")
    if container == "folder":
        (folder / "meta.json").write_text('{"format": "pdr-native/0"}')
        with pytest.raises(UnknownFormatError, match=r"whose meta.json is not tagged \"format\": \"pdr-native/1\""):
            read_recording(folder)
    assert native.near_miss(tmp_path / "absent") is None and native.near_miss(folder / "acc.csv") is None
