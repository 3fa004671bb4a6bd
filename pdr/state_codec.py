r"""Compact, exact bytes for the resumable state of online algorithms (a JSON header plus raw numpy arrays).

Online processors (the phone pipeline, the streaming classifier, foot navigation) are resumed by any
worker from a stored state after every batch, so encoding and decoding it is on the hot path. Plain JSON
writes each float as text (about 20 bytes and a microsecond per number). Here every ``np.ndarray`` of a
numeric or boolean dtype is replaced in a JSON header by a reference ``{"__ndarray__": [dtype, shape,
offset, nbytes]}`` into a block of raw little-endian bytes that follows the header::

    b"PDRSTATE1\\n" | header length (uint32 LE) | header (UTF-8 JSON) | array bytes

Round trips are bit-exact (NaN and infinities included) and cost about a memory copy. No pickle: a stored
state can only ever decode to dicts, lists, strings, numbers and arrays.
"""

from __future__ import annotations

import json
import struct
from typing import Any

import numpy as np

from pdr.errors import InputError

MAGIC = b"PDRSTATE1\n"
_TAG = "__ndarray__"
_DTYPES = {"f8": np.float64, "f4": np.float32, "f2": np.float16, "i8": np.int64, "i4": np.int32, "i2": np.int16,
           "i1": np.int8, "u8": np.uint64, "u4": np.uint32, "u2": np.uint16, "u1": np.uint8, "b1": np.bool_}
_CODES = {np.dtype(v): k for k, v in _DTYPES.items()}
_LEN = struct.Struct("<I")


def dumps(state: Any) -> bytes:
    """``state`` (dicts, lists, scalars and numpy arrays) as bytes for :func:`loads`."""
    chunks: list[bytes] = []
    offset = 0

    def default(obj: Any) -> Any:
        nonlocal offset
        if isinstance(obj, np.ndarray):
            code = _CODES.get(obj.dtype)
            if code is None:
                raise TypeError(f"cannot store an array of dtype {obj.dtype} in a state")
            raw = np.ascontiguousarray(obj, dtype=obj.dtype.newbyteorder("<")).tobytes()
            chunks.append(raw)
            ref = {_TAG: [code, list(obj.shape), offset, len(raw)]}
            offset += len(raw)
            return ref
        if isinstance(obj, np.generic):
            return obj.item()
        raise TypeError(f"cannot store a {type(obj).__name__} in a state")

    header = json.dumps(state, default=default, separators=(",", ":"), allow_nan=True).encode()
    return b"".join([MAGIC, _LEN.pack(len(header)), header, *chunks])


def loads(blob: bytes) -> Any:
    """The object :func:`dumps` wrote; arrays come back as writable numpy arrays of the same dtype and shape.

    :class:`InputError` when ``blob`` is not such a state (corrupt, truncated or from an unknown writer).
    """
    try:
        if not blob.startswith(MAGIC):
            raise ValueError("unknown format")
        start = len(MAGIC) + _LEN.size
        (n,) = _LEN.unpack_from(blob, len(MAGIC))
        data = memoryview(blob)[start + n:]

        def hook(d: dict[str, Any]) -> Any:
            spec = d.get(_TAG)
            if spec is None or len(d) != 1:
                return d
            code, shape, offset, nbytes = spec
            if offset < 0 or offset + nbytes > len(data):
                raise ValueError("array data out of bounds")
            a: np.ndarray = np.frombuffer(data[offset:offset + nbytes], dtype=np.dtype(_DTYPES[code]).newbyteorder("<"))
            return a.astype(_DTYPES[code]).reshape(shape)  # astype: a writable native copy

        return json.loads(bytes(blob[start:start + n]), object_hook=hook)
    except (ValueError, KeyError, TypeError, UnicodeDecodeError, struct.error) as exc:
        raise InputError(f"not a stored processing state ({exc})", source="state") from None
