"""Numpy's optional submodules, loaded on first use in a ``pdr track`` process (:func:`defer_numpy_extras`).

numba loads its compiled-kernel cache through its CPU target, which imports ``scipy.linalg.cython_blas`` (numba's
check that BLAS is there); scipy's array-API layer then copies every public name of numpy, and reading
``numpy.f2py``, ``numpy.testing``, ``numpy.ma``, ... imports those packages: about 0.1-0.2 s of a ``pdr track``
process spent on Fortran wrapping, unit-test helpers and masked arrays that no command uses.

Called by the one-shot ``pdr track`` process before its first kernel loads; not by the long-running, threaded
service (Python 3.11's :class:`importlib.util.LazyLoader` does not lock the first access of a lazy module).
"""

from __future__ import annotations

import importlib.util
import sys

#: numpy's lazily imported submodules that no ``pdr`` command uses (numpy ``__init__``'s ``__getattr__``).
EXTRAS = ("numpy.char", "numpy.core", "numpy.ctypeslib", "numpy.f2py", "numpy.ma", "numpy.rec", "numpy.strings",
          "numpy.testing")


def defer_numpy_extras() -> None:
    """Register each not yet imported module of :data:`EXTRAS` as a lazy module: the module object exists (numpy's
    attribute returns it) and its code runs at the first access of one of its attributes
    (:class:`importlib.util.LazyLoader`), so a command that uses one gets the whole module as usual. Nothing when
    numpy is not imported yet (a light command, ``pdr --help``: nothing to defer, and numpy is not loaded for it).
    """
    numpy = sys.modules.get("numpy")
    if numpy is None:
        return
    for name in EXTRAS:
        if name in sys.modules:
            continue
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            continue
        spec.loader = importlib.util.LazyLoader(spec.loader)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        setattr(numpy, name.rpartition(".")[2], module)
