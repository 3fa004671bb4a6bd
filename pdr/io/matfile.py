"""MATLAB ``.mat`` files (v4-v7.2, read with scipy): loading with project errors, and cheap variable listing.

A v5-v7.2 file is checked before scipy reads it (:func:`check_elements`): scipy's compiled reader trusts the type code
of a numeric or text data element, and a damaged one crashes the interpreter (segmentation fault) instead of raising.
"""

from __future__ import annotations

import io
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io.text import head, read_bytes

_MAGIC = b"MATLAB 5.0 MAT-file"


def is_mat(path: str | Path) -> bool:
    """``path`` is named ``.mat`` (or ``.mat.gz``) and starts as a MATLAB v5-v7.2 file does. Never raises."""
    p = Path(path)
    return p.name.lower().endswith((".mat", ".mat.gz")) and head(p, len(_MAGIC)).startswith(_MAGIC)


def variables(path: str | Path) -> set[str]:
    """Names of the variables of a ``.mat`` (or ``.mat.gz``) file; empty for anything else. Never raises."""
    p = Path(path)
    if not is_mat(p):
        return set()
    try:
        from scipy.io import whosmat

        src: Any = io.BytesIO(read_bytes(p)) if p.name.lower().endswith(".gz") else str(p)
        return {name for name, _, _ in whosmat(src)}
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return set()


def load(path: str | Path, structs: bool = False) -> dict[str, Any]:
    """All variables of a ``.mat`` (or ``.mat.gz``) file; :class:`InputError` if it is not a readable one.

    ``structs``: MATLAB structs as objects with attributes and 1xN arrays squeezed (scipy's ``squeeze_me=True,
    struct_as_record=False``), for exports made of nested structs (Qualisys).
    """
    from scipy.io import loadmat

    p = Path(path)
    raw = read_bytes(p)
    check_elements(raw, str(p))
    try:
        mat: dict[str, Any] = loadmat(io.BytesIO(raw), squeeze_me=structs, struct_as_record=not structs)
    except NotImplementedError:
        raise InputError("MATLAB v7.3 (HDF5) files are not supported; save with -v7", source=str(p)) from None
    except Exception as exc:  # noqa: BLE001 - scipy raises many types on corrupt input
        raise InputError(f"not a readable MATLAB .mat file ({type(exc).__name__}: {exc})", source=str(p)) from None
    return {k: v for k, v in mat.items() if not k.startswith("__")}


