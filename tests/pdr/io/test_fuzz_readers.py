"""Hostile input for every reader: mutated real files either read or raise InputError, nothing else.

Each reader gets a small valid seed (repository fixtures and mobile_logs; excerpts of the shared datasets
for the others, marked ``data``), which hypothesis mutates: NaN/infinities/huge or empty fields, garbage
tokens, SQL and path injection strings, dropped, duplicated and swapped lines, truncation, random bytes,
a destroyed header, an empty member. The file is then read with the reader forced and with format
detection. Anything but a :class:`Recording` or an :class:`InputError` (with a message) is a bug.
MATLAB files go through the service's sandbox (see ``ISOLATED``). ``PDR_FUZZ_EXAMPLES`` raises the number
of examples per seed (default 12); ``PDR_FUZZ_SLOW_EXAMPLES`` those of the slow run (default 300).
"""

from __future__ import annotations

import gzip
import io
import json
import os
import re
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pdr.errors import InputError
from pdr.io.registry import _by_name, read_recording
from pdr.recording import Recording
from tests.conftest import REPO_ROOT, data_path

EXAMPLES = int(os.environ.get("PDR_FUZZ_EXAMPLES", "12"))
SLOW_EXAMPLES = int(os.environ.get("PDR_FUZZ_SLOW_EXAMPLES", "300"))
#: Formats read with ``scipy.io.loadmat``, which can crash the interpreter on corrupt files (a native
#: segmentation fault, not an exception): fuzzed through the service's sandbox (server/sandbox.py), which
#: must turn every crash into an InputError, with fewer examples (a child process per example).
ISOLATED = {"pyshoe"}
ISOLATED_EXAMPLES = 8
NASTY = ["NaN", "nan", "inf", "-Infinity", "1e309", "-1e309", "", " ", "abc", "0x1F", "9" * 60, "-0", "1e-320",
         "null", "true", "[]", "{}", '"', "'; DROP TABLE batches;--", "../../../../etc/passwd", "\x00", "\u00e9",
         "\ufeff", "-9223372036854775809", "1.5.3", "1,5"]


@dataclass(frozen=True)
class Seed:
    """A valid input: ``files`` (relative path -> content) stored as ``pack`` under the name ``root``."""

    fmt: str
    root: str
    files: dict[str, bytes]
    pack: str  # file | gz | zip | folder | binary

    def write(self, base: Path, files: dict[str, bytes]) -> Path:
        path = base / self.root
        if self.pack in ("file", "binary"):
            path.write_bytes(next(iter(files.values())))
        elif self.pack == "gz":
            path.write_bytes(gzip.compress(next(iter(files.values()))))
        elif self.pack == "zip":
            with zipfile.ZipFile(path, "w") as z:
                for name, content in files.items():
                    z.writestr(name, content)
        else:
            for name, content in files.items():
                (path / name).parent.mkdir(parents=True, exist_ok=True)
                (path / name).write_bytes(content)
        return path


def _head(content: bytes, lines: int, name: str = ".csv") -> bytes:
    if _is_binary(name):
        return content
    return b"".join(content.splitlines(keepends=True)[:lines])


def _is_binary(name: str) -> bool:
    return name.endswith((".npy", ".npz", ".mat", ".zip", ".gz"))


def _text_tree(folder: Path, lines: int = 150) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): _head(p.read_bytes(), lines, p.name) for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _zip_tree(path: Path, lines: int = 150) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {n: _head(z.read(n), lines, n) for n in z.namelist() if not n.endswith("/")}


def _gunzipped_tree(folder: Path, lines: int = 150) -> dict[str, bytes]:
    """Every file of a folder, ``.gz`` members decompressed (and renamed without ``.gz``), cut to ``lines``."""
    out = {}
    for p in sorted(folder.iterdir()):
        if p.is_file():
            raw = gzip.decompress(p.read_bytes()) if p.name.endswith(".gz") else p.read_bytes()
            out[p.name.removesuffix(".gz")] = _head(raw, lines)
    return out


def _native_batch() -> bytes:
    from tests.server.helpers import phone_batch

    return json.dumps(phone_batch("b1", 0.0)).encode()


def _npz() -> bytes:
    z = np.load(data_path("allan_static_imudata", "adis_16405_imu1.npz"))
    buf = io.BytesIO()
    np.savez(buf, data=z["data"][:3000], columns=z["columns"], fs=z["fs"])
    return buf.getvalue()


