"""Compact, exact bytes for the resumable state of online algorithms (JSON with binary numpy arrays).

Online processors (the phone pipeline, the streaming classifier, foot navigation) are resumed by any
worker from a stored state after every batch, so encoding and decoding it is on the hot path. Plain JSON
writes each float as text (about 20 bytes and a microsecond per number); here an ``np.ndarray`` of a
numeric or boolean dtype is stored as its raw little-endian bytes in base64, tagged with dtype and shape,
and everything else stays JSON. Round trips are bit-exact (NaN and infinities included). No pickle: a
stored state can only ever decode to dicts, lists, strings, numbers and arrays.
"""

from __future__ import annotations

import base64
import json
from typing import Any

import numpy as np

from pdr.errors import InputError

_TAG = "__ndarray__"
_DTYPES = {"f8": np.float64, "f4": np.float32, "i8": np.int64, "i4": np.int32, "u8": np.uint64, "b1": np.bool_}
_CODES = {np.dtype(v): k for k, v in _DTYPES.items()}


def _encode_array(a: np.ndarray) -> dict[str, Any]:
    code = _CODES.get(a.dtype)
    if code is None:
        raise TypeError(f"cannot store an array of dtype {a.dtype} in a state")
    raw = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<")).tobytes()
    return {_TAG: [code, list(a.shape), base64.b64encode(raw).decode("ascii")]}


def _default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return _encode_array(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store a {type(obj).__name__} in a state")


def _decode_hook(d: dict[str, Any]) -> Any:
    spec = d.get(_TAG)
    if spec is None or len(d) != 1:
        return d
    code, shape, data = spec
    dtype = np.dtype(_DTYPES[code]).newbyteorder("<")
    a: np.ndarray = np.frombuffer(base64.b64decode(data), dtype=dtype).astype(_DTYPES[code])  # writable copy
    return a.reshape(shape)


def dumps(state: Any) -> bytes:
    """``state`` (dicts, lists, scalars and numpy arrays) as bytes for :func:`loads`."""
    return json.dumps(state, default=_default, separators=(",", ":"), allow_nan=True).encode()


def loads(blob: bytes) -> Any:
    """The object :func:`dumps` wrote; arrays come back as writable numpy arrays of the same dtype and shape.

    :class:`InputError` when ``blob`` is not such a state (corrupt or from an unknown writer).
    """
    try:
        return json.loads(blob, object_hook=_decode_hook)
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise InputError(f"not a stored processing state ({exc})", source="state") from None
