"""numba's runtime library rebuilt from machine code cached on disk: :func:`runtime_from_cache`, used by
:class:`pdr.filters.compiled.LeanFunctionCache`.

A process that runs a compiled kernel first starts numba's runtime (NRT, ``numba.core.runtime.nrt._Runtime.initialize``:
the reference counting of the arrays kernels make). It registers the runtime's C helpers and compiles a small LLVM
module of its own (atomic increment, decrement and compare-and-swap, ``NRT_incref``, ``NRT_decref``,
``NRT_MemInfo_data``, the abort of an unresolved symbol) down to machine code: 28-42 ms of every ``pdr track`` process
(three fresh processes, ``rtsys.initialize`` timed alone), the same machine code every time. Here the first process
keeps that library's object code beside the kernels' cache, and later processes rebuild the library from it as a cached
kernel's is rebuilt (:func:`pdr.filters.object_code_load.unserialize`). The file is named by numba's and llvmlite's
versions and by the target machine (triple, CPU name and features: what numba's own cache checks before it loads
machine code), so a file made by another numba or for another CPU is never loaded. The machine code is the one LLVM
made, so every kernel calls the same runtime functions; a missing, unreadable or foreign file is compiled as numba
does and written again.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import llvmlite
import numba
from numba.core.runtime import nrtdynmod

from pdr.filters.object_code_load import unserialize


def runtime_file(codegen: Any, cache_dir: str | Path) -> Path:
    """Where the runtime library's object code for ``codegen``'s target machine is kept in ``cache_dir``."""
    key = repr((numba.__version__, llvmlite.__version__, codegen.magic_tuple()))
    return Path(cache_dir) / f"numba-runtime-{hashlib.sha256(key.encode()).hexdigest()[:16]}.pkl"


def _runtime_library(ctx: Any, cache_dir: str | Path) -> Any:
    """The runtime library of numba for the target context ``ctx``: rebuilt from the object code kept in ``cache_dir``,
    or compiled as numba's ``compile_nrt_functions`` does and its object code kept there.
    """
    codegen = ctx.codegen()
    path = runtime_file(codegen, cache_dir)
    try:
        state = pickle.loads(path.read_bytes())
        name, kind, (object_code, bitcode) = state
        if name == "nrt" and kind == "object" and isinstance(object_code, bytes) and isinstance(bitcode, bytes):
            library = unserialize(codegen, state)
            if library.get_pointer_to_function("nrt_unresolved_abort"):    # the runtime's code is there
                return library
    except Exception:  # noqa: BLE001 - not there, not a file this module wrote, or machine code LLVM refuses: compile
        pass
    ir_module, library = nrtdynmod.create_nrt_module(ctx)     # numba's compile_nrt_functions, its machine code kept
    library.enable_object_caching()
    library.add_ir_module(ir_module)
    library.finalize()
    try:
        data = pickle.dumps(library.serialize_using_object_code())
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=path.name, suffix=".tmp", delete=False) as tmp:
            tmp.write(data)
        os.replace(tmp.name, path)                          # whole or not at all for a concurrent reader
    except OSError:
        pass                                                # a cache that cannot be written: compile next time too
    return library


@contextmanager
def runtime_from_cache(cache_dir: str | Path) -> Iterator[None]:
    """Inside the block, numba's runtime, when it starts, takes its library from ``cache_dir`` (module doc).

    For numba's cache loads, which run under numba's global compiler lock, as the runtime's start does.
    """
    compile_runtime = nrtdynmod.compile_nrt_functions
    nrtdynmod.compile_nrt_functions = lambda ctx: _runtime_library(ctx, cache_dir)
    try:
        yield
    finally:
        nrtdynmod.compile_nrt_functions = compile_runtime
