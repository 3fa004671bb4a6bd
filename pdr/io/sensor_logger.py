"""Sensor Logger (Kelvin Choi, iOS/Android app): HTTP-push JSON messages, and the zip/folder CSV or JSON export.

Push message (HTTP push / MQTT, one per batch period)::

    {"messageId": 46, "sessionId": "...", "deviceId": "...",
     "payload": [{"name": "accelerometer", "time": 1675646835546228200, "values": {"x": .., "y": .., "z": ..}}, ...]}

``time`` is UTC epoch nanoseconds (an integer or a string of digits). :func:`parse_push_message` reads one
message; :func:`read` takes a ``.json`` file holding one message or a list of messages (one session).

Export: a folder or zip with one CSV per sensor, ``time,seconds_elapsed,<components>`` (for xyz sensors the file
order is ``z,y,x``: columns are always read by name), plus ``Metadata.csv`` (``platform``, ``standardisation``,
``device name``, ...). The export of early 2021 (Metadata ``version`` 2) has ``time,<components>`` (no
``seconds_elapsed``) and no ``standardisation`` column; it is read the same way. The app writes empty (0-byte)
files for streams that recorded nothing, and a file may hold its header only: either is skipped with a warning
naming it. The app ends every sample line with a line break (every reading CSV of the 2021 and 2024 exports of
../shared/data does; ``Metadata.csv`` does not and is read apart): a last line without one (an export cut off,
perhaps mid-number) is dropped with a warning naming file and line. The JSON export (a list of flat records
``{"sensor": "Accelerometer", "time": .., "x": ..}`` including a ``Metadata`` record) is read too.

Readings and streams
    ``accelerometer`` -> ``lin_acc`` (gravity removed!), ``totalacceleration`` -> ``acc``, ``gravity`` ->
    ``gravity``, ``gyroscope`` -> ``gyro``, ``magnetometer`` -> ``mag``, ``barometer.pressure`` -> ``baro``
    (hPa; ``relativeAltitude`` is not kept), ``orientation`` (qw, qx, qy, qz) -> ``orientation``, and
    ``accelerometeruncalibrated`` / ``gyroscopeuncalibrated`` / ``magnetometeruncalibrated`` -> ``*_uncal``.
    Other readings (microphone, battery, ...) are ignored and counted in ``meta``.

Location
    ``location`` readings (``latitude``, ``longitude`` in degrees, WGS-84; ``horizontalAccuracy`` in m when given)
    geo-reference the recording: the first fix goes to ``meta["location"]`` (:data:`LOCATION_META`:
    ``lat_deg``, ``lon_deg``, ``t_ns``, ``horizontal_accuracy_m``, ``unix_time_s``, ``fixes``), which the service
    takes as the session's origin (the track's local east/north frame starts there). A ``Location.csv`` without a
    fix (empty, as the app leaves it when the phone got none, or header only) is said in a warning.

Specific force
    Without ``totalacceleration`` (iOS never logs it), ``acc = accelerometer + gravity``: gravity is linearly
    interpolated to the accelerometer timestamps (exact when they coincide, as for the device-motion samples of
    iOS), held at its end values up to :data:`GRAVITY_HOLD_S` beyond its span; accelerometer samples farther
    outside are dropped with a warning.

Platform conventions (app documentation, UNITS.md / COORDINATES.md / CROSSPLATFORM.md of
``tszheichoi/awesome-sensor-logger``): with "Standardise Units & Frames" on, and always on Android, the data
follows Android: m/s^2, specific-force signs (a phone lying face-up reads gravity (0, 0, +9.81)), and the
orientation quaternion is Android's rotation vector, body to ENU (verified: it rotates the logged gravity onto
+z). On iOS without standardisation, accelerations and gravity have the opposite sign (Core Motion reports
-specific force), uncalibrated acceleration is in g, and the quaternion is Core Motion's attitude relative to an
x-north, z-up frame: converted here by negating (and scaling by g), and by ``q_nb = q_enu_nwu * q``. After
conversion every platform reads about (0, 0, +9.81) m/s^2 face-up at rest. An orientation stream that does
not rotate gravity onto +z (median error above 20 deg) is dropped with a warning rather than passed on wrong.

Push messages do not say the platform. It is taken from the ``platform``/``standardised`` arguments when
given, else from the data: ``totalacceleration`` exists only on Android; an uncalibrated accelerometer with a
norm near 1 is iOS in g; gravity rotated by the orientation quaternion points up (Android convention) or down
(raw iOS); otherwise the Android convention is assumed with a warning.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2
from pdr.io.bundle import Bundle, is_zip
from pdr.io.csvtable import parse_table, split_header
from pdr.io.text import decode_text, head, parse_json, read_bytes, strip_gz
from pdr.io.time_order import file_name, keep_increasing
from pdr.recording import LOCATION_META, DeviceInfo, Recording, SensorStream

FORMAT = "sensor_logger"
DESCRIPTION = "Sensor Logger app: HTTP-push JSON messages, zip/folder CSV export or JSON export (iOS and Android)"

_XYZ = ("x", "y", "z")
#: Reading name (lower case; CSV file stem lower-cased) -> (stream kind, components in stream column order).
READINGS: Mapping[str, tuple[str, tuple[str, ...]]] = {
    "accelerometer": ("lin_acc", _XYZ),
    "totalacceleration": ("acc", _XYZ),
    "gravity": ("gravity", _XYZ),
    "gyroscope": ("gyro", _XYZ),
    "magnetometer": ("mag", _XYZ),
    "barometer": ("baro", ("pressure",)),
    "orientation": ("orientation", ("qw", "qx", "qy", "qz")),
    "accelerometeruncalibrated": ("acc_uncal", _XYZ),
    "gyroscopeuncalibrated": ("gyro_uncal", _XYZ),
    "magnetometeruncalibrated": ("mag_uncal", _XYZ),
}
_LOCATION = ("latitude", "longitude")
#: Readings whose sign (and, uncalibrated, unit g) differ on iOS without standardisation.
_IOS_NEGATED = ("accelerometer", "totalacceleration", "gravity")
#: Gravity is held at its first/last value this far (s) beyond its span when recombining acc.
GRAVITY_HOLD_S = 0.1
#: Largest median angle (deg) between gravity rotated by the orientation quaternion and +z.
ORIENTATION_CHECK_DEG = 20.0
#: The end of a warning about a Location.csv without a usable fix.
NOT_GEO_REFERENCED = "the recording is not geo-referenced"
#: q_enu_nwu: the Core Motion x-north, y-west, z-up frame to ENU (a +90 deg turn about up).
Q_ENU_NWU = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])


@dataclass
class _Raw:
    """One reading's samples in the app's own convention, with where each came from (for messages)."""

    t_ns: NDArray[np.int64]
    values: NDArray[np.float64]
    where: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------------------------- sniffing

def _is_reading_csv_header(raw: bytes, name: str, with_metadata: bool) -> bool:
    """The header of reading ``name``'s CSV: ``time,seconds_elapsed,...`` (Metadata version 3 and later), or,
    next to a ``Metadata.csv``, ``time`` and the reading's components (version 2, early 2021: ``time,z,y,x``).
    """
    first = raw.split(b"\n", 1)[0].decode("utf-8-sig", errors="replace").strip().lower()
    if first.startswith("time,seconds_elapsed"):
        return True
    cols = [c.strip() for c in first.split(",")]
    return with_metadata and cols[:1] == ["time"] and {c.lower() for c in READINGS[name][1]} <= set(cols[1:])


def sniff(path: str | Path) -> bool:
    """A Sensor Logger export folder or zip, or a JSON push message / export (plain or .gz)."""
    try:
        p = Path(path)
        if p.is_dir() or (p.is_file() and (p.name.lower().endswith(".zip") or is_zip(p))):
            bundle = Bundle(p, anchor="Metadata.csv")
            members = bundle.members()
            for member in members:
                stem = member.rsplit("/", 1)[-1].rsplit(".", 1)[0].lower()
                if "/" not in member and member.lower().endswith(".csv") and stem in READINGS:
                    raw = bundle.head(member, 200)      # a member cut short further on: its reader says so
                    if _is_reading_csv_header(raw, stem, "Metadata.csv" in members):
                        return True
            return False
        if not p.is_file() or not strip_gz(p.name.lower()).endswith(".json"):
            return False
        start = head(p).lstrip()
        if start[:1] == b"{":
            return b'"payload"' in start and (b'"sessionId"' in start or b'"messageId"' in start)
        if start[:1] == b"[":
            return b'"payload"' in start or (b'"sensor"' in start and b'"seconds_elapsed"' in start)
        return False
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return False


def near_miss(path: str | Path) -> str | None:
    """Why one reading's CSV of an export (``Accelerometer.csv`` alone, its header ``time,seconds_elapsed,...``) is
    not read, or None: the export is read as a whole, from its folder or zip.
    """
    p = Path(path)
    name = strip_gz(p.name)
    stem = name.rsplit(".", 1)[0].lower()
    if not (p.is_file() and name.lower().endswith(".csv") and stem in READINGS
            and _is_reading_csv_header(head(p, 200), stem, False)):
        return None
    return (f"one reading ({name}) of a Sensor Logger export, which is read as a whole: give the export's folder or "
            "zip (its Metadata.csv and the other readings beside it)")


# --------------------------------------------------------------------------------------------- push messages

def _number(x: Any, source: str, where: str) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float | str):
        raise InputError(f"{json.dumps(x, default=str)[:40]} is not a number", source=source, field=where)
    try:
        v = float(x)
    except ValueError:
        raise InputError(f"'{str(x)[:40]}' is not a number", source=source, field=where) from None
    if not math.isfinite(v):
        raise InputError(f"value {v} is not finite", source=source, field=where)
    return v


def _time_ns(x: Any, source: str, where: str) -> int:
    if isinstance(x, bool):
        raise InputError("time must be integer nanoseconds since the epoch, got a boolean", source=source, field=where)
    if isinstance(x, int):
        t = x
    elif isinstance(x, str) and x.strip().lstrip("-").isdigit():
        t = int(x.strip())
    else:
        t = int(round(_number(x, source, where)))
    if not -(2**63) <= t < 2**63:
        raise InputError("time is outside the int64 nanosecond range", source=source, field=where)
    return t


def _collect_push(messages: Sequence[Any], source: str, prefix: str) -> tuple[dict[str, _Raw], dict[str, Any]]:
    """Readings of one or more push messages, in the app's convention (unsorted)."""
    rows: dict[str, tuple[list[int], list[list[float]], list[str]]] = {}
    ignored: dict[str, int] = {}
    fixes: list[dict[str, Any]] = []
    sessions: set[str] = set()
    meta: dict[str, Any] = {}
    for m, msg in enumerate(messages):
        mp = f"{prefix}[{m}]." if prefix else ""
        if not isinstance(msg, dict):
            raise InputError(f"a push message must be a JSON object, got {type(msg).__name__}", source=source,
                             field=mp.rstrip(".") or "$")
        payload = msg.get("payload")
        if not isinstance(payload, list):
            raise InputError("expected a list of readings", source=source, field=f"{mp}payload")
        if msg.get("sessionId") is not None:
            sessions.add(str(msg["sessionId"]))
        for key, name in (("sessionId", "session_id"), ("deviceId", "device_id"), ("messageId", "message_id")):
            if msg.get(key) is not None:
                meta.setdefault(name, msg[key])
        for i, entry in enumerate(payload):
            where = f"{mp}payload[{i}]"
            if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
                raise InputError("a reading must be an object with a string 'name'", source=source, field=where)
            name = entry["name"].lower()
            if name not in READINGS and name != "location":
                ignored[name] = ignored.get(name, 0) + 1
                continue
            if "time" not in entry:
                raise InputError("missing 'time'", source=source, field=f"{where}.time")
            t = _time_ns(entry["time"], source, f"{where}.time")
            values = entry.get("values")
            if not isinstance(values, dict):
                raise InputError("expected an object of values", source=source, field=f"{where}.values")
            if name == "location":
                fix = _fix(t, values, source, f"{where}.values")
                if fix is None:
                    ignored[name] = ignored.get(name, 0) + 1
                else:
                    fixes.append(fix)
                continue
            comps = READINGS[name][1]
            missing = [c for c in comps if c not in values]
            if missing:
                raise InputError(f"missing {missing} for '{name}' (has {sorted(values)})", source=source,
                                 field=f"{where}.values.{missing[0]}")
            vals = [_number(values[c], source, f"{where}.values.{c}") for c in comps]
            bucket = rows.setdefault(name, ([], [], []))
            bucket[0].append(t)
            bucket[1].append(vals)
            bucket[2].append(where)
    if len(sessions) > 1:
        raise InputError(f"messages of {len(sessions)} recording sessions ({sorted(sessions)[:3]}...); read each "
                         "session separately", source=source, field="sessionId")
    if ignored:
        meta["ignored_readings"] = ignored
    if fixes:
        meta[LOCATION_META] = _first_fix(fixes)
    out = {n: _Raw(np.array(t, dtype=np.int64), np.array(v, dtype=np.float64).reshape(len(t), -1), w)
           for n, (t, v, w) in rows.items()}
    return out, meta


