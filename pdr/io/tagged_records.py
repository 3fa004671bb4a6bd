"""One compiled pass over a text log of tagged records (``TAG;field;field;...``, GetSensorData's form): the lines
found, their tags told apart and the numbers of the wanted tags parsed, in one kernel call (:func:`scan_tagged`).

The array path of :mod:`pdr.io.ipin` (:func:`pdr.io.ipin._read_text_arrays`) does this with numpy over every line:
the line ends, the first four and the fifth byte of each line, a mask per tag and per kind, then per tag a gather of
the line offsets and a call of the number parser, with tens of MB of temporary arrays whose pages the process faults
in. Here only the line ends come from numpy; each line is then looked at once, by its tag or by the number parser
(:func:`pdr.io.decimal_kernel.parse_row`, the same values), and each tag's numbers land in one block of a buffer. On
the one-hour IPIN bench log (49 MB, 792 000 lines), the whole text path of the reader (file read apart, recording
assembled) took 0.212 s of CPU by the array path and 0.137 s by this one (least of 8 runs each, interleaved).

Every line is one of: a record of a wanted tag (its fields parsed into that tag's rows), a record of another
four-letter-or-digit tag (counted per tag, with its first line), or an "extra" line (a ``%`` comment, a blank line,
a record of a tag of another length, anything else) whose offsets are returned for the caller to judge. The kernel
stops (and the caller takes its other paths) at a byte that is not ASCII, a NUL byte, a line break other than LF (a CR,
VT, FF, FS, GS or RS byte anywhere), at a record of a wanted tag whose fields are not plain decimals, and when its
tables are full. So it takes a text as it is, a file mapped in memory too (:func:`pdr.io.text.mapped_text`), without a
pass of its own over the bytes to check them first.
"""

from __future__ import annotations

import mmap
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel
from pdr.io.decimal_kernel import parse_row, powers_of_ten
from pdr.io.text import newline_offsets

_NEWLINE, _SEMICOLON = 10, 59
#: Line breaks of :meth:`str.splitlines` other than LF among the ASCII bytes (CR, VT, FF, FS, GS, RS).
_CR, _VT, _FF, _FS, _GS, _RS = 13, 11, 12, 28, 29, 30
#: Distinct other tags, and extra lines, that the kernel's tables hold.
MAX_OTHER_TAGS = 64
MAX_EXTRA_LINES = 4096
#: Kernel outcomes besides -1 (done): a line it does not take, a wanted tag with more records than its rows.
STOPPED, FULL = 0, 1


@dataclass(frozen=True)
class TaggedRecords:
    """What :func:`scan_tagged` found.

    ``values[k]``: (N_k, ncol_k) numbers of the records of wanted tag ``k``, ``lines[k]``: their 1-based line numbers;
    ``others``: (first line index, tag, count) of every other four-character tag; ``extra``: (line index, bytes) of
    every extra line, in file order (line indices 0-based).
    """

    values: list[NDArray[np.float64]]
    lines: list[NDArray[np.int64]]
    others: list[tuple[int, str, int]]
    extra: list[tuple[int, bytes]]


def tag_code(tag: str) -> int:
    """A four-character tag's ASCII bytes as a little-endian integer (the first four bytes of its lines)."""
    return int.from_bytes(tag.encode("ascii"), "little")


def scan_tagged(raw: bytes | mmap.mmap, tags: tuple[str, ...], ncols: tuple[int, ...], sep: bytes = b";"
                ) -> TaggedRecords | None:
    """The records of the text ``raw`` (bytes, or a file mapped in memory) of the four-character ``tags``
    (``ncols[k]`` fields after the tag, one trailing separator allowed), or None when the kernel stops (module doc).
    """
    buf = np.frombuffer(raw, np.uint8)
    ends = newline_offsets(buf)
    if len(raw) and raw[-1:] != b"\n":
        ends = np.append(ends, len(raw))           # a last line without a line break
    codes = np.array([tag_code(t) for t in tags], dtype=np.int64)
    widths = np.array(ncols, dtype=np.int64)
    caps = _first_guess(buf, ends, codes)
    while True:
        # One buffer of numbers and one of line numbers, a block of caps[k] rows per tag.
        base = np.concatenate([[0], np.cumsum(widths * caps)])
        line_base = np.concatenate([[0], np.cumsum(caps)])
        values = np.empty(int(base[-1]))
        lines = np.empty(int(line_base[-1]), dtype=np.int64)
        other = np.empty((MAX_OTHER_TAGS, 3), dtype=np.int64)
        extra = np.empty((MAX_EXTRA_LINES, 3), dtype=np.int64)
        counts = np.zeros(len(tags) + 2, dtype=np.int64)
        status = scan_records(buf, ends, codes, widths, sep[0], values, base, lines, line_base, caps, other, extra,
                              counts)
        if status != FULL:
            break
        caps = count_records(buf, ends, codes)        # a guess too short: the exact counts, and again
    if status != -1:
        return None
    n = counts[:len(tags)].tolist()
    n_other, n_extra = int(counts[-2]), int(counts[-1])
    return TaggedRecords(
        values=[values[base[k]:base[k] + n[k] * ncols[k]].reshape(n[k], ncols[k]) for k in range(len(tags))],
        lines=[lines[line_base[k]:line_base[k] + n[k]] for k in range(len(tags))],
        others=[(int(first), int(code).to_bytes(4, "little").decode("ascii"), int(count))
                for code, first, count in other[:n_other].tolist()],
        extra=[(int(i), raw[a:a + length]) for i, a, length in extra[:n_extra].tolist()])


