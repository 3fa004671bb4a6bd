"""The decorators of every compiled (numba) kernel: :func:`kernel`, with numpy's division semantics (the phone
pipeline's filters, steps and floors, the readers, the classifier windows' resampling), and :func:`cached_njit`, with
numba's own (the heading smoother, the classifier features, map matching and the site's wall index, the foot
navigators).

Both compile with ``numba.njit`` and keep the machine code in numba's disk cache, as ``cache=True`` does, but load it
without numba's registry refresh (:class:`LeanFunctionCache`).

``kernel`` is ``cached_njit(error_model="numpy")``. The error model decides only what a division by zero
does (numba's ``ErrorModel`` in :mod:`numba.core.callconv`, used by the division and modulo lowering of
:mod:`numba.cpython.numbers`): numba's default, ``python``, tests every divisor and raises :class:`ZeroDivisionError`;
``numpy`` lets IEEE arithmetic give ``inf`` or ``nan`` (an integer division gives 0). Every other operation, and every
division by a divisor that is not zero, gives the same bits under both. No caller catches a :class:`ZeroDivisionError`
from a kernel (it ends the command, or fails the service's batch), so every input that the default model processed
comes out bit for bit the same. Without a test and a possible exit at each division, LLVM keeps a kernel's arithmetic
in registers and schedules it freely: the attitude UKF's sigma points (one rotation matrix, with its divisions by the
norm, per point) cost a fraction of what they did.

**Loading from the cache.** numba's cache, before it loads a kernel's machine code, refreshes the CPU target: it
imports and registers every lowering that numba implements (its numpy, unicode, typed-container, random and
datetime support; :meth:`numba.core.cpu.CPUContext.load_additional_registries`), 0.4-0.5 s on a 2-core machine,
the largest part of the first kernel call of a ``pdr track`` or ``pdr classify`` process. Machine code loaded from the
cache is linked already and needs none of them: only numba's runtime (its allocator, for kernels that make arrays)
must be up. :class:`LeanFunctionCache` loads with that alone. When a kernel is not in the cache (a first run, a new
signature, an edited source), numba compiles it, and its compiler refreshes the target as before.

A load also runs without llvmlite's lock callbacks (:func:`_llvm_lock_callbacks_off`). Every call into LLVM takes
llvmlite's lock, and numba hooks the lock to fire a ``numba:llvm_lock`` event, which the dispatcher times while it
compiles or loads: several thousand calls per process, 40-70 ms of a ``pdr track`` process's 11 loads. The time is
kept for a compiled kernel only (in its metadata, which a kernel loaded from the cache has none of), so the loads
skip it.

The cache of a kernel is set up (its folder found and tested for writing with a temporary file, its source file
hashed) when the kernel is first compiled or loaded, not when its module is imported: a ``pdr track`` process imports
79 kernels and loads 19 (the others are compiled into those), and the set-up took about 0.15 ms a kernel.

And a load rebuilds the kernel's library from its machine code and the names in its ELF symbol table, without parsing
the LLVM bitcode numba keeps beside it for linking (:mod:`pdr.filters.object_code_load`); the runtime that the first
load starts takes its own library from machine code kept beside the kernels' cache (:mod:`pdr.filters.runtime_cache`).

**numba's extensions.** Before it types a kernel's arguments, numba loads every installed package's
``numba_extensions`` entry point (``numba.core.entrypoints.init_all``), which reads the entry points of every
distribution in the environment: 20-47 ms of a ``pdr track`` process (three fresh processes), where none is installed.
An extension registers types and implementations for the compiler; a kernel loaded from the cache is machine code
already, and the arguments of this project's kernels are numpy arrays and numbers. So the kernels load without them,
and a cache miss loads them before numba compiles (:meth:`LeanFunctionCache.load_overload`; a compilation's target
refresh loads them too). Plain ``numba.njit`` functions keep numba's hook.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numba
from llvmlite.binding import ffi
from numba.core import entrypoints
from numba.core.caching import FunctionCache
from numba.core.runtime import rtsys

from pdr.filters.object_code_load import object_code_only
from pdr.filters.runtime_cache import runtime_from_cache


class LeanFunctionCache(FunctionCache):
    """numba's disk cache of one function, whose loads start only numba's runtime, not the target's registries
    (module doc), and which is set up when it is first used (module doc).
    """

    def __init__(self, py_func: Callable[..., Any]) -> None:
        self._pending_py_func = py_func

    def __getattr__(self, name: str) -> Any:
        """Set numba's cache up (:class:`FunctionCache`) at the first use of one of its attributes."""
        py_func = self.__dict__.pop("_pending_py_func", None)
        if py_func is None:
            raise AttributeError(name)
        FunctionCache.__init__(self, py_func)
        return getattr(self, name)

    def load_overload(self, sig: Any, target_context: Any) -> Any:
        """The cached compile result of ``sig``, or None: numba then compiles, refreshing the target itself, after
        its extensions are loaded here (module doc).
        """
        with _llvm_lock_callbacks_off(), object_code_only(target_context.codegen()):
            if not rtsys._init:
                with runtime_from_cache(self._cache_path):
                    rtsys.initialize(target_context)
            with self._guard_against_spurious_io_errors():
                result = self._load_overload(sig, target_context)
        if result is None:
            entrypoints.init_all()
        return result


@contextmanager
def _llvm_lock_callbacks_off() -> Iterator[None]:
    """The lock callbacks of llvmlite (numba's ``numba:llvm_lock`` event) unregistered inside the block (module doc).

    numba loads from its cache under its global compiler lock, so no other load or compilation runs meanwhile.
    """
    callbacks = list(ffi.lib._lock._cblist)
    for acquired, released in callbacks:
        ffi.unregister_lock_callback(acquired, released)
    try:
        yield
    finally:
        for acquired, released in callbacks:
            ffi.register_lock_callback(acquired, released)


def cached_njit(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    """``numba.njit(cache=True, **options)`` whose cache loads through :class:`LeanFunctionCache`."""
    def decorate(fn: Callable[..., Any]) -> Any:
        dispatcher = numba.njit(**options)(fn)
        if hasattr(dispatcher, "py_func"):     # not with NUMBA_DISABLE_JIT=1: numba then gives back the function
            dispatcher._cache = LeanFunctionCache(dispatcher.py_func)     # as Dispatcher.enable_caching does
            # numba's extensions are loaded before a compilation, not before a load from the cache (module doc).
            dispatcher._compilation_chain_init_hook = _no_extensions_yet
        return dispatcher
    return decorate


def is_cached(dispatcher: Any) -> bool:
    """Whether numba's disk cache holds machine code of ``dispatcher`` (a :func:`cached_njit` kernel) compiled from
    its current source (its index exists and its source stamp matches); False when it cannot tell.
    """
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:   # NUMBA_DISABLE_JIT (no cache), or an index numba cannot read: as good as none
        return False


def _no_extensions_yet() -> None:
    """A kernel's hook before numba types its arguments: numba's extensions wait for a cache miss (module doc)."""


def kernel(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled by numba in nopython mode, cached on disk, with numpy's division semantics (module doc)."""
    return cached_njit(error_model="numpy")(fn)
