"""The set-up of a one-shot process that reads one log and runs the compiled kernels on it (``pdr track``,
``pdr classify``): :func:`one_shot_process`.

- numpy's unused submodules load on first use only (:func:`pdr.cli.lazy_numpy.defer_numpy_extras`);
- BLAS and LAPACK load for numba without the scipy.linalg package (:func:`pdr.cli.numba_blas.load_numba_blas`);
- the garbage collector pauses while the recording's long-lived objects are made (:mod:`pdr.cli.collector`).

Not for the long-running service (module docs of the three).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from pdr.cli.collector import collection_paused
from pdr.cli.lazy_numpy import defer_numpy_extras
from pdr.cli.numba_blas import load_numba_blas


@contextmanager
def one_shot_process() -> Iterator[None]:
    """Run the body as a one-shot command (module doc): call it before the first compiled kernel loads."""
    defer_numpy_extras()
    load_numba_blas()
    with collection_paused():
        yield
