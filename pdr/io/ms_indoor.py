r"""Microsoft Indoor Location Competition 2.0 traces (``.txt`` / ``.txt.gz``), with ``TYPE_WAYPOINT`` truth.

Tab-separated, one record per line, ``#`` lines are metadata (``startTime``, ``SiteID``, ``FloorName``,
``Brand``, ``Model``, ``AndroidName``, sensor names, ``endTime``). Records read here:

``<unix_ms> TYPE_ACCELEROMETER|TYPE_GYROSCOPE|TYPE_MAGNETIC_FIELD x y z accuracy``
    m/s^2 (incl. gravity), rad/s, uT, Android device frame -> ``acc``, ``gyro``, ``mag``.
``<unix_ms> TYPE_ROTATION_VECTOR x y z accuracy``
    Android rotation vector -> ``orientation`` (``q_nb``, see :mod:`pdr.io.android`).
``<unix_ms> TYPE_*_UNCALIBRATED x y z bx by bz accuracy``
    the first three values -> ``acc_uncal``, ``gyro_uncal``, ``mag_uncal`` (biases are not kept).
``<unix_ms> TYPE_WAYPOINT x_m y_m``
    surveyor-labelled position on the floor map -> :class:`~pdr.recording.PositionTruth`
    (``kind="waypoint"``, ``frame="map"``, floor from ``FloorName``: ``F3`` -> 3, ``B1`` -> -1).

Other records (WiFi, beacons, ``TYPE_DIST1`` ...) are skipped and counted in ``meta["ignored_records"]``.

Time: ``t_ns`` are Unix-epoch nanoseconds (the trace's milliseconds times 10^6); ``t0_ns`` is the first
timestamp of any record read, so ``t_s`` starts near 0 and ``t0_ns / 1e9 + t_s`` is Unix time in
seconds (the reference scorer ``tools/ms_ref.py`` works on that Unix-seconds axis).

Defensive parsing (known quirks of the upstream traces):

* A line that lacks its newline runs into the next record (``...\t31574142012157\tTYPE_...``). It is split
  before every 13-digit timestamp followed by a ``TYPE_`` tag; a fragment that is still malformed
  after the split is dropped and reported in :attr:`Recording.warnings`.
* Repeated timestamps within one sensor: the first sample at a timestamp is kept and later ones, like those
  going back in time, are dropped with a warning naming the line (:mod:`pdr.io.time_order`), since a stream's
  timestamps must increase strictly.

Any other malformed line (wrong number of fields, text or NaN in a numeric field) raises
:class:`~pdr.errors.InputError` naming the file and line.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io.android import rotation_vector_to_q_nb
from pdr.io.text import (
    SNIFF_BYTES,
    decode_text,
    drop_cut_off_last_line,
    head,
    parse_float_rows,
    read_bytes,
    strip_gz,
    timestamps_ns,
    utf8_lines,
)
from pdr.io.time_order import keep_increasing, keep_lines
from pdr.recording import DeviceInfo, GroundTruth, PositionTruth, Recording, SensorStream

FORMAT = "ms_indoor"
DESCRIPTION = "Microsoft Indoor Location Competition 2.0 trace (.txt[.gz]), TYPE_WAYPOINT truth"

_XYZA = ("timestamp_ms", "x", "y", "z", "accuracy")
_UNCAL = ("timestamp_ms", "x", "y", "z", "bias_x", "bias_y", "bias_z", "accuracy")
#: Record type -> (stream kind, numeric field names, i.e. every field but the type tag).
SENSOR_RECORDS: dict[str, tuple[str, tuple[str, ...]]] = {
    "TYPE_ACCELEROMETER": ("acc", _XYZA),
    "TYPE_GYROSCOPE": ("gyro", _XYZA),
    "TYPE_MAGNETIC_FIELD": ("mag", _XYZA),
    "TYPE_ROTATION_VECTOR": ("orientation", _XYZA),
    "TYPE_ACCELEROMETER_UNCALIBRATED": ("acc_uncal", _UNCAL),
    "TYPE_GYROSCOPE_UNCALIBRATED": ("gyro_uncal", _UNCAL),
    "TYPE_MAGNETIC_FIELD_UNCALIBRATED": ("mag_uncal", _UNCAL),
}
WAYPOINT_FIELDS = ("timestamp_ms", "x_m", "y_m")

#: A record's start (a UTF-8 BOM before the first): tags such as ``TYPE_DIST1`` hold digits.
_RECORD = re.compile(rb"^(?:\xef\xbb\xbf)?\d{13}\tTYPE_[A-Z0-9_]+\t", re.MULTILINE)
#: A line of a trace's header (``#<TAB>startTime:...``, ``#<TAB>SiteID:...``).
_HEADER_LINE = re.compile(rb"^(?:\xef\xbb\xbf)?#\t(?:startTime|SiteID|Brand):", re.MULTILINE)
#: Where a run-on line must be cut: before a 13-digit Unix-ms timestamp followed by a record tag.
_RUN_ON_CUT = re.compile(r"(?<=.)(?=\d{13}\tTYPE_)")
#: The upstream dataset's folder layout: one trace per file, in its floor folder's ``path_data_files/`` (beside the
#: floor's plan: floor_info.json, geojson_map.json).
LAYOUT = "<site>/<floor>/path_data_files/<trace>.txt[.gz]"
TRACES_FOLDER = "path_data_files"
#: Levels below a folder searched for :data:`TRACES_FOLDER` (3 from the dataset's root) and sub-folders per level.
LAYOUT_DEPTH = 3
LAYOUT_LISTED = 50
_META_KEYS = ("startTime", "endTime", "SiteID", "SiteName", "FloorId", "FloorName", "Brand", "Model",
              "AndroidName", "APILevel", "VersionName")


def sniff(path: str | Path) -> bool:
    """True for a trace with a record ``<13-digit ms><TAB>TYPE_...<TAB>`` in its first bytes (one is enough)."""
    start = head(path)
    return _RECORD.search(start) is not None


def near_miss(path: str | Path) -> str | None:
    """Why a folder of the dataset above its traces (the root, a site or a floor folder: a ``path_data_files/`` with
    a trace one to :data:`LAYOUT_DEPTH` levels down) is not read as a trace, saying the layout, or why a file with a
    trace's header is not (no whole record in its first bytes: cut short); None otherwise.
    """
    p = Path(path)
    if p.is_file():
        start = head(p)
        if _HEADER_LINE.search(start) and not _RECORD.search(start):
            where = f"in its first {len(start)} bytes" if len(start) >= SNIFF_BYTES else "after it"
            return ("a Microsoft indoor-location trace (its header '#<TAB>startTime:...') without a whole record "
                    f"('<13-digit ms><TAB>TYPE_<NAME><TAB><values>') {where}: it needs at least one")
        return None
    trace = _trace_below(p) if p.is_dir() and p.name != TRACES_FOLDER else None
    return None if trace is None else _layout_message(p, trace)


def _layout_message(folder: Path, trace: Path | None) -> str:
    """Why a folder is not read as a trace, with the dataset's layout and a trace below it when there is one."""
    if trace is None:
        return f"a Microsoft indoor-location trace is a single .txt[.gz] file, not a folder (laid out as {LAYOUT})"
    return (f"a folder of the Microsoft indoor-location dataset, not one trace: its traces are {LAYOUT} "
            f"({trace.relative_to(folder)} here); give one trace file, or the folder to 'pdr eval ms'")