def _fix(t_ns: int, values: Mapping[str, Any], source: str, where: str) -> dict[str, Any] | None:
    """One location fix (degrees, m) of a reading's values, or None when it holds no usable position (location is
    optional: such a reading is counted as ignored, never refuses the data).
    """
    try:
        lat, lon = (_number(values[c], source, f"{where}.{c}") for c in _LOCATION)
        acc = values.get("horizontalAccuracy")
        blank = acc is None or acc == "" or (isinstance(acc, float) and math.isnan(acc))
        accuracy = None if blank else _number(acc, source, f"{where}.horizontalAccuracy")
    except (KeyError, InputError):
        return None
    if abs(lat) > 90.0 or abs(lon) > 180.0:
        return None
    return {"lat_deg": lat, "lon_deg": lon, "t_ns": t_ns, "horizontal_accuracy_m": accuracy, "unix_time_s": t_ns / 1e9}


def _csv_location(text: str, source: str, notes: list[str]) -> dict[str, Any] | None:
    """The first fix of an export's ``Location.csv``, or None, said in ``notes``: a file without fixes (the app
    writes an empty one when the phone had none, e.g. indoors) or one that cannot be read (location is optional: it
    leaves the recording without geo-reference, never refuses it).
    """
    if not text.strip():
        notes.append(f"{file_name(source)}: empty file (no header, no fixes): {NOT_GEO_REFERENCED}")
        return None
    try:
        header = split_header(text.split("\n", 1)[0].lstrip("\ufeff"), ",", source)
        table = parse_table(text, source, int_columns=("time",), notes=notes, terminated=True,
                            nan_columns=[h for h in header if h not in ("time", *_LOCATION)])
        found = (_fix(int(t), {c: table.column(c)[i] for c in (*_LOCATION, "horizontalAccuracy") if c in table.header},
                      source, f"line {table.line(i)}") for i, t in enumerate(table.column("time")))
        fixes = [f for f in found if f is not None]
    except InputError as exc:
        notes.append(f"location not used ({exc}): {NOT_GEO_REFERENCED}")
        return None
    if not fixes:
        why = f"none of its {len(table)} rows is a position fix" if len(table) else "header only, no fixes"
        notes.append(f"{file_name(source)}: {why}: {NOT_GEO_REFERENCED}")
        return None
    return _first_fix(fixes)