FIXTURES = REPO_ROOT / "tests" / "pdr" / "io" / "fixtures"
LOGS = REPO_ROOT / "mobile_logs"

SEEDS: dict[str, Callable[[], Seed]] = {
    "native-zip": lambda: Seed("native", "walk.zip", _zip_tree(LOGS / "sim" / "pocket_office.zip"), "zip"),
    "native-json": lambda: Seed("native", "batch.json", {"batch.json": _native_batch()}, "file"),
    "ms_indoor": lambda: Seed("ms_indoor", "trace.txt.gz", {"t": _head(gzip.decompress(
        (LOGS / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz").read_bytes()), 300)}, "gz"),
    "sensorconnect": lambda: Seed("sensorconnect", "SensorConnectData_42.csv", {"c": (
        FIXTURES / "sensorconnect" / "SensorConnectData_42_head.csv").read_bytes()}, "file"),
    "phyphox": lambda: Seed("phyphox", "export", _text_tree(FIXTURES / "phyphox" / "android_export"), "folder"),
    "sensor_logger-folder": lambda: Seed("sensor_logger", "rec", _text_tree(
        FIXTURES / "sensor_logger" / "android_face_up"), "folder"),
    "sensor_logger-push": lambda: Seed("sensor_logger", "push.json", {"p": (
        FIXTURES / "sensor_logger" / "android_push.json").read_bytes()}, "file"),
}
DATA_SEEDS: dict[str, Callable[[], Seed]] = {
    "ipin": lambda: Seed("ipin", "logfile.txt", {"t": _head(data_path(
        "ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt").read_bytes(), 400)}, "file"),
    "oxford": lambda: Seed("oxford", "accelerometer.csv.gz", {"a": _head(gzip.decompress(data_path(
        "oxford_step_counter", "optimisation", "data", "Samsung_Carmelo_Hard_FrontPocket_1",
        "accelerometer.csv.gz").read_bytes()), 300)}, "gz"),
    "mobifall": lambda: Seed("mobifall", "WAL_acc_2_1.txt.gz", {"a": _head(gzip.decompress(data_path(
        "mobifall_v2_pocket", "sub2", "ADL", "WAL", "WAL_acc_2_1.txt.gz").read_bytes()), 200)}, "gz"),
    "driving": lambda: Seed("driving", "17", _text_tree(data_path("driving_phone_mount", "17"), 200), "folder"),
    "xio": lambda: Seed("xio", "short_walk.csv", {"x": _head(data_path("xio_gait_loop", "short_walk.csv")
                                                             .read_bytes(), 300)}, "file"),
    "pyshoe": lambda: Seed("pyshoe", "2017-11-22-11-35-59.mat", {"m": data_path(
        "pyshoe_vicon", "2017-11-22-11-35-59.mat").read_bytes()}, "binary"),
    "static_npz": lambda: Seed("static_npz", "imu.npz", {"n": _npz()}, "binary"),
    "tyrex": lambda: Seed("tyrex", "Jakob_Nexus5_NoDist_Texting", _gunzipped_tree(data_path(
        "attitude_smartphones", "android", "Jakob_Nexus5_NoDist_Texting")), "folder"),
    "tyrex-zip": lambda: Seed("tyrex", "recording.zip", _gunzipped_tree(data_path(
        "attitude_smartphones", "android", "Jakob_Nexus5_Dist_Swinging")), "zip"),
}


@st.composite
def text_mutation(draw: st.DrawFn, content: bytes) -> bytes:
    lines = content.splitlines(keepends=True) or [b""]
    op = draw(st.sampled_from(["token", "token", "token", "drop", "dup", "swap", "truncate", "insert", "header",
                               "empty", "long_line"]))
    i = draw(st.integers(0, len(lines) - 1))
    if op == "token":
        tokens = list(re.finditer(rb"[^,;\t \r\n]+", lines[i]))
        if tokens:
            m = tokens[draw(st.integers(0, len(tokens) - 1))]
            nasty = draw(st.sampled_from(NASTY)).encode()
            lines[i] = lines[i][:m.start()] + nasty + lines[i][m.end():]
    elif op == "drop":
        del lines[i]
    elif op == "dup":
        lines.insert(i, lines[i])
    elif op == "swap":
        j = draw(st.integers(0, len(lines) - 1))
        lines[i], lines[j] = lines[j], lines[i]
    elif op == "truncate":
        return content[:draw(st.integers(0, len(content)))]
    elif op == "insert":
        at = draw(st.integers(0, len(content)))
        return content[:at] + draw(st.binary(min_size=1, max_size=40)) + content[at:]
    elif op == "header":
        lines[0] = draw(st.text(max_size=60)).encode("utf-8", "surrogatepass") + b"\n"
    elif op == "empty":
        return b""
    else:
        lines[i] = b",".join([draw(st.sampled_from(NASTY)).encode()] * 5000) + b"\n"
    return b"".join(lines)


@st.composite
def binary_mutation(draw: st.DrawFn, content: bytes) -> bytes:
    op = draw(st.sampled_from(["truncate", "flip", "insert", "zero"]))
    at = draw(st.integers(0, max(0, len(content) - 1)))
    if op == "truncate":
        return content[:at]
    if op == "insert":
        return content[:at] + draw(st.binary(min_size=1, max_size=64)) + content[at:]
    n = draw(st.integers(1, 64))
    block = bytes(n) if op == "zero" else bytes(b ^ 0xFF for b in content[at:at + n])
    return content[:at] + block + content[at + len(block):]


def check_reader(seed: Seed, data: st.DataObject) -> None:
    files = dict(seed.files)
    name = data.draw(st.sampled_from(sorted(files)))
    mutate = binary_mutation if seed.pack == "binary" or _is_binary(name) else text_mutation
    files[name] = data.draw(mutate(files[name]))
    module = _by_name()[seed.fmt]
    if seed.fmt in ISOLATED:
        from server.sandbox import read_isolated

        for fmt in (seed.fmt, None):
            try:
                read_isolated(next(iter(files.values())), seed.root, fmt)
            except InputError as exc:
                assert str(exc), "an InputError needs a message"
        return
    with tempfile.TemporaryDirectory(prefix="pdr-fuzz-") as tmp:
        path = seed.write(Path(tmp), files)
        for read in (module.read, read_recording):
            try:
                rec = read(path)
            except InputError as exc:
                assert str(exc), "an InputError needs a message"
                continue
            assert isinstance(rec, Recording)


def _run(seed_factory: Callable[[], Seed], examples: int) -> None:
    seed = seed_factory()
    module = _by_name()[seed.fmt]
    with tempfile.TemporaryDirectory(prefix="pdr-fuzz-") as tmp:  # the seed itself is valid
        assert isinstance(module.read(seed.write(Path(tmp), seed.files)), Recording)

    if seed.fmt in ISOLATED:
        examples = min(examples, ISOLATED_EXAMPLES)

    @settings(max_examples=examples, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(data=st.data())
    def fuzz(data: st.DataObject) -> None:
        check_reader(seed, data)

    fuzz()


@pytest.mark.parametrize("seed", sorted(SEEDS))
def test_reader_survives_hostile_input(seed):
    _run(SEEDS[seed], EXAMPLES)


@pytest.mark.data
@pytest.mark.parametrize("seed", sorted(DATA_SEEDS))
def test_reader_survives_hostile_input_on_dataset_excerpts(seed):
    if seed in ISOLATED:
        pytest.skip("read in a child process per example: fuzzed in the slow run")
    _run(DATA_SEEDS[seed], EXAMPLES)


@pytest.mark.slow
@pytest.mark.data
@pytest.mark.parametrize("seed", sorted(SEEDS | DATA_SEEDS))
def test_reader_survives_many_hostile_inputs(seed):
    _run((SEEDS | DATA_SEEDS)[seed], SLOW_EXAMPLES)


#: Seeds of text files whose lines are samples (JSON messages and binary files have no sample lines).
LINE_SEEDS = [pytest.param(k, marks=[pytest.mark.data] if k in DATA_SEEDS else []) for k in sorted(SEEDS | DATA_SEEDS)
              if k not in ("native-json", "sensor_logger-push", "pyshoe", "static_npz")]


def _samples(seed: Seed, files: dict[str, bytes], tmp: Path) -> Recording:
    with tempfile.TemporaryDirectory(dir=tmp) as sub:
        return read_recording(seed.write(Path(sub), files), seed.fmt)


def _count(rec: Recording) -> int:
    return sum(len(s) for s in rec.streams.values())


@pytest.mark.parametrize("seed_name", LINE_SEEDS)
def test_repeated_and_backward_times_are_dropped_with_a_warning_naming_file_and_line(seed_name, tmp_path):
    """Every reader's rule (pdr.io.time_order): a sample line repeated at once (its time repeats) or a copy of it
    two lines on (its time goes back, or repeats for a record of another stream in between) is dropped, the rest
    read, with a warning naming the file and the copy's line."""
    seed = (SEEDS | DATA_SEEDS)[seed_name]()
    base_rec = _samples(seed, seed.files, tmp_path)
    base = _count(base_rec)
    member = max((n for n in seed.files if not _is_binary(n)), key=lambda n: seed.files[n].count(b"\n"))
    lines = seed.files[member].splitlines(keepends=True)
    name = Path(seed.root if seed.pack in ("file", "gz") else member).name.removesuffix(".gz")
    # a line in the middle that is a sample: deleting it loses a sample
    i = next(i for i in range(len(lines) // 2, len(lines) - 3)
             if _count(_samples(seed, {**seed.files, member: b"".join(lines[:i] + lines[i + 1:])}, tmp_path))
             < base)
    for at in (i + 1, i + 3):
        copy = b"".join(lines[:at] + [lines[i]] + lines[at:])
        rec = _samples(seed, {**seed.files, member: copy}, tmp_path)
        assert _count(rec) == base, f"the copy at line {at + 1} was not dropped"
        new = [w for w in rec.warnings if w not in base_rec.warnings and name.split(".")[0] in w]
        assert new, (at + 1, name, rec.warnings)
        if not any(name.split(".")[0] in w and "repeat" in w for w in base_rec.warnings):  # else the first is named
            assert any(re.search(rf"\bline {at + 1}\b", w) for w in new), (at + 1, new)


@pytest.mark.parametrize("seed_name", LINE_SEEDS)
def test_cut_off_last_line_is_dropped_with_a_warning(seed_name, tmp_path):
    """A log the phone cut off mid-line (its last line ends after the first field, no line break) reads as the
    log without that line, with a warning naming the file and the line."""
    seed = (SEEDS | DATA_SEEDS)[seed_name]()
    member = max((n for n in seed.files if not _is_binary(n)), key=lambda n: seed.files[n].count(b"\n"))
    content = seed.files[member].rstrip(b"\r\n")
    body, _, last = content.rpartition(b"\n")
    whole = _samples(seed, {**seed.files, member: body + b"\n"}, tmp_path)
    cut = re.match(rb"[^,;\t ]+[,;\t ]", last)
    assert cut is not None
    rec = _samples(seed, {**seed.files, member: body + b"\n" + cut.group(0)}, tmp_path)
    assert _count(rec) == _count(whole)
    line = body.count(b"\n") + 2
    name = Path(seed.root if seed.pack in ("file", "gz") else member).name.removesuffix(".gz")
    assert any(name.split(".")[0] in w and f"cut-off last line {line}" in w for w in rec.warnings), rec.warnings


#: Readers that tell a last value cut short: their writers end every line with a line break (``terminated`` in
#: pdr.io.text.drop_cut_off_last_line) or, phyphox, write every value in one form (``value_form``).
CUT_VALUE_SEEDS = [pytest.param(k, marks=[pytest.mark.data] if k in DATA_SEEDS else [])
                   for k in ("ipin", "ms_indoor", "oxford", "mobifall", "driving", "xio", "tyrex", "tyrex-zip",
                             "sensorconnect", "native-zip", "sensor_logger-folder", "phyphox")]


@pytest.mark.parametrize("seed_name", CUT_VALUE_SEEDS)
def test_last_line_cut_in_its_last_value_is_dropped_with_a_warning(seed_name, tmp_path):
    """A log cut off in the last value of its last line (every field there but no line break: '1.67953' of
    '1.6795325') reads as the log without that line, with a warning naming the file and the line; it was read with
    the value cut short."""
    seed = (SEEDS | DATA_SEEDS)[seed_name]()
    member = max((n for n in seed.files if not _is_binary(n)), key=lambda n: seed.files[n].count(b"\n"))
    body, _, last = seed.files[member].rstrip(b"\r\n").rpartition(b"\n")
    whole = _samples(seed, {**seed.files, member: body + b"\n"}, tmp_path)
    value = re.split(rb"[,;\t ]", last)[-1]
    cut = last[:len(last) - max(1, len(value) // 2)]           # half the last value gone (a one-digit one: all)
    rec = _samples(seed, {**seed.files, member: body + b"\n" + cut}, tmp_path)
    assert _count(rec) == _count(whole)
    line = body.count(b"\n") + 2
    name = Path(seed.root if seed.pack in ("file", "gz") else member).name.removesuffix(".gz")
    assert any(name.split(".")[0] in w and f"cut-off last line {line}" in w for w in rec.warnings), rec.warnings
