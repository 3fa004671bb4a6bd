"""x-io Technologies CSV (NGIMU / x-IMU3 as used by the Gait-Tracking example): foot-mounted IMU.

Header ``Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Accelerometer X (g),...``;
optional ``Magnetometer X (uT)`` and ``Barometer (hPa)`` columns are read too. The unit in parentheses is
honoured (deg/s or rad/s; g or m/s^2; uT; hPa) and converted to SI. The accelerometer is specific force in the
sensor frame (about +1 g along the up-pointing axis at rest).

``Time`` is in seconds from the start; ``t_ns = round(t * 1e9)``. The x-io logs repeat some rows verbatim
(the same timestamp and values, about 1 % of the Gait-Tracking example): rows whose time repeats (the first is
kept) or goes back are dropped with a warning naming the line (:mod:`pdr.io.time_order`). The x-io software ends
every row with a line break: a last line without one (a recording cut off, mid-number or mid-line) is dropped with
a warning naming the file and line.

The side of the foot is not recorded: role ``right_foot`` with ``meta['foot_side'] = 'unknown'``.
"""

from __future__ import annotations

import re
from pathlib import Path

from pdr.errors import InputError
from pdr.io.csvtable import parse_table
from pdr.io.text import head, read_text, timestamps_ns
from pdr.io.time_order import keep_increasing
from pdr.recording import DeviceInfo, Recording, SensorStream
from pdr.units import ACC_UNITS, GYRO_UNITS, MAG_UNITS, PRESSURE_UNITS

FORMAT = "xio"
DESCRIPTION = "x-io Technologies CSV (Time (s), Gyroscope X (deg/s), Accelerometer X (g), ...), e.g. Gait-Tracking"

_COLUMN = re.compile(r"^(?P<name>.+?)\s*\((?P<unit>[^)]*)\)$")
_SENSORS = {"Gyroscope": ("gyro", GYRO_UNITS), "Accelerometer": ("acc", ACC_UNITS),
            "Magnetometer": ("mag", MAG_UNITS)}
_UNIT_ALIASES = {"µT": "uT", "μT": "uT", "m/s²": "m/s^2", "m/s2": "m/s^2", "°/s": "deg/s", "dps": "deg/s",
                 "Gauss": "G"}


def sniff(path: str | Path) -> bool:
    """A file (plain or gzipped) whose header is ``Time (s)``, ``Gyroscope X (..)`` ... ``Accelerometer X (..)``
    ...: that header says what it is whatever the file's extension (``.csv``, ``.txt``, ``.dat``).
    """
    try:
        p = Path(path)
        first = head(p).split(b"\n", 1)[0].decode("utf-8-sig", errors="replace").strip()
        fields = [f.strip() for f in first.split(",")]
        return (fields[0] == "Time (s)" and any(f.startswith("Gyroscope X (") for f in fields)
                and any(f.startswith("Accelerometer X (") for f in fields))
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return False


def _unit(raw: str) -> str:
    return _UNIT_ALIASES.get(raw.strip(), raw.strip())


def read(path: str | Path) -> Recording:
    """Read an x-io CSV (plain or .gz) into a foot :class:`Recording` (gyro rad/s, acc m/s^2)."""
    p = Path(path)
    source = str(p)
    text = read_text(p)
    warnings: list[str] = []
    table = parse_table(text, source, notes=warnings, terminated=True)
    if "Time (s)" not in table.header:
        raise InputError(f"no 'Time (s)' column (header has {list(table.header)})", source=source, line=1,
                         field="Time (s)")
    if len(table) == 0:
        raise InputError("no samples after the header", source=source, line=2)
    t_ns = timestamps_ns(table.column("Time (s)"), source, "Time (s)", scale=1e9)
    keep = keep_increasing(t_ns, source, "Time (s)", warnings, lines=table.lines())

    groups: dict[str, dict[str, tuple[str, str]]] = {}
    for col in table.header:
        m = _COLUMN.match(col)
        if not m:
            continue
        name, unit = m["name"], _unit(m["unit"])
        for prefix, (kind, _) in _SENSORS.items():
            axis = name[len(prefix):].strip()
            if name.startswith(prefix) and axis in ("X", "Y", "Z"):
                groups.setdefault(kind, {})[axis] = (col, unit)
        if name == "Barometer":
            groups["baro"] = {"p": (col, unit)}

    streams: dict[str, SensorStream] = {}
    for kind, axes in groups.items():
        units_of = PRESSURE_UNITS if kind == "baro" else next(u for k, u in _SENSORS.values() if k == kind)
        names = ("p",) if kind == "baro" else ("X", "Y", "Z")
        if set(axes) != set(names):
            raise InputError(f"incomplete {kind} columns: found axes {sorted(axes)}", source=source, line=1)
        units = {axes[a][1] for a in names}
        if len(units) != 1 or next(iter(units)) not in units_of:
            raise InputError(f"unknown or mixed unit(s) {sorted(units)} for {kind}; expected one of {list(units_of)}",
                             source=source, line=1, field=axes[names[0]][0])
        unit = next(iter(units))
        values = table.stack_scaled([axes[a][0] for a in names], units_of[unit], unit)
        streams[kind] = SensorStream(kind, t_ns[keep], values[keep])
    if "acc" not in streams or "gyro" not in streams:
        raise InputError("expected Gyroscope X/Y/Z and Accelerometer X/Y/Z columns with units in parentheses "
                         f"(header has {list(table.header)})", source=source, line=1)
    return Recording(streams, device=DeviceInfo(platform="imu", model="x-io Technologies IMU", role="right_foot",
                                                placement="foot"),
                     t0_ns=int(t_ns[0]), source=source, format=FORMAT, warnings=tuple(warnings),
                     meta={"foot_side": "unknown"})
