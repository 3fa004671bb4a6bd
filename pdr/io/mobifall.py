"""MobiFall v2 activity recordings (``<CODE>_<acc|gyro>_<subject>_<trial>.txt[.gz]``), phone in a trouser pocket.

Each file: ``#`` header lines (sensor description, ``#Activity: 2 - WAL - Walking normal - 300s``,
``#Subject ID``, age, height, weight, gender), a line ``@DATA``, then CSV rows ``timestamp_ns, x, y, z``:
accelerometer in m/s^2 including gravity (about 87-100 Hz, irregular) or gyroscope in rad/s (about 200 Hz),
Android device frame, ns since boot. The ``acc`` and ``gyro`` files of one trial share a clock, so reading
either file also reads its sibling when present (``WAL_acc_2_1`` <-> ``WAL_gyro_2_1``); a folder holding the
files of exactly one trial is read the same way. ``ori`` files are not read.

Truth: the whole file is one activity, so :attr:`GroundTruth.modes` is a single interval from the first to
one sample period past the last sample, labelled with the motion-mode name of the activity code
(:data:`MODE_BY_CODE`). The raw code, subject and trial go into ``meta``.

A sample whose time repeats or goes back (one gyroscope file repeats a timestamp once) is dropped with a warning
naming file and line (:mod:`pdr.io.time_order`).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io.text import (
    decode_text,
    drop_cut_off_last_line,
    find_member,
    head,
    is_member_file,
    numeric_rows,
    parse_float_rows,
    read_bytes,
    strip_gz,
    timestamps_ns,
)
from pdr.io.time_order import keep_increasing, keep_lines
from pdr.recording import DeviceInfo, GroundTruth, Labels, Recording, SensorStream

FORMAT = "mobifall"
DESCRIPTION = "MobiFall v2 activity file (<CODE>_acc|gyro_<subject>_<trial>.txt[.gz]) with its activity label"

#: MobiFall activity code -> motion-mode name.
MODE_BY_CODE: dict[str, str] = {
    "STD": "stationary", "WAL": "walking", "JOG": "running", "JUM": "jumping", "STU": "stairs_up",
    "STN": "stairs_down", "SCH": "sitting", "CSI": "car_step_in", "CSO": "car_step_out",
}
SENSOR_KIND = {"acc": "acc", "gyro": "gyro"}
FIELDS = ("timestamp_ns", "x", "y", "z")

_NAME = re.compile(r"^(?P<code>[A-Z]{3})_(?P<sensor>acc|gyro)_(?P<subject>\d+)_(?P<trial>\d+)\.txt(\.gz)?$")
_HEADER_FIELDS = {"Activity": "activity", "Subject ID": "subject_id", "Age": "age", "Height(cm)": "height_cm",
                  "Weight(kg)": "weight_kg", "Gender": "gender", "Datetime": "datetime"}


def sniff(path: str | Path) -> bool:
    """True for a MobiFall acc/gyro text file, or a folder holding the files of one trial."""
    p = Path(path)
    try:
        if p.is_dir():
            return len(_trials_in(p)) == 1
    except OSError:
        return False
    return _sniff_file(p)


def _sniff_file(p: Path) -> bool:
    start = head(p)
    return b"\n@DATA" in start and (b"#Activity:" in start or _NAME.match(p.name) is not None)


def _trials_in(folder: Path) -> set[tuple[str, str, str]]:
    found = set()
    for child in sorted(folder.iterdir()):  # by name: the notices of members that are no files in a fixed order
        m = _NAME.match(child.name)
        if m and is_member_file(child):
            found.add((m["code"], m["subject"], m["trial"]))
    return found


def read(path: str | Path) -> Recording:
    """Read one MobiFall trial (acc and gyro); see the module docstring."""
    p = Path(path)
    if p.is_dir():
        trials = _trials_in(p)
        if len(trials) != 1:
            listed = ", ".join(sorted("_".join(t) for t in trials)[:5]) or "none"
            raise InputError(f"expected the files of exactly one MobiFall trial, found {len(trials)} ({listed});"
                             " pass one file", source=str(p))
        code, subject, trial = trials.pop()
        files = [f for f in (find_member(p, f"{code}_{s}_{subject}_{trial}.txt") for s in SENSOR_KIND) if f]
    else:
        files = [p]
        m = _NAME.match(p.name)
        if m:
            other = "gyro" if m["sensor"] == "acc" else "acc"
            sibling = find_member(p.parent, f"{m['code']}_{other}_{m['subject']}_{m['trial']}.txt")
            if sibling is not None:
                files.append(sibling)
    streams: dict[str, SensorStream] = {}
    headers: dict[str, dict[str, str]] = {}
    warnings: list[str] = []
    for f in files:
        kind, header, t_ns, values = _read_file(f, warnings)
        if kind in streams:
            raise InputError(f"two {kind} files for one trial", source=str(f))
        streams[kind] = SensorStream(kind, t_ns, values)
        headers[kind] = header
    header = next(iter(headers.values()))
    name_match = _NAME.match(files[0].name)
    code = _activity_code(header.get("activity", "")) or (name_match["code"] if name_match else "")
    meta: dict[str, Any] = {"activity_code": code, "files": [strip_gz(f.name) for f in files], "header": header}
    if name_match:
        meta.update(subject=int(name_match["subject"]), trial=int(name_match["trial"]))
    elif header.get("subject_id", "").isdigit():
        meta["subject"] = int(header["subject_id"])
    rec = Recording(streams=streams, device=DeviceInfo(platform="android", role="phone", placement="trouser_pocket"),
                    source=str(p), format=FORMAT, warnings=tuple(warnings), meta=meta)
    mode = MODE_BY_CODE.get(code)
    if mode is None:
        return _with_warning(rec, f"unknown activity code '{code}': no motion-mode label")
    start, end = rec.time_span_s()
    periods = [float(np.median(np.diff(s.t_ns))) / 1e9 for s in streams.values() if len(s) > 1]
    end += max(periods) if periods else 0.0
    return Recording(streams=rec.streams, device=rec.device, t0_ns=rec.t0_ns,
                     truth=GroundTruth(modes=Labels(np.array([start]), np.array([end]), (mode,))),
                     source=rec.source, format=FORMAT, warnings=rec.warnings, meta=meta)


def _with_warning(rec: Recording, warning: str) -> Recording:
    return Recording(streams=rec.streams, device=rec.device, t0_ns=rec.t0_ns, truth=rec.truth, source=rec.source,
                     format=rec.format, warnings=(*rec.warnings, warning), meta=rec.meta)


def _activity_code(activity: str) -> str:
    """``'2 - WAL - Walking normal - 300s'`` -> ``'WAL'``."""
    parts = [s.strip() for s in activity.split("-")]
    return parts[1] if len(parts) > 1 and re.fullmatch(r"[A-Z]{3}", parts[1]) else ""


def _read_file(p: Path, warnings: list[str]) -> tuple[str, dict[str, str], NDArray[np.int64], NDArray[np.float64]]:
    source = str(p)
    raw = drop_cut_off_last_line(read_bytes(p), source, b",", warnings, terminated=True)
    lines = decode_text(raw, source).splitlines()
    header: dict[str, str] = {}
    data_start = None
    for number, line in enumerate(lines, start=1):
        if line.startswith("@DATA"):
            data_start = number
            break
        if line.startswith("#"):
            key, sep, value = line.lstrip("#").partition(":")
            if sep and key.strip() in _HEADER_FIELDS:
                header[_HEADER_FIELDS[key.strip()]] = value.strip()
        elif line.strip():
            raise InputError(f"expected a '#' header line or '@DATA', found '{line.strip()[:40]}'", source=source,
                             line=number)
    if data_start is None:
        raise InputError("no '@DATA' line: not a MobiFall file", source=source)
    kind = _kind_of(p, lines[:data_start], source)
    fast = numeric_rows(raw, len(FIELDS), skip_lines=data_start)
    if fast is not None and fast[0].shape[0]:
        arr, numbers = fast[0], fast[1].tolist()
    else:                                   # line by line: names the bad line and field
        rows: list[list[str]] = []
        numbers = []
        for number in range(data_start + 1, len(lines) + 1):
            line = lines[number - 1]
            if line.strip():
                rows.append(line.split(","))
                numbers.append(number)
        if not rows:
            raise InputError("no samples after '@DATA'", source=source)
        arr = parse_float_rows(rows, numbers, source, FIELDS)
    keep = keep_increasing(arr[:, 0], source, "timestamp_ns", warnings, lines=numbers)
    arr, numbers = arr[keep], keep_lines(numbers, keep)
    return kind, header, timestamps_ns(arr[:, 0], source, "timestamp_ns", line_numbers=numbers), arr[:, 1:4]


def _kind_of(p: Path, header_lines: list[str], source: str) -> str:
    m = _NAME.match(p.name)
    if m:
        return SENSOR_KIND[m["sensor"]]
    text = "\n".join(header_lines)
    if "(m/s^2)" in text or "Acceleration" in text:
        return "acc"
    if "(rad/s)" in text or "Rate of rotation" in text:
        return "gyro"
    raise InputError("cannot tell accelerometer from gyroscope: neither the file name "
                     "(<CODE>_acc|gyro_<subject>_<trial>.txt) nor the header says", source=source)
