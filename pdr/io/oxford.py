"""Oxford Step Counter dataset: accelerometer recordings with ground-truth steps.

Two layouts, each plain or ``.gz``:

Trial folder ``optimisation/data/<Phone>_<User>_<Surface>_<Position>_<n>/``, a zip of it (the folder at the top
of the zip or its files flat; the trial is then named by the zip), or its ``accelerometer.csv``
    ``accelerometer.csv``: no header, ``timestamp_ns, accuracy, ax, ay, az`` (m/s^2, incl. gravity, Android
    device frame, ns since boot). ``stepcounter.csv``: no header, ``timestamp_ns, chan1, chan2`` (0/1) from
    two foot-contact switches on the same clock; the true steps are the rising edges (0 -> 1) of either
    channel, merged and sorted into :attr:`GroundTruth.step_times_s` (per channel also in
    ``extra["step_times_chan1_s"]`` / ``extra["step_times_chan2_s"]``). ``metadata.txt`` (sensor name) and
    ``notes.txt`` (free text, often "<n> steps") go into ``meta``.
Validation file ``validation/user<k>_<position>_<unixms>.csv``
    no header, ``timestamp_ns, ax, ay, az, steps_algo, steps_ground_truth, steps_hw`` (cumulative counts);
    each increment of ``steps_ground_truth`` is a true step at that sample's time (an increment of k
    repeats the time k times).

An accelerometer file under another name (or not beside its ``stepcounter.csv``) is recognised by its content (every
complete line of its start has the five fields above) and read alone: no step truth, no names from its folder. A
validation file under another name is recognised likewise (three whole step counts after the three axes). A last line
cut off (the phone stopped: no line break at its end, which the app writes after every line, so its last value may be
cut short) is dropped with a warning.

Placement comes from the folder or file name: FrontPocket -> ``trouser_pocket_front``, BackPocket ->
``trouser_pocket_back``, InHand/hand and SwingingArm -> ``hand``, NeckPouch -> ``neck``, Armband ->
``armband``, Purse/bag -> ``bag``; anything else (e.g. ``_Patient_3``) is unknown.

Timestamps: the phones logged at SENSOR_DELAY_FASTEST, so the rate is jittery (about 100-405 Hz). A sample
whose timestamp repeats the previous one, or goes back before the latest kept one, is dropped with a
warning naming the file and line, by the readers' shared rule (:mod:`pdr.io.time_order`). ``t0_ns`` is
the first accelerometer timestamp.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io.bundle import Bundle, is_zip
from pdr.io.text import (
    decode_text,
    drop_cut_off_last_line,
    find_member,
    head,
    numeric_rows,
    parse_float_rows,
    read_bytes,
    strip_gz,
    timestamps_ns,
)
from pdr.io.time_order import keep_increasing, keep_lines
from pdr.recording import DeviceInfo, GroundTruth, Recording, SensorStream

FORMAT = "oxford"
DESCRIPTION = "Oxford Step Counter trial folder / accelerometer.csv / validation user*.csv, with true steps"

ACC_FIELDS = ("timestamp_ns", "accuracy", "ax", "ay", "az")
STEP_FIELDS = ("timestamp_ns", "chan1", "chan2")
VALIDATION_FIELDS = ("timestamp_ns", "ax", "ay", "az", "steps_algo", "steps_ground_truth", "steps_hw")

#: Lower-case name fragment -> placement (first match wins).
PLACEMENT_BY_NAME: tuple[tuple[str, str], ...] = (
    ("frontpocket", "trouser_pocket_front"),
    ("backpocket", "trouser_pocket_back"),
    ("neckpouch", "neck"),
    ("armband", "armband"),
    ("swingingarm", "hand"),
    ("inhand", "hand"),
    ("hand", "hand"),
    ("purse", "bag"),
    ("bag", "bag"),
)

_ACC_LINE = re.compile(rb"^\d{6,},-?\d+,[-+0-9.eE]+,[-+0-9.eE]+,[-+0-9.eE]+\r?$", re.MULTILINE)
_VALIDATION_NAME = re.compile(r"^user\d+_[A-Za-z]+_\d+\.csv(\.gz)?$")
_VALIDATION_LINE = re.compile(rb"^\d{6,}(,[-+0-9.eE]+){6}\r?$", re.MULTILINE)
#: A validation row recognised by content alone: three numbers after the time, then three whole step counts.
_VALIDATION_CONTENT = re.compile(rb"^\d{6,}(,-?[0-9.]+(e-?\d+)?){3}(,\d+(\.0)?){3}\r?$", re.IGNORECASE)
#: Complete lines of a file's start that must all fit a layout for content detection.
SNIFF_LINES = 5
ACC_FILE = "accelerometer.csv"
STEPS_FILE = "stepcounter.csv"


def sniff(path: str | Path) -> bool:
    """True for a trial folder or a zip of it, an accelerometer file (by its name or, renamed, by its content), or a
    validation file.
    """
    p = Path(path)
    try:
        if p.is_dir() or (p.is_file() and is_zip(p)):
            bundle = Bundle(p, anchor=ACC_FILE)
            acc = bundle.get(ACC_FILE)
            return acc is not None and bundle.get(STEPS_FILE) is not None and _all_lines_match(acc, _ACC_LINE)
    except (OSError, InputError):
        return False
    return _file_kind(p) is not None


def near_miss(path: str | Path) -> str | None:
    """Why a folder (or zip) that looks like a trial (its ``stepcounter.csv``) is not read as one, or None: the
    accelerometer file that :func:`sniff` needs is missing, empty or not in the trial's form.
    """
    p = Path(path)
    try:
        if not (p.is_dir() or (p.is_file() and is_zip(p))):
            return None
        bundle = Bundle(p, anchor=STEPS_FILE)
        if bundle.get(STEPS_FILE) is None:
            return None
        acc = bundle.get(ACC_FILE)
    except (OSError, InputError):
        return None
    trial = f"an Oxford step-counter trial ({STEPS_FILE})"
    if acc is None:
        return f"{trial} without {ACC_FILE}, the accelerometer it is read from"
    if not acc.strip():
        return f"{trial} whose {ACC_FILE} is empty"
    return f"{trial} whose {ACC_FILE} has lines that are not 'timestamp_ns,accuracy,x,y,z' in its first bytes"


def _file_kind(p: Path) -> str | None:
    """``acc`` or ``validation`` for a single file: by its name when it carries one of ours, else by its content
    (every complete line of its first bytes has the fields of exactly one of the two layouts).
    """
    start = head(p, 2048)
    if strip_gz(p.name) == ACC_FILE:
        return "acc" if _all_lines_match(start, _ACC_LINE) else None
    if _VALIDATION_NAME.match(p.name):
        return "validation" if _all_lines_match(start, _VALIDATION_LINE) else None
    if _all_lines_match(start, _ACC_LINE):
        return "acc"
    return "validation" if _all_lines_match(start, _VALIDATION_CONTENT) else None


def _all_lines_match(raw: bytes, pattern: re.Pattern[bytes]) -> bool:
    """True when the complete lines of ``raw`` (at most the first :data:`SNIFF_LINES`, at least one) all match."""
    lines = raw[:2048].split(b"\n")[:-1][:SNIFF_LINES] or raw[:2048].split(b"\n")[:1]
    return bool(lines) and all(pattern.match(line) is not None for line in lines)


def placement_from_name(name: str) -> str | None:
    """Placement named in a trial folder or file name, or None."""
    low = name.lower()
    for fragment, placement in PLACEMENT_BY_NAME:
        if fragment in low:
            return placement
    return None


def read(path: str | Path) -> Recording:
    """Read a trial folder (or a zip of it), an accelerometer file, or a validation file; see the module docstring."""
    p = Path(path)
    if p.is_dir() or is_zip(p):
        bundle = Bundle(p, anchor=ACC_FILE)
        if bundle.get(ACC_FILE) is None:
            raise InputError(f"no {ACC_FILE}[.gz] in the trial folder", source=str(p))
        return _read_trial(bundle, ACC_FILE, _trial_name(p, bundle), str(p))
    if strip_gz(p.name).startswith("stepcounter"):
        raise InputError("a step-counter file alone has no sensor data; pass the trial folder", source=str(p))
    if _file_kind(p) == "acc" or strip_gz(p.name) == ACC_FILE:
        # beside its stepcounter.csv the file is a trial's; renamed or alone it is read without truth or names
        if strip_gz(p.name) == ACC_FILE and find_member(p.parent, STEPS_FILE) is not None:
            return _read_trial(Bundle(p.parent), p.name, p.parent.name, str(p.parent))
        return _read_trial(Bundle(p.parent), p.name, None, str(p))
    return _read_validation(p)


def _trial_name(p: Path, bundle: Bundle) -> str:
    """The trial's folder name: the folder's, the zip's top folder's, or the zip's name without ``.zip``."""
    if p.is_dir():
        return p.name
    inner = bundle.name(ACC_FILE).rsplit(":", 1)[-1].split("/")
    return inner[-2] if len(inner) > 1 else strip_gz(p.name).removesuffix(".zip")


