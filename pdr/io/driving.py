"""Driver Behavior Dataset trips (``driverBehaviorDataset``): a phone on a windscreen mount in a car.

A trip folder holds, each plain or ``.gz``:

``acelerometro_terra.csv``, ``aceleracaoLinear_terra.csv``, ``giroscopio_terra.csv``, ``campoMagnetico_terra.csv``
    header ``timestamp,uptimeNanos,x,y,z``; ``timestamp`` is a wall-clock string (ignored), ``uptimeNanos`` ns
    since boot (the time used). m/s^2 (accelerometer including gravity; linear acceleration without),
    rad/s, uT -> ``acc``, ``lin_acc``, ``gyro``, ``mag``. Any of them may be missing (not all of them).
``viagem.json``
    ``firstCollectionUptimeNanos`` (trip start, used as ``t0_ns``), ``lastCollectionUptimeNanos``,
    ``smartphoneModel``, ``androidVersion``.
``groundTruth.csv``
    ``evento, inicio, fim``: driving events with start/end in seconds from the trip start.

**Frame.** The ``_terra`` values were already rotated by the app into an Earth frame (z up: the accelerometer
reads about (0, 0, +9.8) m/s^2 whatever the mounting), not the device body frame the data model expects
elsewhere. The reader keeps them as they are, says so in :attr:`Recording.warnings` and sets
``meta["frame"] = "earth"``; consumers that need body-frame data must not use these streams as such.

Truth: the whole trip is one motion mode, ``vehicle`` (:attr:`GroundTruth.modes`, from the trip start to its
last collection). The driving events go into :attr:`GroundTruth.landmarks` as labelled intervals with English
names (:data:`EVENT_NAMES`; unknown names are kept verbatim), sorted by start time; the raw Portuguese
names are in ``meta["events_raw"]``.

Reading: a sensor file of the plain form (UTF-8, LF or CR LF line breaks, five fields on every non-blank line) is
parsed in one pass by pandas' C parser (:func:`_numbers_fast`, the values :func:`float` gives: the files' 16-17 digit
decimals need its exact converter); anything else, and every bad input, takes the line-by-line path
(:func:`_numbers_exact`), which names the line and field. Pandas is loaded only for a file of at least
:data:`PANDAS_MIN_BYTES` or when it is already loaded (its import costs about as much as the line-by-line path saves
on a whole trip).

Repeated timestamps: the magnetometer file of the upstream trips lists most samples twice with the same
``uptimeNanos`` and slightly different values (two rotations of one reading into the Earth frame). Rows that
share a timestamp are averaged into one sample, with a warning. A row going back in time is dropped with a warning
naming the line (:mod:`pdr.io.time_order`).
"""

from __future__ import annotations

import csv
import io
import sys
import warnings as warning_filters
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
    parse_float_rows,
    parse_json,
    read_bytes,
    read_text,
    strip_gz,
    timestamps_ns,
    utf8_lines,
)
from pdr.io.time_order import keep_increasing, keep_lines
from pdr.recording import DeviceInfo, GroundTruth, Labels, Recording, SensorStream

FORMAT = "driving"
DESCRIPTION = "driverBehaviorDataset car trip folder (*_terra.csv in an Earth frame, viagem.json, groundTruth.csv)"

#: File name -> stream kind.
SENSOR_FILES: dict[str, str] = {
    "acelerometro_terra.csv": "acc",
    "aceleracaoLinear_terra.csv": "lin_acc",
    "giroscopio_terra.csv": "gyro",
    "campoMagnetico_terra.csv": "mag",
}
HEADER = ("timestamp", "uptimeNanos", "x", "y", "z")
#: Portuguese event name of groundTruth.csv -> English landmark label.
EVENT_NAMES: dict[str, str] = {
    "evento_nao_agressivo": "non_aggressive_event",
    "curva_direita_agressiva": "aggressive_right_turn",
    "curva_esquerda_agressiva": "aggressive_left_turn",
    "troca_faixa_direita_agressiva": "aggressive_right_lane_change",
    "troca_faixa_esquerda_agressiva": "aggressive_left_lane_change",
    "freada_agressiva": "aggressive_braking",
    "aceleracao_agressiva": "aggressive_acceleration",
}
EARTH_FRAME_WARNING = ("values are in an Earth frame (already rotated by the app, z up), not the device body "
                       "frame")


def sniff(path: str | Path) -> bool:
    """True for a trip folder (with ``acelerometro_terra.csv``) or one of its ``*_terra.csv`` files."""
    p = Path(path)
    try:
        if p.is_dir():
            acc = find_member(p, "acelerometro_terra.csv")
            return acc is not None and _has_header(acc)
    except OSError:
        return False
    return strip_gz(p.name) in SENSOR_FILES and _has_header(p)


