"""pdr.filters.runtime_cache and the extensions' deferral of pdr.filters.compiled: a process whose kernels load from
the cache takes numba's runtime library from the machine code an earlier process kept, and loads no extensions;
kernels that make and free arrays compute the same."""

from __future__ import annotations

import os
import pickle
import textwrap
from pathlib import Path

from tests.fresh_process import python_json

_MODULE = textwrap.dedent('''
    import numpy as np

    from pdr.filters.compiled import kernel


    @kernel
    def cumulative(x):
        out = np.empty(x.size)          # made by numba's runtime, freed through its reference counting
        total = 0.0
        for i in range(x.size):
            total += x[i]
            out[i] = total
        return out
''')

_RUN = ("import json; import numpy as np; import numba.core.entrypoints as ep; import runtime_probe as m; "
        "from numba.core.runtime import rtsys; from pdr.filters.runtime_cache import runtime_file; "
        "values = [m.cumulative(np.arange(float(n))).tolist() for n in (0, 1, 5, 1000)]; "
        "print(json.dumps({'values': values, 'hits': sum(m.cumulative.stats.cache_hits.values()), "
        "'runtime': type(rtsys.library).__name__, 'extensions_loaded': ep._already_initialized, "
        "'file': str(runtime_file(rtsys.library.codegen, m.cumulative._cache._cache_path))}))")


def _env(tmp_path: Path) -> dict[str, str]:
    (tmp_path / "runtime_probe.py").write_text(_MODULE)
    repo = Path(__file__).resolve().parents[3]
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(repo)]),
            "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}


def test_the_runtime_is_kept_by_the_first_process_and_loaded_by_the_next(tmp_path: Path) -> None:
    env = _env(tmp_path)
    compiled = python_json(_RUN, env=env)
    loaded = python_json(_RUN, env=env)
    expected = [[], [0.0], [0.0, 1.0, 3.0, 6.0, 10.0], [float(k * (k + 1) // 2) for k in range(1000)]]
    assert compiled["values"] == loaded["values"] == expected
    assert Path(compiled["file"]).is_file() and compiled["file"] == loaded["file"]
    assert compiled["hits"] == 0 and loaded["hits"] == 1
    assert not compiled["runtime"].startswith("Lazy")          # compiled by LLVM, its object code written
    assert loaded["runtime"].startswith("Lazy")                # rebuilt from that object code
    # numba's extensions are loaded before a compilation, not for a load from the cache.
    assert compiled["extensions_loaded"] and not loaded["extensions_loaded"]


def test_a_damaged_runtime_file_is_compiled_and_written_again(tmp_path: Path) -> None:
    env = _env(tmp_path)
    first = python_json(_RUN, env=env)
    path = Path(first["file"])
    # Not a pickle; a pickle of the right shape whose code is no object code nor bitcode; an ELF header and nothing.
    for damaged in (b"not a pickle", pickle.dumps(("nrt", "object", (b"garbage", b"garbage"))),
                    pickle.dumps(("nrt", "object", (b"\x7fELF\x02\x01" + bytes(100), b"garbage")))):
        path.write_bytes(damaged)
        second = python_json(_RUN, env=env)
        assert second["values"] == first["values"]
        assert not second["runtime"].startswith("Lazy")
        third = python_json(_RUN, env=env)
        assert third["values"] == first["values"] and third["runtime"].startswith("Lazy")
