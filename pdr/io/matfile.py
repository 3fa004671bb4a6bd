"""MATLAB ``.mat`` files (v4-v7.2, read with scipy): loading with project errors, and cheap variable listing."""

from __future__ import annotations

import io
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