def _trace_below(folder: Path) -> Path | None:
    """The first trace (by name) of a ``path_data_files/`` that is ``folder`` or at most :data:`LAYOUT_DEPTH` levels
    below it (at most :data:`LAYOUT_LISTED` sub-folders looked at per level); None when there is none (never raises).
    """
    level = [folder]
    try:
        for _ in range(LAYOUT_DEPTH + 1):
            for d in level:
                if d.name == TRACES_FOLDER:
                    trace = next((f for f in sorted(d.iterdir()) if f.is_file() and sniff(f)), None)
                    if trace is not None:
                        return trace
            level = [c for d in level for c in sorted(d.iterdir()) if c.is_dir() and not c.name.startswith(".")]
            level = level[:LAYOUT_LISTED]
    except OSError:
        return None
    return None


def read(path: str | Path) -> Recording:
    """Read one Microsoft indoor-location trace; see the module docstring."""
    p = Path(path)
    if p.is_dir():
        raise InputError(_layout_message(p, _trace_below(p)), source=str(p))
    cut: list[str] = []
    raw = drop_cut_off_last_line(read_bytes(p), str(p), b"\t", cut, terminated=True)
    parsed = _parse_fast(raw)
    parsed = parsed if parsed is not None else _parse_exact(str(p), raw)
    parsed[3][:0] = cut
    return _assemble(p, parsed)


