"""The decorator of the compiled (numba) kernels on the paths of ``pdr track`` and ``pdr classify`` (the phone
pipeline, the readers, the classifier windows' resampling): :func:`kernel`.

``kernel`` is ``numba.njit(cache=True, error_model="numpy")``. The error model decides only what a division by zero
does (numba's ``ErrorModel`` in :mod:`numba.core.callconv`, used by the division and modulo lowering of
:mod:`numba.cpython.numbers`): numba's default, ``python``, tests every divisor and raises :class:`ZeroDivisionError`;
``numpy`` lets IEEE arithmetic give ``inf`` or ``nan`` (an integer division gives 0). Every other operation, and every
division by a divisor that is not zero, gives the same bits under both. No caller catches a :class:`ZeroDivisionError`
from a kernel (it ends the command, or fails the service's batch), so every input that the default model processed
comes out bit for bit the same. Without a test and a possible exit at each division, LLVM keeps a kernel's arithmetic
in registers and schedules it freely: the attitude UKF's sigma points (one rotation matrix, with its divisions by the
norm, per point) cost a fraction of what they did.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba


def kernel(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled by numba in nopython mode, cached on disk, with numpy's division semantics (module doc)."""
    return numba.njit(cache=True, error_model="numpy")(fn)