def array(mat: dict[str, Any], name: str, source: str, *, ncol: int | None = None, vector: bool = False,
          finite: bool = True) -> NDArray[np.float64]:
    """Variable ``name`` as float64: (N,) when ``vector`` (a 1xN or Nx1 matrix), else (N, ncol).

    Raises :class:`InputError` naming the variable (and the first bad row) when it is missing, not numeric,
    of the wrong shape or (with ``finite``) holds NaN or infinity.
    """
    if name not in mat:
        raise InputError(f"missing variable '{name}' (file has {sorted(mat)})", source=source, field=name)
    try:
        a = np.asarray(mat[name], dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("not a numeric array", source=source, field=name) from None
    if vector:
        if a.ndim != 2 or min(a.shape) != 1:
            raise InputError(f"expected a 1xN vector, got shape {a.shape}", source=source, field=name)
        a = a.ravel()
    elif a.ndim != 2 or (ncol is not None and a.shape[1] != ncol):
        raise InputError(f"expected an Nx{ncol} matrix, got shape {a.shape}", source=source, field=name)
    if finite and not np.all(np.isfinite(a)):
        row = int(np.argwhere(~np.isfinite(a))[0][0])
        raise InputError(f"row {row + 1} is not finite", source=source, field=name)
    return a


def scalar(mat: dict[str, Any], name: str) -> Any:
    """A 1x1 numeric or string variable as a plain Python value, or None when absent or not scalar."""
    if name not in mat:
        return None
    a = np.asarray(mat[name])
    if a.size != 1:
        return None
    item = a.ravel()[0]
    return item.item() if isinstance(item, np.generic) else item


# ---------------------------------------------------------------------------------------------------------
# the element tree of a v5 file, checked before scipy reads it

#: Type codes scipy reads a numeric or text data element as (miINT8 .. miUINT64 without the reserved 8, 10 and 11,
#: and miUTF8/16/32). scipy (1.17) looks the code up in a table of 20 slots without checking it: any other code is a
#: NULL or wild pointer and a segmentation fault (scipy pull request 25349, not merged).
DATA_TYPES = frozenset({1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18})
_MI_MATRIX, _MI_COMPRESSED = 14, 15
_CELL, _STRUCT, _OBJECT, _CHAR, _SPARSE, _FUNCTION, _OPAQUE = 1, 2, 3, 4, 5, 16, 17
_NUMERIC = range(6, 16)


class _Damage(Exception):
    """A structural defect at byte ``offset`` (of the file, or of an element's inflated data), in ``variable``."""

    def __init__(self, what: str, offset: int) -> None:
        super().__init__(what)
        self.what, self.offset = what, offset
        self.variable: str | None = None


def check_elements(raw: bytes, source: str) -> None:
    """Check the element tree of a MATLAB v5-v7.2 file (``raw``, its bytes) as scipy walks it: every element within
    its enclosing one and the file, every compressed element inflating, every numeric or text data element of a type
    in :data:`DATA_TYPES`. :class:`InputError` naming the variable and the element otherwise. Other files (v4, v7.3,
    not MATLAB) are left to scipy, whose readers of those raise. Costs one inflation of the compressed elements.
    """
    if len(raw) < 128 or 0 in raw[:4]:
        return  # a v4 file (scipy reads those in Python) or too short for a v5 header: scipy raises
    order = {b"IM": "<", b"MI": ">"}.get(raw[126:128])
    if order is None or raw[124 + (raw[126:127] == b"I")] != 1:
        return  # not version 1 (v5-v7.2) of the header: scipy refuses it (v7.3 is HDF5)
    off, index = 128, 0
    while off < len(raw):
        index += 1
        inside = ""  # where the offsets of a defect count from
        try:
            mdtype, start, size, _ = _tag(raw, off, len(raw), order)
            if mdtype == _MI_COMPRESSED:
                try:
                    body = zlib.decompressobj().decompress(raw[start:start + size])
                except zlib.error as exc:
                    raise _Damage(f"its compressed data does not inflate ({exc})", start) from None
                inside = " of its inflated data"
                _matrix(body, 0, len(body), order)
            else:
                _matrix(raw, off, start + size, order)
        except _Damage as exc:
            raise InputError(f"not a readable MATLAB .mat file (damaged: element {index} at byte {off}: {exc.what}, "
                             f"at byte {exc.offset}{inside})", source=source, field=exc.variable) from None
        off = start + size


def _tag(buf: bytes, off: int, end: int, order: str) -> tuple[int, int, int, int]:
    """(type, data offset, data bytes, next element's offset) of the element at ``off``, within ``[off, end)``."""
    if end - off < 8:
        raise _Damage(f"cut off: an element's tag needs 8 bytes, {end - off} are left", off)
    mdtype, size = struct.unpack_from(order + "II", buf, off)
    if mdtype >> 16:  # small data element: type and size in 2 bytes each, up to 4 bytes of data in the tag
        mdtype, size = mdtype & 0xFFFF, mdtype >> 16
        if size > 4:
            raise _Damage(f"a small element declares {size} bytes (at most 4)", off)
        return mdtype, off + 4, size, off + 8
    if size > end - off - 8:
        raise _Damage(f"an element declares {size} bytes, {end - off - 8} are left", off)
    return mdtype, off + 8, size, min(off + 8 + -(-size // 8) * 8, end)


def _data(buf: bytes, off: int, end: int, order: str) -> int:
    """Offset after the numeric or text data element at ``off``; :class:`_Damage` for a type scipy cannot read."""
    mdtype, _, _, nxt = _tag(buf, off, end, order)
    if mdtype not in DATA_TYPES:
        raise _Damage(f"a data element of unknown type {mdtype} (numbers and text are types 1-7, 9, 12, 13, 16-18)",
                      off)
    return nxt


def _matrix(buf: bytes, off: int, end: int, order: str, variable: str | None = None) -> int:
    """Walk the miMATRIX element at ``off`` (and the arrays it holds) of ``variable`` (None: the element names it);
    offset of the element after it.
    """
    mdtype, start, size, nxt = _tag(buf, off, end, order)
    if mdtype != _MI_MATRIX:
        raise _Damage(f"expected a matrix element (type {_MI_MATRIX}), found type {mdtype}", off)
    _matrix_contents(buf, start, start + size, order, variable)
    return nxt


def _matrix_contents(buf: bytes, p: int, stop: int, order: str, variable: str | None) -> None:
    """Walk the contents ``[p, stop)`` of a miMATRIX element: flags, dimensions, name, then by the array's class."""
    if p == stop:
        return  # an empty array
    if stop - p < 16:
        raise _Damage("a matrix element too short for its array flags", p)
    flags = struct.unpack_from(order + "I", buf, p + 8)[0]
    cls, complex_ = flags & 0xFF, flags >> 11 & 1
    p += 16
    if cls == _OPAQUE:  # three names, then the object's contents
        for _ in range(3):
            p = _tag(buf, p, stop, order)[3]
        _matrix(buf, p, stop, order, variable)
        return
    dims_at = p
    _, d0, dbytes, p = _tag(buf, p, stop, order)
    if dbytes < 8:  # MATLAB writes at least 2; scipy crashes on a text array of none
        raise _Damage(f"an array of {dbytes // 4} dimensions (at least 2)", dims_at)
    count = 1
    for (n,) in struct.iter_unpack(order + "i", buf[d0:d0 + dbytes // 4 * 4]):
        count *= max(n, 0)
    _, n0, nbytes, p = _tag(buf, p, stop, order)
    if variable is None:
        name = buf[n0:n0 + nbytes].split(b"\0")[0].decode("latin-1")
        variable = name if name.isprintable() and name else None  # a damaged name names nothing
    try:
        if cls in _NUMERIC or cls == _CHAR:
            for _ in range(1 + (complex_ if cls != _CHAR else 0)):
                p = _data(buf, p, stop, order)
        elif cls == _SPARSE:
            for _ in range(3 + complex_):
                p = _data(buf, p, stop, order)
        elif cls == _CELL:
            for _ in range(count):
                p = _matrix(buf, p, stop, order, variable)
        elif cls in (_STRUCT, _OBJECT):
            if cls == _OBJECT:
                p = _tag(buf, p, stop, order)[3]  # the class name
            _, l0, lbytes, p = _tag(buf, p, stop, order)
            length = struct.unpack_from(order + "i", buf, l0)[0] if lbytes >= 4 else 0
            fbytes, p = _tag(buf, p, stop, order)[2:]
            if fbytes and length <= 0:
                raise _Damage(f"field names of length {length}", l0)
            for _ in range(count * (fbytes // length if fbytes else 0)):
                p = _matrix(buf, p, stop, order, variable)
        elif cls == _FUNCTION:
            _matrix(buf, p, stop, order, variable)
    except _Damage as exc:
        exc.variable = exc.variable or variable
        raise