#: Per record tag: its (N, fields) numbers and the 1-based file line of every row.
_Rows = dict[str, tuple[NDArray[np.float64], list[int]]]


def _parse_exact(source: str, raw: bytes) -> tuple[_Rows, dict[str, int], dict[str, str], list[str]]:
    """The records read line by line: rows per tag, ignored record counts, ``#`` metadata and warnings.
    :class:`InputError` naming the line and field of anything malformed (module docstring).
    """
    wanted = (*SENSOR_RECORDS, "TYPE_WAYPOINT")
    rows: dict[str, list[list[str]]] = {tag: [] for tag in wanted}
    numbers: dict[str, list[int]] = {tag: [] for tag in wanted}
    ignored: dict[str, int] = {}
    meta_header: dict[str, str] = {}
    warnings: list[str] = []
    run_on_lines = 0
    dropped: list[int] = []
    for number, line in enumerate(decode_text(raw, source).splitlines(), start=1):
        if not line.strip():
            continue
        if line[0] == "#":
            _parse_meta(line, meta_header)
            continue
        pieces = [line]
        if line.count("\tTYPE_") > 1:
            pieces = _RUN_ON_CUT.split(line)
            run_on_lines += 1
        for k, piece in enumerate(pieces):
            fields = piece.rstrip("\t").split("\t")
            if len(fields) < 2:
                if len(pieces) > 1:
                    dropped.append(number)
                    continue
                raise InputError(f"expected '<unix_ms>\\t<TYPE_...>\\t...', found '{piece.strip()[:40]}'",
                                 source=source, line=number)
            tag = fields[1]
            if tag not in rows:
                ignored[tag] = ignored.get(tag, 0) + 1
                continue
            numeric = [fields[0], *fields[2:]]
            expected = len(_fields_of(tag))
            if len(pieces) > 1 and k < len(pieces) - 1 and not _is_clean(numeric, expected):
                dropped.append(number)  # the fragment that lost its end to the run-on
                continue
            rows[tag].append(numeric)
            numbers[tag].append(number)
    if run_on_lines:
        warnings.append(f"split {run_on_lines} line(s) that ran into the next record")
    if dropped:
        warnings.append(f"dropped {len(dropped)} malformed fragment(s) of run-on lines (lines "
                        f"{', '.join(str(n) for n in dropped[:10])}{', ...' if len(dropped) > 10 else ''})")
    arrays = {tag: (parse_float_rows(rows[tag], numbers[tag], source, _fields_of(tag)), numbers[tag])
              for tag in wanted if rows[tag]}
    return arrays, ignored, meta_header, warnings


def _fields_of(tag: str) -> tuple[str, ...]:
    return SENSOR_RECORDS[tag][1] if tag in SENSOR_RECORDS else WAYPOINT_FIELDS


