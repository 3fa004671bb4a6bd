"""pdr.filters.compiled: a kernel compiled in one process loads from the disk cache in the next without numba's
registry refresh, and computes the same (its arrays allocated by numba's runtime, numpy's division semantics)."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

from tests.conftest import data_path
from tests.fresh_process import python_json

_MODULE = textwrap.dedent('''
    import numpy as np

    from pdr.filters.compiled import kernel


    @kernel
    def ratios(x, d):
        out = np.empty(x.size)          # numba's runtime allocates it
        for i in range(x.size):
            out[i] = x[i] / d           # inf or nan for d == 0 (error_model="numpy")
        return out
''')

_RUN = ("import json, sys; import numpy as np; import lean_kernel_probe as m; "
        "a = m.ratios(np.array([1.0, -2.0, 0.0]), 0.0); b = m.ratios(np.arange(3.0), 4); "
        "print(json.dumps({'values': [repr(float(v)) for v in np.concatenate([a, b])], "
        "'cache_hits': sum(m.ratios.stats.cache_hits.values()), "
        "'refreshed': 'numba.np.arraymath' in sys.modules, "
        "'lock_callbacks': len(__import__('llvmlite.binding.ffi').binding.ffi.lib._lock._cblist)}))")


def test_a_kernel_loads_from_the_cache_without_the_registry_refresh(tmp_path: Path) -> None:
    (tmp_path / "lean_kernel_probe.py").write_text(_MODULE)
    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(repo)]),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}
    compiled = python_json(_RUN, env=env)          # compiles two signatures (float and int divisor): numba refreshes
    loaded = python_json(_RUN, env=env)
    assert compiled["cache_hits"] == 0 and compiled["refreshed"]
    assert loaded["cache_hits"] == 2 and not loaded["refreshed"]
    assert loaded["values"] == compiled["values"] == ["inf", "-inf", "nan", "0.0", "0.25", "0.5"]
    # numba's hook on llvmlite's lock, off while a kernel loads, is back after the loads.
    assert loaded["lock_callbacks"] == compiled["lock_callbacks"] == 1


def test_with_the_jit_disabled_a_kernel_runs_as_python(tmp_path: Path) -> None:
    (tmp_path / "lean_kernel_probe.py").write_text(_MODULE)
    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(repo)]), "NUMBA_DISABLE_JIT": "1"}
    out = python_json("import json; import numpy as np; import lean_kernel_probe as m; "
                      "print(json.dumps({'compiled': hasattr(m.ratios, 'py_func'), "
                      "'values': m.ratios(np.arange(3.0), 4).tolist()}))", env=env)
    assert out == {"compiled": False, "values": [0.0, 0.25, 0.5]}


@pytest.mark.data
def test_pdr_track_loads_its_kernels_without_numbas_array_math(tmp_path: Path) -> None:
    """The pipeline's kernels call no numba implementation that lives in ``numba.np.arraymath`` (``np.cross``,
    ``np.outer``, ...): rebuilding their environments from the cache would import that module, 0.25-0.4 s of a
    ``pdr track`` process's start."""
    log = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial02_repetition01.txt")
    argv = ["track", str(log), "--out", str(tmp_path / "track.csv")]
    code = ("import json, sys, contextlib, io; from pdr.cli import main\n"
            f"with contextlib.redirect_stdout(io.StringIO()):\n    rc = main({argv!r})\n"
            "print(json.dumps({'rc': rc, 'array_math': 'numba.np.arraymath' in sys.modules}))")
    python_json(code, timeout_s=600)                   # compiles what the cache does not hold yet
    assert python_json(code, timeout_s=600) == {"rc": 0, "array_math": False}


_LINKING_MODULE = textwrap.dedent('''
    import numba
    import numpy as np

    from pdr.filters.compiled import kernel


    @kernel
    def scaled(x, k):
        return x * k + 1.0


    @numba.njit                     # not cached: compiled in every process, linking the cached kernel in
    def twice_scaled(x, k):
        return scaled(scaled(x, k), k)
''')


def _probe_env(tmp_path: Path) -> dict[str, str]:
    """The environment of a process that imports the module of :data:`_LINKING_MODULE` (written to ``tmp_path``)
    with its own numba cache there."""
    (tmp_path / "lean_linking_probe.py").write_text(_LINKING_MODULE)
    repo = Path(__file__).resolve().parents[3]
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(repo)]),
            "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}