def _first_fix(fixes: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The earliest fix, with the number of fixes."""
    return {**min(fixes, key=lambda f: int(f["t_ns"])), "fixes": len(fixes)}


def parse_push_message(obj: dict, *, source: str = "message", platform: str | None = None,
                       standardised: bool | None = None) -> Recording:
    """The :class:`Recording` of one decoded Sensor Logger push message.

    Parameters
    ----------
    obj
        ``{"messageId", "sessionId", "deviceId", "payload": [...]}``.
    source
        Name for messages (e.g. ``message 46``).
    platform, standardised
        ``"android"``/``"ios"`` and the app's "Standardise Units & Frames" setting, when the caller knows them;
        otherwise inferred from the data (see the module docstring).

    Raises
    ------
    InputError
        Naming the JSON path (``payload[3].values.x``) of a malformed reading, and when the message holds no
        supported sensor reading.
    """
    raw, meta = _collect_push([obj], source, "")
    return _assemble(raw, meta, source, platform, standardised, sort=True, device_name="")


# --------------------------------------------------------------------------------------------- files

def read(path: str | Path) -> Recording:
    """Read a Sensor Logger export (folder, zip; CSV or JSON) or a JSON file of push messages."""
    p = Path(path)
    if p.is_dir() or (p.is_file() and (p.name.lower().endswith(".zip") or is_zip(p))):
        return _read_bundle(Bundle(p, anchor="Metadata.csv"), str(p))
    text = decode_text(read_bytes(p), str(p))
    return _read_json(parse_json(text, str(p)), str(p))


def _read_json(obj: Any, source: str) -> Recording:
    if isinstance(obj, dict):
        raw, meta = _collect_push([obj], source, "")
        return _assemble(raw, meta, source, None, None, sort=True, device_name="")
    if isinstance(obj, list) and obj and isinstance(obj[0], dict) and "payload" in obj[0]:
        raw, meta = _collect_push(obj, source, "$")
        return _assemble(raw, meta, source, None, None, sort=True, device_name="")
    if isinstance(obj, list):
        return _read_json_export(obj, source)
    raise InputError("expected a push message, a list of them, or a Sensor Logger JSON export", source=source)


def _read_json_export(records: list[Any], source: str) -> Recording:
    """The JSON export: flat records ``{"sensor": "Accelerometer", "time": .., "x": .., ...}``."""
    rows: dict[str, tuple[list[int], list[list[float]], list[str]]] = {}
    metadata: dict[str, str] = {}
    fixes: list[dict[str, Any]] = []
    for i, rec in enumerate(records):
        where = f"[{i}]"
        if not isinstance(rec, dict) or not isinstance(rec.get("sensor"), str):
            raise InputError("a record must be an object with a string 'sensor'", source=source, field=where)
        name = rec["sensor"].lower()
        if name == "metadata":
            metadata = {str(k): str(v) for k, v in rec.items()}
            continue
        if name == "location" and "time" in rec:
            fix = _fix(_time_ns(rec["time"], source, f"{where}.time"), rec, source, where)
            fixes += [] if fix is None else [fix]
            continue
        if name not in READINGS:
            continue
        comps = READINGS[name][1]
        missing = [c for c in ("time", *comps) if c not in rec]
        if missing:
            raise InputError(f"missing {missing} for '{rec['sensor']}'", source=source, field=f"{where}.{missing[0]}")
        bucket = rows.setdefault(name, ([], [], []))
        bucket[0].append(_time_ns(rec["time"], source, f"{where}.time"))
        bucket[1].append([_number(rec[c], source, f"{where}.{c}") for c in comps])
        bucket[2].append(where)
    raw = {n: _Raw(np.array(t, dtype=np.int64), np.array(v, dtype=np.float64).reshape(len(t), -1), w)
           for n, (t, v, w) in rows.items()}
    platform, standardised, meta, device_name = _metadata_fields(metadata)
    if fixes:
        meta[LOCATION_META] = _first_fix(fixes)
    return _assemble(raw, meta, source, platform, standardised, sort=False, device_name=device_name)


def _metadata_fields(md: Mapping[str, str]) -> tuple[str | None, bool | None, dict[str, Any], str]:
    platform = md.get("platform", "").strip().lower() or None
    if platform not in (None, "ios", "android"):
        platform = None
    flag = md.get("standardisation", "").strip().lower()
    standardised = True if flag == "true" else False if flag == "false" else None
    meta: dict[str, Any] = {k: v for k, v in md.items() if k != "sensor"}
    if md.get("device id"):
        meta["device_id"] = md["device id"]
    return platform, standardised, meta, md.get("device name", "")


def _read_bundle(bundle: Bundle, source: str) -> Recording:
    metadata: dict[str, str] = {}
    md_raw = bundle.get("Metadata.csv")
    if md_raw is not None:
        try:
            rows = list(csv.reader(io.StringIO(decode_text(md_raw, bundle.name("Metadata.csv")), newline="")))
        except csv.Error as exc:
            raise InputError(f"not a readable CSV file ({exc})", source=bundle.name("Metadata.csv")) from None
        if len(rows) >= 2:
            metadata = {k.strip(): v.strip() for k, v in zip(rows[0], rows[1], strict=False)}
    raw: dict[str, _Raw] = {}
    notes: list[str] = []
    location: dict[str, Any] | None = None
    for member in bundle.members():
        if "/" in member or not member.lower().endswith(".csv"):
            continue
        name = member[:-4].lower()
        if name not in READINGS and name != "location":
            continue
        fname = bundle.name(member)
        text = bundle.text(member)
        if name == "location":
            location = _csv_location(text, fname, notes) or location
            continue
        if not text.strip():
            # The app writes empty files for streams that recorded nothing (e.g. Annotation.csv).
            notes.append(f"{member}: empty file (no header, no samples): {READINGS[name][0]} skipped")
            continue
        table = parse_table(text, fname, int_columns=("time",), notes=notes, terminated=True)
        comps = READINGS[name][1]
        for c in ("time", *comps):
            table.column(c)  # InputError naming the missing column
        if not len(table):
            notes.append(f"{member}: header only, no samples: {READINGS[name][0]} skipped")
            continue
        raw[name] = _Raw(table.column("time").astype(np.int64), table.stack(comps),
                         [f"{fname}, line {table.line(i)}" for i in range(len(table))])
    if not raw:
        raise InputError(f"no supported sensor CSV (expected e.g. {', '.join(_csv_names()[:4])}, ...)"
                         + (f"; {'; '.join(notes)}" if notes else ""), source=source)
    platform, standardised, meta, device_name = _metadata_fields(metadata)
    if not metadata:
        meta["metadata"] = "missing"
    if location is not None:
        meta[LOCATION_META] = location
    return _assemble(raw, meta, source, platform, standardised, sort=False, device_name=device_name, notes=notes)


def _csv_names() -> list[str]:
    names = {"accelerometer": "Accelerometer", "totalacceleration": "TotalAcceleration", "gravity": "Gravity",
             "gyroscope": "Gyroscope", "magnetometer": "Magnetometer", "barometer": "Barometer",
             "orientation": "Orientation", "accelerometeruncalibrated": "AccelerometerUncalibrated",
             "gyroscopeuncalibrated": "GyroscopeUncalibrated", "magnetometeruncalibrated": "MagnetometerUncalibrated"}
    return [names[k] + ".csv" for k in READINGS]


# --------------------------------------------------------------------------------------------- assembly

def _ordered(name: str, r: _Raw, source: str, sort: bool, warnings: list[str]) -> _Raw:
    """Samples in time order; a sample whose time repeats or goes back is dropped with a warning naming the file
    and line (or the message field), the first of a repeat kept (:mod:`pdr.io.time_order`).

    Push payloads are sorted first (their order carries no meaning), so there only repeats are dropped.
    """
    t, v, where = r.t_ns, r.values, r.where
    if sort:
        order = np.argsort(t, kind="stable")
        t, v, where = t[order], v[order], [where[i] for i in order]
    files = {w.rpartition(", line ")[0] for w in where}
    if len(files) == 1 and "" not in files:
        keep = keep_increasing(t, files.pop(), "time", warnings, lines=[int(w.rpartition(", line ")[2]) for w in where])
    else:
        keep = keep_increasing(t, source, "time", warnings, places=where, what=name)
    return _Raw(t[keep], v[keep], [where[i] for i in np.flatnonzero(keep)])


def _infer_convention(raw: Mapping[str, _Raw]) -> tuple[str, str]:
    """``android`` or ``ios`` (raw, unstandardised iOS), and why."""
    if "totalacceleration" in raw:
        return "android", "a totalacceleration reading (Android only)"
    if "accelerometeruncalibrated" in raw and len(raw["accelerometeruncalibrated"].t_ns):
        norm = float(np.median(np.linalg.norm(raw["accelerometeruncalibrated"].values, axis=1)))
        if 0.5 < norm < 2.0:
            return "ios", f"uncalibrated acceleration in g (median norm {norm:.3g})"
        if 5.0 < norm < 20.0:
            return "android", f"uncalibrated acceleration in m/s^2 (median norm {norm:.3g})"
    if "gravity" in raw and "orientation" in raw and len(raw["gravity"].t_ns) and len(raw["orientation"].t_ns):
        up = _gravity_in_nav(raw["orientation"].t_ns, _as_q(raw["orientation"].values), raw["gravity"])
        z = float(np.median(up[:, 2]))
        if abs(z) > 0.8 * GRAVITY_MPS2:
            return ("android", "gravity rotated by the orientation points up") if z > 0 else \
                ("ios", "gravity rotated by the orientation points down")
    return "unknown", ""


def _as_q(qwxyz: NDArray[np.float64]) -> NDArray[np.float64]:
    return quaternion.normalize(qwxyz)


def _gravity_in_nav(t_q: NDArray[np.int64], q: NDArray[np.float64], gravity: _Raw) -> NDArray[np.float64]:
    """Gravity interpolated to the quaternion times, rotated into the navigation frame."""
    g = _interp(gravity.t_ns, gravity.values, t_q)
    return quaternion.rotate(q, g)


def _interp(t_src: NDArray[np.int64], v_src: NDArray[np.float64], t_dst: NDArray[np.int64]) -> NDArray[np.float64]:
    t0 = t_src[0]
    xs = (t_src - t0).astype(np.float64)
    xd = (t_dst - t0).astype(np.float64)
    return np.column_stack([np.interp(xd, xs, v_src[:, k]) for k in range(v_src.shape[1])])


def _assemble(raw: dict[str, _Raw], meta: dict[str, Any], source: str, platform: str | None,
              standardised: bool | None, *, sort: bool, device_name: str, notes: Sequence[str] = ()) -> Recording:
    warnings: list[str] = list(notes)
    raw = {n: _ordered(n, r, source, sort, warnings) for n, r in raw.items()}
    raw = {n: r for n, r in raw.items() if len(r.t_ns)}
    if not raw:
        raise InputError("no supported sensor readings (accelerometer, gyroscope, magnetometer, ...)", source=source)

    if platform is not None and platform not in ("android", "ios"):
        raise InputError(f"unknown platform '{platform}' (android or ios)", source=source, field="platform")
    if platform == "android" or standardised:
        convention, why = "android", ("standardised units and frames" if standardised else "Android")
    elif platform == "ios" and standardised is False:
        convention, why = "ios", "iOS without standardisation"
    else:
        convention, why = _infer_convention(raw)
        if platform == "ios" and convention == "unknown":
            convention, why = "ios", "iOS; standardisation setting unknown, assumed off"
            warnings.append("iOS data without the standardisation setting: assumed off (the app's default)")
        elif convention == "unknown":
            convention = "android"
            why = "assumed"
            warnings.append("platform unknown and not inferable from the data: Android/standardised axes and "
                            "units assumed (turn on 'Standardise Units & Frames' in Sensor Logger to be sure)")
    meta = {**meta, "convention": convention, "convention_reason": why}
    if standardised is not None:
        meta["standardisation"] = standardised

    values: dict[str, NDArray[np.float64]] = {n: r.values for n, r in raw.items()}
    if convention == "ios":
        for name in _IOS_NEGATED:
            if name in values:
                values[name] = -values[name]
        if "accelerometeruncalibrated" in values:
            values["accelerometeruncalibrated"] = -values["accelerometeruncalibrated"] * GRAVITY_MPS2
        if "orientation" in values:
            values["orientation"] = quaternion.multiply(Q_ENU_NWU, _as_q(values["orientation"]))
    if "orientation" in values:
        values["orientation"] = _as_q(values["orientation"])

    streams: dict[str, SensorStream] = {}
    for name, r in raw.items():
        kind = READINGS[name][0]
        streams[kind] = SensorStream(kind, r.t_ns, values[name])
    if "acc" not in streams and "lin_acc" in streams and "gravity" in streams:
        streams["acc"] = _recombine(streams["lin_acc"], streams["gravity"], warnings)
    if "orientation" in streams and "gravity" in streams:
        g = _Raw(streams["gravity"].t_ns, np.asarray(streams["gravity"].values))
        up = _gravity_in_nav(streams["orientation"].t_ns, np.asarray(streams["orientation"].values), g)
        err = np.degrees(np.arccos(np.clip(up[:, 2] / np.maximum(np.linalg.norm(up, axis=1), 1e-9), -1, 1)))
        if float(np.median(err)) > ORIENTATION_CHECK_DEG:
            del streams["orientation"]
            warnings.append(f"orientation dropped: it does not rotate gravity onto up (median error "
                            f"{float(np.median(err)):.0f} deg), so its convention is not the documented one")
    if "lin_acc" in streams and "acc" not in streams:
        warnings.append("only gravity-free acceleration (no gravity or totalacceleration reading): no 'acc' stream")
    device = DeviceInfo(platform=platform or "unknown", model=device_name, role="phone", placement=None,
                        device_id=str(meta.get("device_id", "")))
    return Recording(streams, device=device, source=source, format=FORMAT, warnings=tuple(warnings), meta=meta)


def _recombine(lin: SensorStream, gravity: SensorStream, warnings: list[str]) -> SensorStream:
    """Specific force = user acceleration + gravity, gravity interpolated to the accelerometer times."""
    t = lin.t_ns
    hold = int(GRAVITY_HOLD_S * 1e9)
    ok = (t >= gravity.t_ns[0] - hold) & (t <= gravity.t_ns[-1] + hold)
    if not ok.all():
        warnings.append(f"acc: {int((~ok).sum())} accelerometer samples outside the gravity time span dropped "
                        "(acc = accelerometer + gravity needs both)")
    g = _interp(gravity.t_ns, np.asarray(gravity.values), t[ok])
    return SensorStream("acc", t[ok], np.asarray(lin.values)[ok] + g)