def _parse_fast(raw: bytes) -> tuple[_Rows, dict[str, int], dict[str, str], list[str]] | None:
    """What :func:`_parse_exact` gives, by array operations on the bytes (:class:`~pdr.io.text.Lines`), or None.

    Records are told apart by the field between their first two tabs, the numbers parsed in one pass per record
    kind (:meth:`~pdr.io.text.Lines.numbers`). None for anything the exact path treats otherwise or refuses
    (text that is not UTF-8, unusual line breaks, run-on lines, a record not starting with a digit, a line
    without a tab, a bad number or field count): that path then reads it or names the line and field.
    """
    lines = utf8_lines(raw)
    if lines is None:
        return None
    buf, start, length = lines.buf, lines.start, lines.length
    end = start + length
    first = buf[start]                                      # the LF ending the previous line when a line is empty
    comment = (length > 0) & (first == ord("#"))
    record = np.flatnonzero((length > 0) & ~comment)
    if not np.all((buf[start[record]] >= ord("0")) & (buf[start[record]] <= ord("9"))):
        return None                                         # blank-looking or malformed lines: the exact path
    tabs = np.flatnonzero(buf == ord("\t"))
    k = np.searchsorted(tabs, start[record])
    last = np.append(tabs, buf.size)                        # a sentinel past every line
    t1 = last[k]                                            # the tab after the timestamp
    if np.any(t1 >= end[record]):
        return None                                         # a record without a tab: the exact path names it
    t2 = np.minimum(last[np.minimum(k + 1, tabs.size)], end[record])      # the tab (or line end) after the tag
    words = _words(buf)
    if _run_on(words, tabs, start[record], end[record]).any():
        return None
    pos, size = t1 + 1, t2 - t1 - 1                         # each record's tag: buf[pos:pos + size]
    arrays: _Rows = {}
    matched = np.zeros(record.size, bool)
    for name in (*SENSOR_RECORDS, "TYPE_WAYPOINT"):
        cand = np.flatnonzero(size == len(name))
        sel = cand[_equal(words, pos[cand], name.encode())]
        if not sel.size:
            continue
        matched[sel] = True
        rows = record[sel]
        ncol = len(_fields_of(name))
        t = lines.numbers(start[rows], t1[sel] - start[rows], 1, b"\t")
        v = lines.numbers(t2[sel] + 1, end[rows] - t2[sel] - 1, ncol - 1, b"\t", trailing_separator=True)
        if t is None or v is None:
            return None
        arrays[name] = (np.column_stack([t, v]), (rows + 1).tolist())
    ignored = _ignored_tags(buf, words, pos[~matched], size[~matched])
    if ignored is None:
        return None
    order = (*SENSOR_RECORDS, "TYPE_WAYPOINT")
    arrays = {tag: arrays[tag] for tag in order if tag in arrays}
    meta_header: dict[str, str] = {}
    for i in np.flatnonzero(comment).tolist():
        _parse_meta(lines.text(i).decode("utf-8"), meta_header)
    return arrays, ignored, meta_header, []


def _words(buf: NDArray[np.uint8]) -> NDArray[np.uint64]:
    """``words[i]``: the eight bytes ``buf[i:i + 8]`` (zeros past the end) as one little-endian uint64."""
    padded = np.concatenate([buf, np.zeros(8, np.uint8)])
    return np.ndarray((buf.size,), dtype="<u8", buffer=padded, strides=(1,))


def _low_bytes(n: NDArray[np.int64]) -> NDArray[np.uint64]:
    """Masks keeping the ``n`` (0..8) low bytes of a uint64."""
    return np.where(n >= 8, np.uint64(2**64 - 1), (np.uint64(1) << (np.uint64(8) * np.minimum(n, 7).astype(np.uint64)))
                    - np.uint64(1)).astype(np.uint64)


def _equal(words: NDArray[np.uint64], pos: NDArray[np.int64], text: bytes) -> NDArray[np.bool_]:
    """Per position: do the ``len(text)`` bytes from there equal ``text``? Eight bytes per comparison."""
    ok = np.ones(pos.size, bool)
    for j in range(0, len(text), 8):
        chunk = text[j:j + 8]
        mask = _low_bytes(np.array([len(chunk)]))[0]
        ok &= (words[pos + j] & mask) == np.uint64(int.from_bytes(chunk, "little"))
    return ok