#: Lines whose tags :func:`_first_guess` counts, the margin it adds to the counts it extrapolates from them, and the
#: lines per row it adds for every tag.
GUESS_LINES = 4096
GUESS_MARGIN = 1.25
GUESS_RARE = 128


def _first_guess(buf: NDArray[np.uint8], ends: NDArray[np.int64], codes: NDArray[np.int64]) -> NDArray[np.int64]:
    """Rows to make for each tag: the records of each tag among the first :data:`GUESS_LINES` lines, scaled to all
    lines with a margin (:data:`GUESS_MARGIN`), and one row per :data:`GUESS_RARE` lines more (a rare tag, such as
    the landmarks, may have none among the first lines); the exact counts for a short text. A guess too short costs
    a second pass; one too long only address space, whose pages are never touched.
    """
    if ends.size <= GUESS_LINES:
        return count_records(buf, ends, codes)
    seen = count_records(buf, ends[:GUESS_LINES], codes)
    return (seen * (GUESS_MARGIN * ends.size / GUESS_LINES)).astype(np.int64) + ends.size // GUESS_RARE + 64


@kernel
def _plain_line(buf: NDArray[np.uint8], p: int, end: int) -> bool:  # pragma: no cover - compiled
    """Whether ``buf[p:end]`` is ASCII without NUL bytes and holds none of the line breaks other than LF (module
    doc).
    """
    for j in range(p, end):
        c = buf[j]
        if c >= 128 or (c < 32 and (c == 0 or c == _CR or c == _VT or c == _FF or c == _FS or c == _GS or c == _RS)):
            return False
    return True


@kernel
def _tag_of(buf: NDArray[np.uint8], p: int, length: int,
            codes: NDArray[np.int64]) -> tuple[int, int]:  # pragma: no cover - compiled
    """(index in ``codes`` or -1, the four-byte code) of the line ``buf[p:p + length]``: -2 when it is no record
    with a four-byte tag (shorter than five bytes, or no separator after four bytes).
    """
    if length < 5 or buf[p + 4] != _SEMICOLON:
        return -2, 0
    word = int(buf[p]) | (int(buf[p + 1]) << 8) | (int(buf[p + 2]) << 16) | (int(buf[p + 3]) << 24)
    for k in range(codes.size):
        if codes[k] == word:
            return k, word
    return -1, word


@kernel
def _alnum4(buf: NDArray[np.uint8], p: int) -> bool:  # pragma: no cover - compiled
    """Whether the four bytes from ``p`` are ASCII letters or digits."""
    for j in range(4):
        c = buf[p + j]
        low = c | 0x20
        if not ((48 <= c <= 57) or (97 <= low <= 122)):
            return False
    return True


@kernel
def scan_records(buf: NDArray[np.uint8], ends: NDArray[np.int64], codes: NDArray[np.int64],
                 ncols: NDArray[np.int64], sep: int, values: NDArray[np.float64], base: NDArray[np.int64],
                 lines: NDArray[np.int64], line_base: NDArray[np.int64], caps: NDArray[np.int64],
                 other: NDArray[np.int64], extra: NDArray[np.int64],
                 counts: NDArray[np.int64]) -> int:  # pragma: no cover - compiled
    """Sort every line of ``buf`` (line ``i`` ends at ``ends[i]``; module doc): the records of tag ``codes[k]`` parsed
    into rows of ``ncols[k]`` numbers from ``values[base[k]]`` on (file order, at most ``caps[k]`` rows) with their
    line numbers from ``lines[line_base[k]]`` on; other four-character tags as (code, first line, count) rows of
    ``other``; extra lines as (line, start, length) rows of ``extra``. ``counts``: the rows of each tag, then of
    ``other`` and of ``extra``. Returns -1, :data:`STOPPED` or :data:`FULL`.
    """
    pow10 = powers_of_ten()
    ntag = codes.size
    p = 0
    for line in range(ends.size):
        q = ends[line]
        length = q - p
        k, word = _tag_of(buf, p, length, codes)
        if k >= 0:
            r = counts[k]
            if r >= caps[k]:
                return FULL
            # The fields' bytes are digits, signs, points, exponents, blanks and separators, or the parse stops.
            if not parse_row(buf, p + 5, q, ncols[k], True, sep, pow10, values, base[k] + r * ncols[k]):
                return STOPPED
            lines[line_base[k] + r] = line + 1
            counts[k] = r + 1
        elif not _plain_line(buf, p, q):
            return STOPPED
        elif k == -1 and _alnum4(buf, p):
            j = 0
            while j < counts[ntag] and other[j, 0] != word:
                j += 1
            if j == counts[ntag]:
                if j == other.shape[0]:
                    return STOPPED
                other[j, 0], other[j, 1], other[j, 2] = word, line, 0
                counts[ntag] = j + 1
            other[j, 2] += 1
        else:
            e = counts[ntag + 1]
            if e == extra.shape[0]:
                return STOPPED
            extra[e, 0], extra[e, 1], extra[e, 2] = line, p, length
            counts[ntag + 1] = e + 1
        p = q + 1
    return -1


@kernel
def count_records(buf: NDArray[np.uint8], ends: NDArray[np.int64],
                  codes: NDArray[np.int64]) -> NDArray[np.int64]:  # pragma: no cover - compiled
    """The number of lines of each tag of ``codes`` in ``buf`` (as :func:`scan_records` finds them)."""
    out = np.zeros(codes.size, dtype=np.int64)
    p = 0
    for q in ends:
        k, _ = _tag_of(buf, p, q - p, codes)
        if k >= 0:
            out[k] += 1
        p = q + 1
    return out