def _csv_rows(raw: bytes, source: str, columns: tuple[str, ...], warnings: list[str]
              ) -> tuple[NDArray[np.float64], list[int]]:
    """The numbers of a headerless CSV file and the line of every row (array path; line by line on bad input); a
    last line cut off (no line break at its end) is dropped with a warning.
    """
    raw = drop_cut_off_last_line(raw, source, b",", warnings, terminated=True)
    fast = numeric_rows(raw, len(columns))
    if fast is not None and fast[0].shape[0]:
        return fast[0], fast[1].tolist()
    rows: list[list[str]] = []
    numbers: list[int] = []
    for number, line in enumerate(decode_text(raw, source).splitlines(), start=1):
        if line.strip():
            rows.append(line.split(","))
            numbers.append(number)
    if not rows:
        raise InputError("empty file: no samples", source=source)
    return parse_float_rows(rows, numbers, source, columns), numbers


def _read_trial(bundle: Bundle, acc_member: str, trial: str | None, source: str) -> Recording:
    """The accelerometer member of a trial folder or zip (``trial`` its folder name), or of any folder when
    ``trial`` is None (then the file alone: no step truth, no names from the folder).
    """
    warnings: list[str] = []
    acc_source = bundle.name(acc_member)
    arr, numbers = _csv_rows(bundle.need(acc_member), acc_source, ACC_FIELDS, warnings)
    keep = keep_increasing(arr[:, 0], acc_source, "timestamp_ns", warnings, lines=numbers)
    arr = arr[keep]
    kept_lines = keep_lines(numbers, keep)
    t_ns = timestamps_ns(arr[:, 0], acc_source, "timestamp_ns", line_numbers=kept_lines)
    t0_ns = int(t_ns[0])
    stream = SensorStream("acc", t_ns, arr[:, 2:5])
    meta: dict[str, Any] = {"accuracy_values": sorted({int(a) for a in np.unique(arr[:, 1])})}
    truth = GroundTruth()
    if trial is None:
        meta = {"file": strip_gz(Path(acc_member).name), **meta}
        warnings.append(f"{strip_gz(Path(acc_member).name)} read alone (not beside a stepcounter.csv in its trial "
                        "folder): no step ground truth")
        device = DeviceInfo(platform="android", role="phone", placement=placement_from_name(acc_member))
        return Recording(streams={"acc": stream}, device=device, t0_ns=t0_ns, truth=truth, source=source,
                         format=FORMAT, warnings=tuple(warnings), meta=meta)
    meta = {"trial": trial, **meta}
    steps = bundle.get(STEPS_FILE)
    if steps is not None:
        truth = _contact_switch_truth(steps, bundle.name(STEPS_FILE), t0_ns, warnings)
    else:
        warnings.append("no stepcounter.csv in the trial folder: no step ground truth")
    for name in ("metadata.txt", "notes.txt"):
        if bundle.get(name) is not None:
            text = bundle.text(name).strip()
            meta[name.removesuffix(".txt")] = text
            m = re.search(r"(\d+)\s*steps", text, flags=re.IGNORECASE)
            if name == "notes.txt" and m:
                meta["notes_step_count"] = int(m.group(1))
    phone = trial.split("_")[0] if not trial.startswith("_") else ""
    device = DeviceInfo(platform="android", model=phone, role="phone", placement=placement_from_name(trial))
    return Recording(streams={"acc": stream}, device=device, t0_ns=t0_ns, truth=truth, source=source,
                     format=FORMAT, warnings=tuple(warnings), meta=meta)