def test_a_kernel_compiled_after_a_lean_load_links_the_loaded_kernel_in(tmp_path: Path) -> None:
    """A cached kernel loaded from its machine code alone (pdr.filters.object_code_load) keeps its bitcode for a
    kernel compiled later in the process, which calls it."""
    env = _probe_env(tmp_path)
    run = ("import json; import lean_linking_probe as m; a = m.scaled(2.0, 3.0); b = m.twice_scaled(2.0, 3.0); "
           "lib = type(m.scaled.overloads[m.scaled.signatures[0]].library).__name__; "
           "print(json.dumps({'values': [a, b], 'hits': sum(m.scaled.stats.cache_hits.values()), 'library': lib}))")
    first = python_json(run, env=env)
    second = python_json(run, env=env)
    assert first["values"] == second["values"] == [7.0, 22.0]
    assert first["hits"] == 0 and second["hits"] == 1
    assert second["library"].startswith("Lazy")


def test_the_elf_symbol_table_names_what_the_linking_module_defines(tmp_path: Path) -> None:
    """The names a lean load gives the execution engine (from the object code's symbol table) are those numba's load
    reads from the bitcode: every function and global its module for linking defines."""
    env = _probe_env(tmp_path)
    code = ("import json; import numpy as np; import llvmlite.binding as ll; import lean_linking_probe as m; "
            "from pdr.filters.object_code_load import elf_defined_symbols; m.scaled(np.arange(3.0), 2.0); "
            "out = []\n"
            "for result in m.scaled.overloads.values():\n"
            "    _, kind, (obj, bitcode) = result.library.serialize_using_object_code()\n"
            "    module = ll.parse_bitcode(bitcode)\n"
            "    defined = {g.name for gs in (module.functions, module.global_variables) for g in gs "
            "if not g.is_declaration}\n"
            "    out.append([kind, sorted(elf_defined_symbols(obj)), sorted(defined)])\n"
            "print(json.dumps(out))")
    (kind, from_elf, from_bitcode), = python_json(code, env=env)
    assert kind == "object" and len(from_elf) > 3
    assert from_elf == from_bitcode


def test_an_object_that_is_not_elf_is_left_to_numba() -> None:
    from pdr.filters.object_code_load import elf_defined_symbols

    assert elf_defined_symbols(b"\xcf\xfa\xed\xfe" + bytes(60)) is None      # a Mach-O header
    assert elf_defined_symbols(b"") is None


def test_a_numba_without_the_internals_used_rebuilds_the_library_its_own_way(monkeypatch):
    # pdr.filters.object_code_load relies on numba's private library methods; where they are not there (a later
    # numba), the load falls back to numba's own rebuild instead of failing.
    from pdr.filters import object_code_load

    monkeypatch.setattr(object_code_load, "elf_defined_symbols", lambda obj: {"kernel"})

    class Library:
        def __init__(self, codegen: object, name: str) -> None:     # no enable_object_caching: internals moved
            self.name = name

        @classmethod
        def _unserialize(cls, codegen: object, state: tuple) -> tuple:
            return ("numba's own rebuild", state[0])

    class Codegen:
        _library_class = Library

    state = ("kernel", "object", (b"object code", b"bitcode"))
    assert object_code_load.unserialize(Codegen(), state) == ("numba's own rebuild", "kernel")


def test_is_cached_says_whether_the_disk_cache_holds_the_kernel_compiled_from_its_source(tmp_path: Path) -> None:
    (tmp_path / "lean_kernel_probe.py").write_text(_MODULE)
    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(repo)]),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}
    probe = ("import json; import numpy as np; import lean_kernel_probe as m; from pdr.filters.compiled import "
             "is_cached; before = is_cached(m.ratios); m.ratios(np.arange(3.0), 4); "
             "print(json.dumps([before, is_cached(m.ratios)]))")
    assert python_json(probe, env=env) == [False, True]      # compiled in this process, then kept
    assert python_json(probe, env=env) == [True, True]       # the next process finds it
    # An edited source is not the kernel in the cache.
    (tmp_path / "lean_kernel_probe.py").write_text(_MODULE.replace("out[i] = x[i] / d", "out[i] = x[i] / d + 0.0"))
    assert python_json(probe, env=env) == [False, True]
    from pdr.filters.compiled import is_cached
    assert is_cached(len) is False                           # not a kernel at all
