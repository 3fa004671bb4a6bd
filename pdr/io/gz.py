"""gzip data of the readers: decompressed whole, or, cut short (a copy or download stopped), as far as it goes.

:func:`gunzip` refuses damaged data with an :class:`~pdr.errors.InputError` naming the file. Data cut short (the
stream ends before its end-of-stream marker: :func:`gzip.decompress` raises ``EOFError``) is refused too, except
within :func:`cut_gzip_warnings` (:func:`pdr.io.registry.read_recording` reads every log so): there the bytes that
decompress are returned and a warning naming the file is collected, for the recording's warnings. Data from which
nothing decompresses, or that is not gzip at all (said so: a plain file named ``.gz``), is refused either way. Bytes
after the last whole member that are not gzip data (trailing garbage, as ``gzip -d`` warns of) are likewise ignored
with a warning within :func:`cut_gzip_warnings`, and refused outside it.
"""

from __future__ import annotations

import gzip
import zlib
from collections.abc import Iterator

from pdr.errors import InputError
from pdr.io import notices
from pdr.io.time_order import file_name

GZIP_MAGIC = b"\x1f\x8b"

#: Within it, a gzip cut short is read as far as it decompresses, with a notice naming it (the helpers' notices of
#: :mod:`pdr.io.notices`).
cut_gzip_warnings = notices.collecting


def gunzip(raw: bytes, source: str) -> bytes:
    """The decompressed content of gzip data (every member); see the module docstring for data cut short.

    Raises
    ------
    InputError
        ``not gzip data (...)`` naming ``source`` when ``raw`` does not start with :data:`GZIP_MAGIC` (a plain file
        named ``.gz``); ``corrupt gzip data (...)`` when it is damaged, or cut short outside :func:`cut_gzip_warnings`.
    """
    if raw and raw[:2] != GZIP_MAGIC:
        raise InputError(f"not gzip data, though named .gz: it starts with {raw[:8]!r}, gzip with bytes 1f 8b",
                         source=source)
    try:
        return gzip.decompress(raw)
    except EOFError as exc:
        notes = notices.active()
        whole = b"" if notes is None else decompressed_prefix(raw)
        if notes is None or not whole:
            raise InputError(f"corrupt gzip data ({exc})", source=source) from None
        notes.append(f"{file_name(source)}: cut short (the gzip stream ends before its end marker): read the "
                     f"{len(whole)} bytes that decompress")
        return whole
    except (OSError, zlib.error) as exc:      # zlib.error: a bad deflate block inside the gzip
        notes = notices.active()
        trailing = None if notes is None else _trailing_bytes(raw)
        if notes is None or not trailing:
            raise InputError(f"corrupt gzip data ({exc})", source=source) from None
        notes.append(f"{file_name(source)}: {trailing} bytes after the end of the gzip stream that are not gzip data "
                     "ignored (the stream itself is whole)")
        return decompressed_prefix(raw)


def _trailing_bytes(raw: bytes) -> int:
    """How many bytes follow the last gzip member of ``raw`` when every member before them is whole (checked by its
    CRC) and they are not gzip data; 0 otherwise (no member, cut short, damaged, or nothing after the members).
    """
    if raw[:2] != GZIP_MAGIC:
        return 0
    while raw[:2] == GZIP_MAGIC:
        stream = zlib.decompressobj(wbits=31)
        try:
            while raw and not stream.eof:
                stream.decompress(raw, 1 << 20)
                raw = stream.unconsumed_tail
        except zlib.error:
            return 0
        if not stream.eof:
            return 0
        raw = stream.unused_data.lstrip(b"\x00")
    return len(raw)


def decompressed_prefix(raw: bytes, limit: int = 0) -> bytes:
    """The bytes that decompress from the start of gzip data, member after member, up to where it is cut short or
    damaged (at most ``limit`` bytes when given, for sniffing); empty when none do.
    """
    out: list[bytes] = []
    n = 0
    for chunk in _inflate(raw, limit or None):
        out.append(chunk)
        n += len(chunk)
        if limit and n >= limit:
            break
    return b"".join(out)[:limit] if limit else b"".join(out)


def inflated_size(raw: bytes, limit: int) -> int:
    """How many bytes gzip data inflates to (every member, up to where it is cut short or damaged), counted without
    keeping them; ``limit + 1`` as soon as it is more than ``limit`` bytes (a compression bomb costs no more).
    """
    n = 0
    for chunk in _inflate(raw, 1 << 20):
        n += len(chunk)
        if n > limit:
            return limit + 1
    return n


def _inflate(raw: bytes, chunk: int | None) -> Iterator[bytes]:
    """The decompressed bytes of gzip data in pieces of at most ``chunk`` bytes (None: one piece per member),
    member after member, until the data ends, is cut short or is damaged.
    """
    while raw[:2] == GZIP_MAGIC:
        stream = zlib.decompressobj(wbits=31)            # 31: a gzip header and trailer
        data = raw
        while True:
            try:
                piece = stream.decompress(data, chunk or 0)
            except zlib.error:
                return
            if piece:
                yield piece
            data = stream.unconsumed_tail
            if stream.eof or not data:
                break
        if not stream.eof:
            return                                       # cut short
        raw = stream.unused_data.lstrip(b"\x00")        # gzip allows zero padding between members