def near_miss(path: str | Path) -> str | None:
    """Why a folder that looks like a trip (its ``viagem.json``) is not read as one, or None: the accelerometer file
    that :func:`sniff` needs is missing or does not start with the trip files' header.
    """
    p = Path(path)
    if not p.is_dir() or find_member(p, "viagem.json") is None:
        return None
    acc = find_member(p, "acelerometro_terra.csv")
    if acc is not None:
        return None if _has_header(acc) else (
            f"a driverBehaviorDataset trip folder whose {acc.name} does not start with the header "
            f"{','.join(HEADER)}")
    others = [name for name in SENSOR_FILES if find_member(p, name) is not None]
    return ("a driverBehaviorDataset trip folder (viagem.json) without acelerometro_terra.csv, the accelerometer "
            "it is read from" + (f" (it has {', '.join(others)})" if others else "; it has no sensor file at all"))


def _has_header(p: Path) -> bool:
    first = head(p, 256).split(b"\n", 1)[0].strip()
    return tuple(f.strip() for f in first.decode("latin-1").split(",")) == HEADER


def read(path: str | Path) -> Recording:
    """Read a trip folder (or the folder of a given trip file); see the module docstring."""
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    warnings = [EARTH_FRAME_WARNING]
    streams: dict[str, SensorStream] = {}
    for name, kind in SENSOR_FILES.items():
        member = find_member(folder, name)
        if member is not None:
            streams[kind] = _read_sensor(member, kind, warnings)
    if not streams:
        raise InputError("no *_terra.csv sensor file (acelerometro_terra.csv, giroscopio_terra.csv, ...) in the "
                         "trip folder", source=str(folder))
    trip = _read_trip(folder)
    first = min(int(s.t_ns[0]) for s in streams.values())
    last = max(int(s.t_ns[-1]) for s in streams.values())
    meta: dict[str, Any] = {}
    if trip is None:
        warnings.append("no viagem.json: trip start taken as the first sample (event times may be offset)")
        t0_ns, end_ns, model = first, last, ""
    else:
        t0_ns = int(trip.get("firstCollectionUptimeNanos", first))
        end_ns = int(trip.get("lastCollectionUptimeNanos", last))
        model = str(trip.get("smartphoneModel", ""))
        meta["trip"] = {k: v for k, v in trip.items() if isinstance(v, (str, int, float))}
    end_s = max(end_ns, last) / 1e9 - t0_ns / 1e9
    start_s = min(0.0, (first - t0_ns) / 1e9)
    modes = Labels(np.array([start_s]), np.array([end_s]), ("vehicle",))
    landmarks, raw = _read_events(folder)
    meta.update({"frame": "earth", "trip_folder": folder.name, "events_raw": raw})
    device = DeviceInfo(platform="android", model=model, role="phone", placement="vehicle_mount")
    return Recording(streams=streams, device=device, t0_ns=t0_ns, truth=GroundTruth(modes=modes, landmarks=landmarks),
                     source=str(folder), format=FORMAT, warnings=tuple(warnings), meta=meta)


#: Size of a sensor file from which a process that has not loaded pandas yet parses it with pandas (module doc):
#: loading pandas costs about 0.5 s once, the line-by-line path about 50 ms/MB more than pandas' parser.
PANDAS_MIN_BYTES = 10_000_000
_COMMA = ord(",")


def _read_sensor(p: Path, kind: str, warnings: list[str]) -> SensorStream:
    source = str(p)
    raw = drop_cut_off_last_line(read_bytes(p), source, b",", warnings, terminated=True)
    fast = _numbers_fast(raw) if len(raw) >= PANDAS_MIN_BYTES or "pandas" in sys.modules else None
    arr, numbers = fast if fast is not None else _numbers_exact(raw, source)
    keep = keep_increasing(arr[:, 0], source, "uptimeNanos", warnings, lines=numbers, keep_repeats=True)
    if not keep.all():
        arr, numbers = arr[keep], keep_lines(numbers, keep)
    t_ns, values, merged = average_repeated_times(timestamps_ns(arr[:, 0], source, "uptimeNanos", line_numbers=numbers),
                                                      arr[:, 1:4])
    if merged:
        first = numbers[int(np.flatnonzero(np.diff(arr[:, 0]) == 0)[0]) + 1]
        warnings.append(f"{p.name}: averaged {merged} row(s) that repeat the previous timestamp into one sample "
                        f"each, first at line {first}")
    return SensorStream(kind, t_ns, values)


