"""The BLAS and LAPACK modules numba's compiled kernels ask for, loaded alone in a ``pdr track`` process
(:func:`load_numba_blas`).

The first call of a cached kernel sets numba's CPU target up, and that imports ``scipy.linalg.cython_blas`` (numba's
check that BLAS is there, and the functions its ``np.dot`` calls); a kernel that calls ``np.linalg`` links to
``scipy.linalg.cython_lapack``. Importing them the usual way first runs the ``scipy.linalg`` package (its solvers,
decompositions and array-API layer): about 0.15 s of a one-shot process's CPU for two extension modules whose
function tables are all numba reads. Loaded alone under their own names, the imports numba makes find them in
:data:`sys.modules`; ``import scipy.linalg`` later in the process still runs the package as usual (its own imports
of them find the same modules). The one difference: the package's attribute ``scipy.linalg.cython_blas`` is not set
(``from scipy.linalg import cython_blas`` and ``sys.modules`` still give the module).

Called by the one-shot ``pdr track`` process before its first kernel loads, as
:func:`pdr.cli.lazy_numpy.defer_numpy_extras`; not by the long-running service.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
from pathlib import Path

#: The modules numba imports (``numba.np.linalg.ensure_blas``, ``ensure_lapack``).
NAMES = ("scipy.linalg.cython_blas", "scipy.linalg.cython_lapack")


def load_numba_blas() -> bool:
    """Load each module of :data:`NAMES` without its package (unless ``scipy.linalg`` is loaded already); True when
    all are loaded now. A module that cannot be loaded so (scipy not installed, another layout than an extension
    file in ``scipy/linalg``) is left to numba's own import.
    """
    if "scipy.linalg" in sys.modules:
        return all(name in sys.modules for name in NAMES)
    return all([_load_alone(name) for name in NAMES])


def _load_alone(name: str) -> bool:
    """Load the extension module ``scipy.linalg.X`` under its name without running ``scipy.linalg``."""
    if name in sys.modules:
        return True
    try:
        spec = importlib.util.find_spec("scipy")
    except (ImportError, ValueError):
        return False
    if spec is None or not spec.submodule_search_locations:
        return False
    folder = Path(next(iter(spec.submodule_search_locations))) / "linalg"
    files = sorted(p for suffix in importlib.machinery.EXTENSION_SUFFIXES
                   for p in folder.glob(f"{name.rpartition('.')[2]}{suffix}"))
    if not files:
        return False
    import scipy  # noqa: F401  (the package the import statement binds; light: its submodules load on use)
    loader = importlib.machinery.ExtensionFileLoader(name, str(files[0]))
    module_spec = importlib.util.spec_from_file_location(name, files[0], loader=loader)
    if module_spec is None:
        return False
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[name] = module
    try:
        loader.exec_module(module)
    except Exception:  # any failure: leave it to numba's own import
        del sys.modules[name]
        return False
    return True
