"""phyphox (RWTH Aachen) CSV export: zip or folder of one CSV per data set, with meta/time.csv and meta/device.csv.

Data sets are named by the experiment (``Accelerometer.csv``, ``Raw Data.csv``, ...), so streams are found by
their column headers, not file names: ``Time (s)`` plus

``Acceleration x (m/s^2)`` ... -> ``acc`` (with g), ``Linear Acceleration x (m/s^2)`` ... -> ``lin_acc``,
``Gyroscope x (rad/s)`` ... -> ``gyro``, ``Magnetic Field x (µT)`` ... -> ``mag``, ``Pressure (hPa)`` -> ``baro``.

The iOS multi-sensor export names the sensor only in the file name: ``Accelerometer.csv`` (with g),
``Linear Accelerometer.csv``, ``Gyroscope.csv``, ``Magnetometer.csv`` with plain ``X (m/s^2)``, ``Y (m/s^2)``,
``Z (m/s^2)`` columns; inside an export (next to ``meta/``) such a file is read by its name (:data:`FILE_KINDS`).

The unit in parentheses is honoured (m/s^2 or g, rad/s or deg/s, µT/uT, mT, hPa/kPa/Pa). phyphox already
reports Android-convention specific force on both platforms, so no sign changes are made. Columns such as
``Absolute acceleration`` are ignored. The five CSV dialects of phyphox are read: comma, tab or semicolon
with a decimal point, tab or semicolon with a decimal comma (the decimal mark is taken from the first data
line). Samples whose time repeats (a resaved file) or goes back are dropped with a warning naming file and line,
keeping the first of a repeat (:mod:`pdr.io.time_order`). phyphox for iOS writes the line break before each row,
not after it, so a whole export may end without one: a cut-off data set is told by its last value instead, one not
in phyphox's form (:data:`VALUE_FORM`; '9.8066' of '9.806650000E0') drops that line with a warning naming file
and line.

An export of gravity-free acceleration only (the "Linear Acceleration" experiment) gives no ``acc`` stream and
a warning naming the experiment that records acceleration with g, which the attitude and step stages need.

Time: ``Time (s)`` is experiment time, which stops while the experiment is paused. ``meta/time.csv`` lists
``event, experiment time, system time`` (epoch s) of every START/PAUSE; a sample at experiment time ``t`` after
the k-th START is at epoch ``system_k + (t - experiment_k)``, kept as integer ns. Without ``meta/time.csv``
(e.g. a single CSV file) the experiment time is used as is, with a warning.

``meta/device.csv`` (``property, value``) gives ``deviceModel`` and the platform (``deviceBrand`` Apple or an
iPhone/iPad model means iOS; ``deviceRelease``/``deviceBaseOS`` means Android).
"""

from __future__ import annotations

import csv
import io
import re
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from pdr.errors import InputError
from pdr.io.bundle import Bundle, is_zip
from pdr.io.csvtable import parse_table, split_header
from pdr.io.text import decode_text, head, read_bytes, strip_gz, timestamps_ns
from pdr.io.time_order import keep_increasing
from pdr.recording import DeviceInfo, Recording, SensorStream
from pdr.units import ACC_UNITS, GYRO_UNITS, MAG_UNITS, PRESSURE_UNITS

FORMAT = "phyphox"
DESCRIPTION = "phyphox CSV export (zip or folder: Time (s), Acceleration x (m/s^2), ..., meta/time.csv)"

_VECTOR = re.compile(r"^(?P<sensor>linear acceleration|acceleration|gyroscope|magnetic field) (?P<axis>[xyz]) "
                     r"\((?P<unit>[^)]*)\)$", re.IGNORECASE)
_PRESSURE = re.compile(r"^pressure \((?P<unit>[^)]*)\)$", re.IGNORECASE)
_KINDS = {"acceleration": "acc", "linear acceleration": "lin_acc", "gyroscope": "gyro", "magnetic field": "mag"}
#: Bare axis columns of the iOS multi-sensor export (``X (m/s^2)``); the file name says the sensor.
_BARE_AXIS = re.compile(r"^(?P<axis>[XYZxyz]) \((?P<unit>[^)]*)\)$")
#: File stem (lower case) -> stream kind, for files with bare axis columns inside an export with ``meta/``.
FILE_KINDS = {"accelerometer": "acc", "acceleration": "acc", "linear accelerometer": "lin_acc",
              "linear acceleration": "lin_acc", "gyroscope": "gyro", "magnetometer": "mag", "magnetic field": "mag"}