def _numbers_exact(raw: bytes, source: str) -> tuple[NDArray[np.float64], list[int]]:
    """(N, 4) uptimeNanos, x, y, z of a sensor file's non-blank rows and their 1-based line numbers, read line by
    line: :class:`InputError` naming the line (and field) of bad input.
    """
    lines = decode_text(raw, source).splitlines()
    if not lines or not lines[0].strip():
        raise InputError("empty file: no header line", source=source, line=1)
    if tuple(f.strip() for f in lines[0].split(",")) != HEADER:
        raise InputError(f"expected the header '{','.join(HEADER)}', found '{lines[0].strip()[:60]}'",
                         source=source, line=1)
    rows: list[list[str]] = []
    numbers: list[int] = []
    for number in range(2, len(lines) + 1):
        line = lines[number - 1]
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != len(HEADER):
            raise InputError(f"expected {len(HEADER)} fields ({', '.join(HEADER)}), found {len(fields)}",
                             source=source, line=number)
        rows.append(fields[1:])
        numbers.append(number)
    if not rows:
        raise InputError("no samples after the header", source=source)
    return parse_float_rows(rows, numbers, source, HEADER[1:]), numbers


def _numbers_fast(raw: bytes) -> tuple[NDArray[np.float64], list[int]] | None:
    """What :func:`_numbers_exact` returns, by pandas' C parser (module doc), or None when the file is not of the
    plain form or a value is not a finite number: the line-by-line path then reads it or names the bad line.
    """
    lines = utf8_lines(raw)
    if lines is None or lines.start.size < 2:
        return None
    if tuple(f.strip() for f in lines.text(0).decode("utf-8").split(",")) != HEADER:
        return None
    rows = np.flatnonzero(lines.length > 0)
    rows = rows[rows > 0]
    commas = np.bincount(np.searchsorted(lines.start, np.flatnonzero(lines.buf == _COMMA), side="right") - 1,
                         minlength=lines.start.size)
    if rows.size == 0 or np.any(commas[rows] != len(HEADER) - 1):
        return None         # a row with another number of fields, a blank-only line: the exact path decides
    import pandas as pd  # half a second of imports (module doc)

    from pdr.io.csvtable import float_precision_option
    body = lines.buf[lines.start[1]:].tobytes()
    try:
        with warning_filters.catch_warnings():
            warning_filters.simplefilter("error")
            frame = pd.read_csv(io.BytesIO(body), sep=",", header=None, usecols=[1, 2, 3, 4], dtype=np.float64,
                                engine="c", skip_blank_lines=True, na_filter=False, quoting=csv.QUOTE_NONE,
                                float_precision=float_precision_option(pd.__version__))
    except (ValueError, TypeError, OverflowError, Warning):   # pandas' ParserError is a ValueError
        return None
    arr = np.ascontiguousarray(frame.to_numpy(dtype=np.float64))
    if arr.shape != (rows.size, 4) or not np.all(np.isfinite(arr)):
        return None
    return arr, (rows + 1).tolist()


def average_repeated_times(t_ns: NDArray[np.int64], values: NDArray[np.float64]
                           ) -> tuple[NDArray[np.int64], NDArray[np.float64], int]:
    """Merge rows of a non-decreasing time series that share a timestamp into their mean.

    Returns the unique timestamps, the (M, k) averaged values and the number of rows merged away.
    """
    unique, first, counts = np.unique(t_ns, return_index=True, return_counts=True)
    if unique.size == t_ns.size:
        return t_ns, values, 0
    sums = np.add.reduceat(values, first, axis=0)
    return unique, sums / counts[:, None], int(t_ns.size - unique.size)


def _read_trip(folder: Path) -> dict[str, Any] | None:
    member = find_member(folder, "viagem.json")
    if member is None:
        return None
    trip = parse_json(read_text(member), str(member), "not valid JSON")
    if not isinstance(trip, dict):
        raise InputError("expected a JSON object", source=str(member))
    for key in ("firstCollectionUptimeNanos", "lastCollectionUptimeNanos"):
        if key in trip and (not isinstance(trip[key], int) or isinstance(trip[key], bool)):
            raise InputError(f"expected an integer, found {trip[key]!r}", source=str(member), field=key)
    return trip


def _read_events(folder: Path) -> tuple[Labels | None, list[str]]:
    member = find_member(folder, "groundTruth.csv")
    if member is None:
        return None, []
    source = str(member)
    lines = read_text(member).splitlines()
    names: list[str] = []
    rows: list[list[str]] = []
    numbers: list[int] = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = [f.strip() for f in line.split(",")]
        if len(fields) != 3:
            raise InputError(f"expected 3 fields (evento, inicio, fim), found {len(fields)}", source=source,
                             line=number)
        names.append(fields[0])
        rows.append(fields[1:])
        numbers.append(number)
    if not rows:
        return None, []
    times = parse_float_rows(rows, numbers, source, ("inicio", "fim"))
    bad = np.flatnonzero(times[:, 1] < times[:, 0])
    if bad.size:
        i = int(bad[0])
        raise InputError(f"event ends ({times[i, 1]}) before it starts ({times[i, 0]})", source=source,
                         line=numbers[i], field="fim")
    order = np.argsort(times[:, 0], kind="stable")
    labels = tuple(EVENT_NAMES.get(names[i], names[i]) for i in order)
    return Labels(times[order, 0], times[order, 1], labels), [names[i] for i in order]
