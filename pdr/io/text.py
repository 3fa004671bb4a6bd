"""Shared pieces of the text readers: opening plain/.gz/zip members, and numeric tables with line numbers.

Every reader goes through these so that bad input (binary garbage, a truncated line, text in a
numeric field) is reported the same way: an :class:`~pdr.errors.InputError` naming file, line and field.
"""

from __future__ import annotations

import gzip
import io
import json
import mmap
import re
import stat
import warnings as warning_filters
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, AnyStr

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io import notices
from pdr.io.gz import GZIP_MAGIC, decompressed_prefix, gunzip
from pdr.io.time_order import file_name

#: Bytes read by :func:`head` for sniffing.
SNIFF_BYTES = 4096


def strip_gz(name: str) -> str:
    """File name without a trailing ``.gz``."""
    return name[:-3] if name.endswith(".gz") else name


def read_bytes(path: str | Path) -> bytes:
    """Whole content of a file, transparently gunzipped (:func:`pdr.io.gz.gunzip`) when it ends in ``.gz`` or starts
    with gzip's magic bytes.
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror})", source=str(p)) from None
    if p.name.endswith(".gz") or raw[:2] == GZIP_MAGIC:
        raw = gunzip(raw, str(p))
    return raw


def mapped_text(path: str | Path) -> mmap.mmap | None:
    """The bytes of a plain (not gzip-compressed) file that ends with a line break, mapped read-only, or None (a
    ``.gz`` name or gzip's magic bytes, an empty file, a last line without a line break, a file that cannot be mapped:
    :func:`read_bytes` reads those). A mapped file's pages are the operating system's cached pages: nothing is
    copied into fresh memory, which the process would fault in and zero page by page (a 49 MB log: about 12 000
    pages, 28 ms of CPU for :func:`read_bytes` and the checks of its bytes against 9 ms mapped). A file cut shorter
    by another process while it is mapped ends the process (SIGBUS) where a read would have seen the shorter file: a
    log is not rewritten while it is read.
    """
    p = Path(path)
    if p.name.endswith(".gz"):
        return None
    try:
        with p.open("rb") as f:
            mapped = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    except (OSError, ValueError):       # ValueError: an empty file
        return None
    if mapped[:2] == GZIP_MAGIC or mapped[-1:] not in (b"\n", b"\r"):
        mapped.close()
        return None
    return mapped


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


def parse_json(text: str, source: str, what: str = "invalid JSON") -> Any:
    """The JSON document ``text``; :class:`InputError` naming ``source`` (and the line) when it is not one, including
    an integer of more digits than Python converts (4300) and arrays or objects nested deeper than its recursion.
    """
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{what}: {exc.msg}", source=source, line=exc.lineno) from None
    except ValueError as exc:       # an integer of more than 4300 digits
        raise InputError(f"{what}: {exc}", source=source) from None
    except RecursionError:
        raise InputError(f"{what}: arrays or objects nested too deeply", source=source) from None


def read_text(path: str | Path) -> str:
    """Decoded text of a plain or ``.gz`` file."""
    return decode_text(read_bytes(path), str(path))


def head(path: str | Path, n: int = SNIFF_BYTES) -> bytes:
    """First ``n`` bytes of a file, gunzipped as :func:`read_bytes` does (named ``.gz`` or starting with gzip's
    magic bytes: a trace saved without its ``.gz``; a gzip cut short shows what decompresses); empty on any error and
    for a zip archive (whose stored members would otherwise show their text to a text reader's sniffer: a zip is read
    from its members). For sniffing only.
    """
    p = Path(path)
    try:
        if not p.is_file():
            return b""
        with p.open("rb") as f:
            start = f.read(n)
        if p.name.endswith(".gz") or start[:2] == GZIP_MAGIC:
            try:
                with gzip.open(p, "rb") as f:
                    return f.read(n)
            except EOFError:
                return decompressed_prefix(p.read_bytes(), n)
        return b"" if start.startswith(b"PK\x03\x04") else start
    except (OSError, EOFError, zlib.error):
        return b""


def find_member(folder: Path, name: str) -> Path | None:
    """``folder/name`` or ``folder/name.gz``, whichever is a file (:func:`is_member_file`)."""
    for candidate in (folder / name, folder / (name + ".gz")):
        if is_member_file(candidate):
            return candidate
    return None


def is_member_file(path: Path) -> bool:
    """Whether a folder's member ``path`` is a file (or a link to one) a reader may open. Anything else of that name
    (a folder, a named pipe, a socket or device, a symbolic link that loops or leads nowhere) is not read, with a
    notice naming it (:func:`pdr.io.notices.note`); an absent name is just absent.
    """
    if path.is_file():
        return True
    what = not_a_file(path)
    if what is not None:
        notices.note(f"{path.name}: not read: {what}")
    return False


def not_a_file(path: Path) -> str | None:
    """What ``path`` is when it is there but is no regular file (``a folder, not a file``, ...); None for a file or
    nothing at all. Never raises, never opens it (a named pipe would wait for a writer).
    """
    try:
        mode = path.lstat().st_mode
        if stat.S_ISLNK(mode):
            mode = path.stat().st_mode
    except OSError:  # absent, or a link that loops or leads nowhere
        return "a symbolic link that leads nowhere (a loop, or its target is missing)" if path.is_symlink() else None
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder, not a file"
    if stat.S_ISFIFO(mode):
        return "a named pipe (FIFO), not a file"
    return "a socket or device, not a file"


#: Line breaks of :meth:`str.splitlines` other than LF and CR LF (the ASCII ones; non-ASCII text takes the exact path).
_UNUSUAL_BREAKS = (b"\r", b"\x0b", b"\x0c", b"\x1c", b"\x1d", b"\x1e")
_NEWLINE = 10


#: Bytes of the plain decimals :meth:`Lines.fields` hands to numpy's text reader (and the LF ending each line).
_PLAIN_DECIMAL_BYTE = np.zeros(256, dtype=bool)
_PLAIN_DECIMAL_BYTE[np.frombuffer(b"0123456789.-+eE\n", np.uint8)] = True


#: Ranges :meth:`Lines.numbers` converts with numpy before it leaves a text to the line-by-line path (or 2 %).
MAX_EXACT_ROWS = 64


@dataclass(frozen=True)
class Lines:
    """The lines of an ASCII text as byte offsets, for readers that classify and parse lines with array operations.

    ``buf`` holds the text (CR LF made LF), a LF ending its last line; line ``i`` (0-based) is
    ``buf[start[i]:start[i] + length[i]]``: these are the lines :meth:`str.splitlines` finds in the decoded text.
    """

    buf: NDArray[np.uint8]
    start: NDArray[np.int64]
    length: NDArray[np.int64]

    def head_code(self) -> tuple[NDArray[np.uint32], NDArray[np.uint8]]:
        """The first four bytes of every line as a little-endian uint32 (bytes past a line's end zero) and the
        fifth byte (zero past the end): a record tag and its separator, compared with one integer per line.
        """
        # Unaligned little-endian words read in place: a padded copy of a long text costs more than its lines' tags.
        n = self.buf.size
        words = np.ndarray((max(n - 3, 0),), dtype="<u4", buffer=self.buf, strides=(1,))
        late = self.start > n - 4                       # a word from here would run past the end: short lines
        code = words[np.where(late, 0, self.start)] if n >= 4 else np.zeros(self.start.size, np.uint32)
        for i in np.flatnonzero(late).tolist():
            code[i] = int.from_bytes(self.text(i)[:4], "little")
        short = self.length < 4
        if short.any():
            keep = np.where(self.length[short] > 0, (1 << (8 * np.minimum(self.length[short], 4))) - 1, 0)
            code[short] &= keep.astype(np.uint32)
        fifth = self.buf[np.minimum(self.start + 4, n - 1)] if n else np.zeros(0, np.uint8)
        fifth[self.length < 5] = 0
        return code, fifth

    def text(self, i: int) -> bytes:
        """Line ``i`` as bytes."""
        a = int(self.start[i])
        return self.buf[a:a + int(self.length[i])].tobytes()

    def numbers(self, start: NDArray[np.int64], length: NDArray[np.int64], ncol: int, sep: bytes, *,
                trailing_separator: bool = False) -> NDArray[np.float64] | None:
        """(N, ncol) float64 of the ``sep``-separated numbers in the byte ranges ``buf[start:start + length]``.

        Plain decimals go through the compiled one-pass parser (:mod:`pdr.io.decimal_kernel`); a range it does
        not take (an exponent, more than 15 digits, ...) is converted by numpy from its text, as
        :func:`parse_float_rows` converts it. None when a range has the wrong number of fields, a field is not a
        number or a value is not finite: the caller's line-by-line path names the line and field. None too when
        more than :data:`MAX_EXACT_ROWS` or 2 % of the ranges need numpy: that path is as fast then.
        """
        from pdr.io.decimal_kernel import parse_lines
        out = np.empty((start.size, ncol))
        if np.any(length < 0):
            return None
        done = 0
        budget = max(MAX_EXACT_ROWS, start.size // 50)
        while done < start.size:
            bad = parse_lines(self.buf, start[done:], length[done:], ncol, trailing_separator, sep[0], out[done:])
            if bad < 0:
                break
            i = done + bad
            budget -= 1
            if budget < 0:
                return None         # mostly out of the kernel's form: the line-by-line path is as fast
            text = self.buf[start[i]:start[i] + length[i]].tobytes().decode("utf-8")
            if trailing_separator and text.endswith(sep.decode()):
                text = text[:-1]
            parts = text.split(sep.decode())
            if len(parts) != ncol:
                return None
            try:
                row = np.array(parts, dtype=np.float64)
            except ValueError:
                return None
            if not np.all(np.isfinite(row)):
                return None
            out[i] = row
            done = i + 1
        return out

    def fields(self, mask: NDArray[np.bool_], ncol: int, skip_bytes: int = 0, sep: bytes = b";", *,
               trailing_separator: bool = False, compiled: bool = True) -> NDArray[np.float64] | None:
        """(N, ncol) float64 of the ``sep``-separated plain decimals of the selected lines after their first
        ``skip_bytes`` bytes (:func:`pdr.io.decimal_kernel.parse_lines`: the values :func:`float` gives), or None
        when a line is not of that form: the caller's line-by-line path then reads it or names the line and field.

        ``compiled=False`` parses with numpy's C text reader instead (:meth:`_fields_loadtxt`, the same values),
        for a process that has not loaded numba and reads a short text (loading the compiler costs more).
        """
        rows = np.flatnonzero(mask)
        if np.any(self.length[rows] < skip_bytes):
            return None
        if not compiled:
            return self._fields_loadtxt(rows, ncol, skip_bytes, sep, trailing_separator)
        from pdr.io.decimal_kernel import parse_lines
        out = np.empty((rows.size, ncol))
        bad = parse_lines(self.buf, self.start[rows] + skip_bytes, self.length[rows] - skip_bytes, ncol,
                          trailing_separator, sep[0], out)
        return out if bad < 0 else None

    def _fields_loadtxt(self, rows: NDArray[np.int64], ncol: int, skip_bytes: int, sep: bytes,
                        trailing_separator: bool) -> NDArray[np.float64] | None:
        """:meth:`fields` of the lines ``rows`` by :func:`numpy.loadtxt` (correctly rounded: the values of
        :func:`float`). Only lines of signs, digits, points, exponents and separators with ``ncol`` fields (one
        trailing separator allowed with ``trailing_separator``) are taken, so that every text it accepts the
        line-by-line path accepts with the same values; None otherwise.
        """
        if rows.size == 0:
            return np.empty((0, ncol))
        start = self.start[rows] + skip_bytes
        length = self.length[rows] - skip_bytes
        seg = length + 1                                   # each line with the LF after it (buf has one)
        ends = np.cumsum(seg)
        body = self.buf[np.arange(int(ends[-1])) + np.repeat(start - (ends - seg), seg)]
        if not np.all(_PLAIN_DECIMAL_BYTE[body] | (body == sep[0])):
            return None
        at_sep = np.flatnonzero(body == sep[0])
        count = np.bincount(np.searchsorted(ends, at_sep, side="right"), minlength=rows.size)
        ok = count == ncol - 1
        if trailing_separator:
            ok |= (count == ncol) & (length > 0) & (self.buf[start + length - 1] == sep[0])
        if not ok.all():
            return None
        text = body.tobytes().decode("ascii")
        try:
            with warning_filters.catch_warnings():
                warning_filters.simplefilter("error")
                out = np.loadtxt(io.StringIO(text), delimiter=sep.decode("ascii"), comments=None, quotechar=None,
                                 dtype=np.float64, ndmin=2, usecols=range(ncol))
        except (ValueError, Warning):
            return None
        if out.shape != (rows.size, ncol) or not np.all(np.isfinite(out)):
            return None
        return out


def ascii_lines(raw: bytes) -> Lines | None:
    """The :class:`Lines` of ``raw``, or None when the exact line-by-line path must read it.

    None for anything :func:`decode_text` and :meth:`str.splitlines` would treat otherwise: non-ASCII bytes (a
    BOM, Latin-1 or UTF-8 text), NUL bytes, other line breaks (a lone CR, form feed, ...).
    """
    if not raw.isascii() or b"\x00" in raw:
        return None
    return _split_lines(raw)


def _split_lines(raw: bytes) -> Lines | None:
    """:class:`Lines` of a text without NUL bytes whose only line breaks are LF and CR LF (else None)."""
    if b"\r" in raw:
        raw = raw.replace(b"\r\n", b"\n")
    if any(c in raw for c in _UNUSUAL_BREAKS):
        return None
    if raw and not raw.endswith(b"\n"):
        raw += b"\n"
    # A read-only view of the bytes: a copy of a log of tens of MB costs more than finding its lines.
    buf = np.frombuffer(raw, np.uint8)
    newline = newline_offsets(buf)
    start = np.concatenate([np.zeros(min(newline.size, 1), np.int64), newline[:-1] + 1])
    return Lines(buf, start, newline - start)


#: Bytes per block of :func:`newline_offsets`: the block's comparison stays in the cache instead of a mask of the
#: whole text.
_NEWLINE_BLOCK = 1 << 20


def newline_offsets(buf: NDArray[np.uint8]) -> NDArray[np.int64]:
    """Indices (int64, increasing) of the LF bytes of ``buf``."""
    blocks = [np.flatnonzero(buf[a:a + _NEWLINE_BLOCK] == _NEWLINE) + a for a in range(0, buf.size, _NEWLINE_BLOCK)]
    return np.concatenate(blocks).astype(np.int64, copy=False) if blocks else np.zeros(0, np.int64)


#: UTF-8 encodings of the line breaks of :meth:`str.splitlines` beyond ASCII (NEL, LINE and PARAGRAPH SEPARATOR).
_UNICODE_BREAKS = (b"\xc2\x85", b"\xe2\x80\xa8", b"\xe2\x80\xa9")
_BOM = b"\xef\xbb\xbf"


def utf8_lines(raw: bytes) -> Lines | None:
    """The :class:`Lines` of a UTF-8 text (a BOM dropped) whose lines are those :func:`decode_text` and
    :meth:`str.splitlines` give, or None when the exact line-by-line path must read it: text that is not UTF-8
    (:func:`decode_text` then takes it as Latin-1), NUL bytes, line breaks other than LF and CR LF.
    """
    if raw.isascii():
        return ascii_lines(raw)
    if raw.startswith(_BOM):
        raw = raw[len(_BOM):]
    if b"\x00" in raw or any(c in raw for c in _UNICODE_BREAKS):
        return None
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return None
    return _split_lines(raw)


def numeric_rows(raw: bytes, ncol: int, sep: bytes = b",", *, skip_lines: int = 0
                 ) -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """(N, ncol) numbers of the non-empty lines (after the first ``skip_lines``) of a text of ``sep``-separated
    numbers and their 1-based line numbers, by :meth:`Lines.numbers`: the values :func:`parse_float_rows` gives
    for the fields ``str.split`` cuts. None when a reader's line-by-line path must read the text (see
    :func:`utf8_lines`, :meth:`Lines.numbers`).
    """
    lines = utf8_lines(raw)
    if lines is None:
        return None
    rows = np.flatnonzero(lines.length > 0)
    rows = rows[rows >= skip_lines]
    arr = lines.numbers(lines.start[rows], lines.length[rows], ncol, sep)
    return None if arr is None else (arr, rows + 1)


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


def drop_cut_off_last_line(text: AnyStr, source: str, sep: AnyStr | None, warnings: list[str], *,
                           terminated: bool = False, value_form: re.Pattern[AnyStr] | None = None) -> AnyStr:
    """``text`` without its last line when a phone cut the log off mid-line: the text does not end with a line
    break and its last line has fewer ``sep``-separated fields (whitespace-separated for None) than the line before.
    With ``terminated`` (the writer ends every record with a line break), a last line without one is cut off even
    when it has all its fields: its last value may be a shorter number than was written. With ``value_form`` (the
    writer's fixed form of every value, for a writer that may leave the last line without a line break), it is cut
    off when its last value does not have that form and the line before's does. The line is reported in
    ``warnings`` with file and line number; any other text is returned as it is.
    """
    if isinstance(text, str):
        newline, ends = "\n", ("\n", "\r")
    else:
        newline, ends = b"\n", (b"\n", b"\r")
    if not text or text.endswith(ends):
        return text
    head, nl, last = text.rpartition(newline)
    prev = head.rstrip().rpartition(newline)[2]
    if not nl or not prev.strip():
        return text
    fields, expected = len(last.split(sep)), len(prev.split(sep))
    line = text.count(newline) + 1
    if fields < expected:
        why = f"{fields} of {expected} fields"
    elif terminated and last.strip():
        why = "no line break after its last value, which may be cut short"
    elif value_form is not None and _cut_value(last, prev, sep, value_form):
        why = f"no line break after its last value {last.split(sep)[-1].strip()!r}, which is cut short"
    else:
        return text
    warnings.append(f"{file_name(source)}: dropped the cut-off last line {line} ({why}): the log ends mid-line")
    return head + nl


def _cut_value(last: AnyStr, prev: AnyStr, sep: AnyStr | None, form: re.Pattern[AnyStr]) -> bool:
    """Whether the last value of line ``last`` lacks the writer's ``form`` that the last value of ``prev`` has."""
    value, before = last.split(sep)[-1].strip(), prev.split(sep)[-1].strip()
    return form.fullmatch(before) is not None and form.fullmatch(value) is None


#: Largest magnitude of an int64 nanosecond timestamp we accept (about 292 years from the epoch or boot).
MAX_ABS_NS = float(2**63 - 2**12)


def timestamps_ns(t: NDArray[np.float64], source: str, field: str, *, scale: float = 1.0, multiplier: int = 1,
                  line_numbers: Sequence[int] | NDArray[np.int64] | None = None) -> NDArray[np.int64]:
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
                         line=None if line_numbers is None else int(line_numbers[i]), field=field)
    out: NDArray[np.int64] = r.astype(np.int64) * np.int64(multiplier)
    return out