#: What to record when an export has gravity-free acceleration only.
LIN_ACC_ONLY = ("only gravity-free acceleration (the phyphox 'Linear Acceleration' experiment): no 'acc' stream; "
                "record with the 'Acceleration (with g)' experiment, or a multi-sensor one with the "
                "accelerometer and gyroscope, for tracks and step counts")
_UNITS = {"acc": ACC_UNITS, "lin_acc": ACC_UNITS, "gyro": GYRO_UNITS, "mag": {**MAG_UNITS, "mT": 1000.0},
          "baro": PRESSURE_UNITS}
_ALIASES = {"µT": "uT", "μT": "uT", "m/s²": "m/s^2", "m/s2": "m/s^2", "°/s": "deg/s", "mbar": "hPa"}
TIME_COLUMN = "Time (s)"
#: How phyphox writes every value of a data set (Java's DecimalFormat "0.000000000E0" with the dialect's decimal
#: mark; Python's "E+00" taken too), and the fillers of a missing one (Android "NaN", iOS '""').
VALUE_FORM = re.compile(r'-?\d[.,]\d{9}E[-+]?\d+|NaN|""')


def _axis_columns(header: list[str], file_kind: str | None = None) -> dict[str, dict[str, tuple[str, str]]]:
    """Stream kind -> axis -> (column name, unit) of the recognised columns of a header.

    ``file_kind`` is the stream kind the file name gives (iOS multi-sensor export): bare ``X (unit)`` columns
    are then read as that stream's axes.
    """
    out: dict[str, dict[str, tuple[str, str]]] = {}
    for col in header:
        b = _BARE_AXIS.match(col)
        if b and file_kind is not None:
            unit = b["unit"].strip()
            out.setdefault(file_kind, {})[b["axis"].lower()] = (col, _ALIASES.get(unit, unit))
            continue
        # the axis letter must be lower case: phyphox writes "x", x-io writes "X"
        m = _VECTOR.match(col)
        if m and m["axis"] in "xyz":
            unit = m["unit"].strip()
            out.setdefault(_KINDS[m["sensor"].lower()], {})[m["axis"]] = (col, _ALIASES.get(unit, unit))
            continue
        m = _PRESSURE.match(col)
        if m:
            unit = m["unit"].strip()
            out["baro"] = {"p": (col, _ALIASES.get(unit, unit))}
    return out


def _dialect(text: str) -> tuple[str, str]:
    """(delimiter, decimal mark) of a phyphox CSV: the delimiter from its header line, the decimal mark from
    the first data line (a comma there, with a tab or semicolon delimiter, is a decimal comma).
    """
    lines = text.lstrip("\ufeff").split("\n", 2)
    first = lines[0]
    delim = "\t" if "\t" in first else ";" if ";" in first else ","
    data = lines[1] if len(lines) > 1 else ""
    return delim, "," if delim != "," and "," in data else "."


def _file_kind(member: str, with_meta: bool) -> str | None:
    """Stream kind a data file's name gives, inside an export (``meta/`` next to it) only."""
    stem = member.rsplit("/", 1)[-1]
    stem = stem[:-4] if stem.lower().endswith(".csv") else stem
    return FILE_KINDS.get(stem.strip().lower()) if with_meta else None


def _is_data_header(first_line: str, file_kind: str | None = None) -> bool:
    delim, _ = _dialect(first_line)
    try:
        header = split_header(first_line, delim)
    except InputError:
        return False
    return bool(header) and header[0] == TIME_COLUMN and bool(_axis_columns(header[1:], file_kind))