def rising_edges(t_s: NDArray[np.float64], state: NDArray[np.float64]) -> NDArray[np.float64]:
    """Times at which a 0/1 contact signal switches on (the sample where it first reads 1)."""
    on = state > 0.5
    return t_s[1:][on[1:] & ~on[:-1]]


def _contact_switch_truth(raw: bytes, source: str, t0_ns: int, warnings: list[str]) -> GroundTruth:
    arr, numbers = _csv_rows(raw, source, STEP_FIELDS, warnings)
    bad = np.flatnonzero(~np.isin(arr[:, 1:], (0.0, 1.0)))
    if bad.size:
        r, c = divmod(int(bad[0]), 2)
        raise InputError(f"contact switch value {arr[r, 1 + c]} is not 0 or 1", source=source, line=numbers[r],
                         field=STEP_FIELDS[1 + c])
    keep = keep_increasing(arr[:, 0], source, "timestamp_ns", warnings, lines=numbers)
    arr = arr[keep]
    t_s = (timestamps_ns(arr[:, 0], source, "timestamp_ns") - np.int64(t0_ns)) / 1e9
    chan1 = rising_edges(t_s, arr[:, 1])
    chan2 = rising_edges(t_s, arr[:, 2])
    return GroundTruth(step_times_s=np.sort(np.concatenate([chan1, chan2])),
                       extra={"step_times_chan1_s": chan1, "step_times_chan2_s": chan2})


