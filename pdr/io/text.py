"""Shared pieces of the text readers: opening plain/.gz/zip members, and numeric tables with line numbers.

Every reader goes through these so that bad input (binary garbage, a truncated line, text in a
numeric field) is reported the same way: an :class:`~pdr.errors.InputError` naming file, line and field.
"""

from __future__ import annotations

import gzip
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

#: Bytes read by :func:`head` for sniffing.
SNIFF_BYTES = 4096


def strip_gz(name: str) -> str:
    """File name without a trailing ``.gz``."""
    return name[:-3] if name.endswith(".gz") else name


def read_bytes(path: str | Path) -> bytes:
    """Whole content of a file, transparently gunzipped when it ends in ``.gz``."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror})", source=str(p)) from None
    if p.name.endswith(".gz") or raw[:2] == b"\x1f\x8b":
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError) as exc:
            raise InputError(f"corrupt gzip data ({exc})", source=str(p)) from None
    return raw


def decode_text(raw: bytes, source: str) -> str:
    """UTF-8 (with BOM) or Latin-1 text; binary content is rejected."""
    if b"\x00" in raw[:65536]:
        raise InputError("binary data where a text log was expected", source=source)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
        control = sum(1 for ch in text[:65536] if ord(ch) < 32 and ch not in "\r\n\t")
        if control > 0.01 * min(len(text), 65536):
            raise InputError("binary data where a text log was expected", source=source) from None
        return text


def read_text(path: str | Path) -> str:
    """Decoded text of a plain or ``.gz`` file."""
    return decode_text(read_bytes(path), str(path))


def head(path: str | Path, n: int = SNIFF_BYTES) -> bytes:
    """First ``n`` bytes of a file (gunzipped if ``.gz``); empty on any error. For sniffing only."""
    p = Path(path)
    try:
        if not p.is_file():
            return b""
        if p.name.endswith(".gz"):
            with gzip.open(p, "rb") as f:
                return f.read(n)
        with p.open("rb") as f:
            return f.read(n)
    except (OSError, EOFError):
        return b""


def find_member(folder: Path, name: str) -> Path | None:
    """``folder/name`` or ``folder/name.gz``, whichever exists."""
    for candidate in (folder / name, folder / (name + ".gz")):
        if candidate.is_file():
            return candidate
    return None


def parse_float_rows(rows: Sequence[Sequence[str]], line_numbers: Sequence[int], source: str,
                     columns: Sequence[str]) -> NDArray[np.float64]:
    """Convert string fields to an (N, len(columns)) float64 array.

    Raises :class:`InputError` naming the line and column of the first row with the wrong number of
    fields, a non-numeric field or a non-finite value.
    """
    ncol = len(columns)
    for row, line in zip(rows, line_numbers, strict=True):
        if len(row) != ncol:
            raise InputError(f"expected {ncol} fields ({', '.join(columns)}), found {len(row)}",
                             source=source, line=line)
    if not rows:
        return np.empty((0, ncol))
    try:
        arr = np.array(rows, dtype=np.float64)
    except ValueError:
        for row, line in zip(rows, line_numbers, strict=True):
            for value, col in zip(row, columns, strict=True):
                try:
                    float(value)
                except ValueError:
                    raise InputError(f"'{value.strip()[:40]}' is not a number", source=source, line=line,
                                     field=col) from None
        raise
    bad = ~np.isfinite(arr)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(f"value {arr[r, c]} is not finite", source=source, line=line_numbers[r],
                         field=columns[c])
    return arr


def check_increasing_rows(t: NDArray[np.generic], line_numbers: Sequence[int], source: str, field: str) -> None:
    """:class:`InputError` naming the line where timestamps stop strictly increasing."""
    if t.size > 1:
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            i = int(bad[0]) + 1
            what = "repeats" if t[i] == t[i - 1] else "goes backwards"
            raise InputError(f"time {what} ({t[i - 1]} then {t[i]})", source=source, line=line_numbers[i],
                             field=field)


#: Largest magnitude of an int64 nanosecond timestamp we accept (about 292 years from the epoch or boot).
MAX_ABS_NS = float(2**63 - 2**12)


def timestamps_ns(t: NDArray[np.float64], source: str, field: str, *, scale: float = 1.0, multiplier: int = 1,
                  line_numbers: Sequence[int] | None = None) -> NDArray[np.int64]:
    """``round(t * scale) * multiplier`` as int64 nanoseconds; :class:`InputError` for a time out of range.

    ``scale`` converts float units before rounding (1e9 for seconds), ``multiplier`` whole units after it
    (1_000_000 for integer milliseconds, exact). A timestamp far in the future or past (beyond int64
    nanoseconds) is reported with its line when ``line_numbers`` are given, never wrapped around.
    """
    r = np.round(np.asarray(t, dtype=np.float64) * scale)
    bad = ~(np.abs(r) * multiplier <= MAX_ABS_NS)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"time {t[i]!r} is out of range (beyond ±292 years as int64 nanoseconds)", source=source,
                         line=None if line_numbers is None else line_numbers[i], field=field)
    out: NDArray[np.int64] = r.astype(np.int64) * np.int64(multiplier)
    return out