def sniff(path: str | Path) -> bool:
    """A folder/zip with ``meta/time.csv`` or ``meta/device.csv`` and a phyphox data CSV, or one such CSV."""
    try:
        p = Path(path)
        if p.is_dir() or (p.is_file() and (p.name.lower().endswith(".zip") or is_zip(p))):
            bundle = Bundle(p, anchor="meta/time.csv")
            members = bundle.members()
            if "meta/time.csv" not in members and "meta/device.csv" not in members:
                return False
            for m in members:
                if "/" not in m and m.lower().endswith(".csv"):
                    raw = bundle.head(m, 1000)      # a member cut short further on: its reader says so
                    first = raw.decode("utf-8-sig", "replace").split("\n")[0]
                    if _is_data_header(first, _file_kind(m, True)):
                        return True
            return False
        if not strip_gz(p.name.lower()).endswith(".csv"):
            return False
        first = head(p).decode("utf-8-sig", errors="replace").split("\n", 1)[0].strip()
        return _is_data_header(first)
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return False


def read(path: str | Path) -> Recording:
    """Read a phyphox export (zip or folder) or a single phyphox CSV (plain or .gz)."""
    p = Path(path)
    warnings: list[str] = []
    meta: dict[str, object] = {}
    model, platform = "", "unknown"
    clock: list[tuple[float, int]] | None = None
    texts: list[tuple[str, str, str | None]] = []   # (name, text, stream kind its file name gives)
    if p.is_dir() or (p.is_file() and (p.name.lower().endswith(".zip") or is_zip(p))):
        bundle = Bundle(p, anchor="meta/time.csv")
        members = bundle.members()
        if "meta/time.csv" in members:
            clock = _read_time(bundle.text("meta/time.csv"), bundle.name("meta/time.csv"))
        if "meta/device.csv" in members:
            props = _read_device(bundle.text("meta/device.csv"), bundle.name("meta/device.csv"))
            meta["device"] = props
            model, platform = _model_platform(props)
        for m in members:
            if "/" not in m and m.lower().endswith(".csv"):
                texts.append((bundle.name(m), bundle.text(m), _file_kind(m, True)))
    else:
        texts.append((str(p), decode_text(read_bytes(p), str(p)), None))
    if clock is None:
        warnings.append("no meta/time.csv: timestamps are phyphox experiment time (s from the start), not epoch")

    streams: dict[str, SensorStream] = {}
    for name, text, file_kind in texts:
        for kind, stream in _read_data_csv(name, text, clock, file_kind, warnings).items():
            if kind in streams:
                raise InputError(f"a second '{kind}' data set (the first came from another file)", source=name)
            streams[kind] = stream
    if not streams:
        raise InputError("no phyphox data set found (a CSV with 'Time (s)' and e.g. 'Acceleration x (m/s^2)')",
                         source=str(p))
    if "lin_acc" in streams and "acc" not in streams:
        warnings.append(LIN_ACC_ONLY)
    if clock is not None:
        meta["start_epoch_ns"] = clock[0][1]
        meta["pauses"] = len(clock) - 1
    return Recording(streams, device=DeviceInfo(platform=platform, model=model), source=str(p), format=FORMAT,
                     warnings=tuple(warnings), meta=meta)


def _read_data_csv(name: str, text: str, clock: list[tuple[float, int]] | None, file_kind: str | None,
                   warnings: list[str]) -> dict[str, SensorStream]:
    first = text.split("\n", 1)[0].lstrip("\ufeff")
    delim, decimal = _dialect(text)
    header = split_header(first, delim, name) if first.strip() else []
    groups = _axis_columns(header[1:] if header[:1] == [TIME_COLUMN] else [], file_kind)
    if not groups:
        return {}
    table = parse_table(text, name, delimiter=delim, decimal=decimal, notes=warnings, value_form=VALUE_FORM)
    if len(table) == 0:
        raise InputError("no samples after the header", source=name, line=2)
    t_ns = epoch_ns(table.column(TIME_COLUMN), clock, name)
    keep = keep_increasing(t_ns, name, TIME_COLUMN, warnings, lines=table.lines())
    out: dict[str, SensorStream] = {}
    for kind, axes in groups.items():
        names = ("p",) if kind == "baro" else ("x", "y", "z")
        if set(axes) != set(names):
            raise InputError(f"incomplete {kind} columns (axes {sorted(axes)})", source=name, line=1)
        units = {axes[a][1] for a in names}
        unit = next(iter(units))
        if len(units) != 1 or unit not in _UNITS[kind]:
            raise InputError(f"unknown unit(s) {sorted(units)} for {kind}; expected one of {list(_UNITS[kind])}",
                             source=name, line=1, field=axes[names[0]][0])
        values = table.stack_scaled([axes[a][0] for a in names], _UNITS[kind][unit], unit)
        out[kind] = SensorStream(kind, t_ns[keep], values[keep])
    return out