def _ignored_tags(buf: NDArray[np.uint8], words: NDArray[np.uint64], pos: NDArray[np.int64],
                  size: NDArray[np.int64]) -> dict[str, int] | None:
    """Count per distinct tag ``buf[pos:pos + size]``, in the order of first appearance.

    Tags are grouped by their length and first and last eight bytes, longer ones checked byte by byte: None when
    two different tags share a group (the exact path counts them then).
    """
    first = words[pos] & _low_bytes(size)
    last = np.where(size > 8, words[np.maximum(pos + size - 8, 0)], np.uint64(0))
    key = np.column_stack([size.astype(np.uint64), first, last])
    _, first_at, inverse, counts = np.unique(key, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    out: dict[str, int] = {}
    for g in np.argsort(first_at, kind="stable").tolist():
        i = int(first_at[g])
        text = buf[pos[i]:pos[i] + size[i]].tobytes()
        if size[i] > 16 and not _equal(words, pos[inverse == g], text).all():
            return None
        out[text.decode("utf-8")] = int(counts[g])
    return out


def _run_on(words: NDArray[np.uint64], tabs: NDArray[np.int64], start: NDArray[np.int64],
            end: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Per line ``buf[start:end]``: does a tab followed by ``TYPE_`` occur in it more than once (a run-on line)?"""
    marker = tabs[(words[tabs] & np.uint64(2**48 - 1)) == np.uint64(int.from_bytes(b"\tTYPE_", "little"))]
    return np.asarray(np.searchsorted(marker, end) - np.searchsorted(marker, start) > 1)


def _assemble(p: Path, parsed: tuple[_Rows, dict[str, int], dict[str, str], list[str]]) -> Recording:
    """The recording of the parsed records (either path): streams, waypoint truth, metadata."""
    source = str(p)
    arrays, ignored, meta_header, warnings = parsed
    streams: dict[str, SensorStream] = {}
    for tag, (kind, _) in SENSOR_RECORDS.items():
        if tag not in arrays:
            continue
        arr, lines = _drop_repeated_times(*arrays[tag], source, tag, warnings)
        t_ns = timestamps_ns(arr[:, 0], source, "timestamp_ms", multiplier=1_000_000, line_numbers=lines)
        values = rotation_vector_to_q_nb(arr[:, 1:4]) if kind == "orientation" else arr[:, 1:4]
        streams[kind] = SensorStream(kind, t_ns, values)
    if not streams:
        raise InputError("no accelerometer, gyroscope, magnetometer or rotation-vector records: not a usable "
                         "indoor-location trace", source=source)
    firsts = [int(s.t_ns[0]) for s in streams.values()]
    truth = GroundTruth()
    if "TYPE_WAYPOINT" in arrays:
        wp, wp_lines = arrays["TYPE_WAYPOINT"]
        back = np.flatnonzero(np.diff(wp[:, 0]) < 0)
        if back.size:
            i = int(back[0]) + 1
            raise InputError(f"waypoint time goes backwards ({wp[i - 1, 0]:.0f} then {wp[i, 0]:.0f})",
                             source=source, line=wp_lines[i], field="timestamp_ms")
        wp_ns = timestamps_ns(wp[:, 0], source, "timestamp_ms", multiplier=1_000_000, line_numbers=wp_lines)
        firsts.append(int(wp_ns[0]))
    t0_ns = min(firsts)
    if "TYPE_WAYPOINT" in arrays:
        floor = floor_number(meta_header.get("FloorName", ""))
        truth = GroundTruth(positions=PositionTruth(
            t_s=(wp_ns - t0_ns) / 1e9, pos_m=np.column_stack([wp[:, 1:3], np.zeros(len(wp))]),
            floor=np.full(len(wp), floor), kind="waypoint", frame="map"))
    meta: dict[str, Any] = {
        "clock": "unix_epoch",
        "t0_unix_s": t0_ns / 1e9,
        "header": meta_header,
        "ignored_records": ignored,
        "file": strip_gz(p.name),
        "site_id": meta_header.get("SiteID", ""),
        "floor_name": meta_header.get("FloorName", ""),
    }
    device = DeviceInfo(platform="android", model=meta_header.get("Model", ""), role="phone", placement="hand")
    return Recording(streams=streams, device=device, t0_ns=t0_ns, truth=truth, source=source, format=FORMAT,
                     warnings=tuple(warnings), meta=meta)


def floor_number(name: str) -> float:
    """Floor number from a floor name: ``F3`` or ``3F`` -> 3, ``B1`` -> -1; NaN when not recognised."""
    m = re.fullmatch(r"\s*(?:F(\d+)|(\d+)F|B(\d+))\s*", name, flags=re.IGNORECASE)
    if m is None:
        return float("nan")
    if m.group(3) is not None:
        return -float(m.group(3))
    return float(m.group(1) or m.group(2))


def _parse_meta(line: str, out: dict[str, str]) -> None:
    for item in line.lstrip("#").split("\t"):
        key, sep, value = item.partition(":")
        key = key.strip()
        if sep and key in _META_KEYS and key not in out:
            out[key] = value.strip()


def _is_clean(numeric: list[str], expected: int) -> bool:
    if len(numeric) != expected:
        return False
    try:
        return all(np.isfinite(float(v)) for v in numeric)
    except ValueError:
        return False


def _drop_repeated_times(arr: NDArray[np.float64], lines: list[int], source: str, tag: str,
                         warnings: list[str]) -> tuple[NDArray[np.float64], list[int]]:
    """The samples whose time is strictly later than every earlier one (:mod:`pdr.io.time_order`: the first of a
    repeat kept, the others and those going back dropped with a warning naming the line).
    """
    keep = keep_increasing(arr[:, 0], source, "timestamp_ms", warnings, lines=lines, what=tag)
    return (arr, lines) if keep.all() else (arr[keep], keep_lines(lines, keep))