def _read_validation(p: Path) -> Recording:
    warnings: list[str] = []
    source = str(p)
    arr, numbers = _csv_rows(read_bytes(p), source, VALIDATION_FIELDS, warnings)
    keep = keep_increasing(arr[:, 0], source, "timestamp_ns", warnings, lines=numbers)
    arr = arr[keep]
    kept_lines = [n for n, k in zip(numbers, keep, strict=True) if k]
    t_ns = timestamps_ns(arr[:, 0], source, "timestamp_ns", line_numbers=kept_lines)
    t0_ns = int(t_ns[0])
    t_s = (t_ns - np.int64(t0_ns)) / 1e9
    counts = arr[:, 5]
    increments = np.diff(counts)
    down = np.flatnonzero(increments < 0)
    if down.size:
        i = int(down[0]) + 1
        raise InputError(f"cumulative ground-truth step count decreases ({counts[i - 1]:g} then {counts[i]:g})",
                         source=source, line=kept_lines[i], field="steps_ground_truth")
    steps = np.repeat(t_s[1:], np.round(increments).astype(np.int64))
    truth = GroundTruth(step_times_s=steps)
    meta = {"file": strip_gz(p.name), "steps_algo": float(arr[-1, 4] - arr[0, 4]),
            "steps_hw_counter": float(arr[-1, 6] - arr[0, 6])}
    device = DeviceInfo(platform="android", role="phone", placement=placement_from_name(p.name))
    return Recording(streams={"acc": SensorStream("acc", t_ns, arr[:, 1:4])}, device=device, t0_ns=t0_ns,
                     truth=truth, source=source, format=FORMAT, warnings=tuple(warnings), meta=meta)