#: Longest experiment time accepted (s): a phyphox run of more than ten years is a corrupt file.
MAX_EXPERIMENT_S = 3.2e8


def epoch_ns(t_s: np.ndarray, clock: list[tuple[float, int]] | None, source: str) -> np.ndarray:
    """Experiment time (s) to int ns: epoch via the START events of ``meta/time.csv`` when known."""
    if np.any(np.abs(t_s) > MAX_EXPERIMENT_S):
        raise InputError(f"experiment time beyond {MAX_EXPERIMENT_S:g} s (found {float(np.max(np.abs(t_s))):g} s)",
                         source=source, field=TIME_COLUMN)
    if clock is None:
        return timestamps_ns(t_s, source, TIME_COLUMN, scale=1e9)
    if any(not (0 <= c[1] < 2**62) for c in clock):
        raise InputError("system time outside the representable epoch range", source="meta/time.csv",
                         field="systemTime")
    starts = np.array([c[0] for c in clock])
    base_ns = np.array([c[1] for c in clock], dtype=np.int64)
    k = np.clip(np.searchsorted(starts, t_s, side="right") - 1, 0, len(clock) - 1)
    # the epoch part stays integer (parsed exactly from the text), only the offset is a float
    return base_ns[k] + timestamps_ns(t_s - starts[k], "meta/time.csv", "experimentTime", scale=1e9)


def _csv_rows(text: str, source: str) -> list[list[str]]:
    delim, _ = _dialect(text)
    try:
        return list(csv.reader(io.StringIO(text, newline=""), delimiter=delim))
    except csv.Error as exc:
        raise InputError(f"not a readable CSV file ({exc})", source=source) from None


def _read_time(text: str, source: str) -> list[tuple[float, int]] | None:
    """(experiment time s, system time epoch ns) of every START event."""
    rows = _csv_rows(text, source)
    if not rows:
        raise InputError("empty file", source=source, line=1)
    header = [h.strip() for h in rows[0]]
    need = ("event", "experiment time", "system time")
    missing = [h for h in need if h not in header]
    if missing:
        raise InputError(f"missing column(s) {missing} (header has {header})", source=source, line=1,
                         field=missing[0])
    idx = [header.index(h) for h in need]
    _, decimal = _dialect(text)
    starts = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) < len(header):
            raise InputError(f"expected {len(header)} fields, found {len(row)}", source=source, line=line)
        if row[idx[0]].strip().upper() != "START":
            continue
        vals = []
        for j, col in zip(idx[1:], need[1:], strict=True):
            try:
                v = Decimal(row[j].strip().replace(decimal, "."))
            except InvalidOperation:
                raise InputError(f"'{row[j][:40]}' is not a number", source=source, line=line, field=col) from None
            if not v.is_finite():
                raise InputError(f"value {v} is not finite", source=source, line=line, field=col)
            vals.append(v)
        starts.append((float(vals[0]), int((vals[1] * 10**9).to_integral_value())))
    if not starts:
        return None
    return sorted(starts)


def _read_device(text: str, source: str) -> dict[str, str]:
    rows = _csv_rows(text, source)
    if not rows:
        return {}
    return {r[0].strip(): r[1].strip() for r in rows[1:] if len(r) >= 2}


def _model_platform(props: dict[str, str]) -> tuple[str, str]:
    model = props.get("deviceModel", "")
    brand = (props.get("deviceBrand", "") + " " + props.get("deviceManufacturer", "")).lower()
    if "apple" in brand or model.startswith(("iPhone", "iPad")):
        return model, "ios"
    if any(k in props for k in ("deviceRelease", "deviceBaseOS", "deviceBoard", "deviceCodename")) or brand.strip():
        return model, "android"
    return model, "unknown"
