"""What a speed figure depends on besides the code: the interpreter, the numerical libraries and the machine.

The benchmarks (``pdr bench phone``, ``python -m pdr.evaluation.foot_speed``) print it with their figures, so
figures from different sessions or machines can be compared.
"""

from __future__ import annotations

import os
import platform
from importlib.metadata import PackageNotFoundError, version
from typing import Any

#: Libraries whose versions the compiled kernels' and the vectorised code's speed depend on.
LIBRARIES = ("numpy", "numba", "llvmlite", "scipy")


def environment() -> dict[str, Any]:
    """What a speed figure depends on besides the code: interpreter, numerical libraries, machine."""
    libs: dict[str, str | None] = {}
    for name in LIBRARIES:
        try:
            libs[name] = version(name)
        except PackageNotFoundError:
            libs[name] = None
    return {"python": platform.python_version(), **libs, "machine": platform.machine(),
            "system": platform.system(), "cpus": os.cpu_count()}


def environment_line(env: dict[str, Any] | None = None) -> str:
    """One line for a benchmark's printout, e.g. ``Python 3.11.9, numpy 2.1.3, numba 0.60.0, ...; Linux x86_64,
    2 CPUs``.
    """
    e = env or environment()
    libs = ", ".join(f"{k} {e[k]}" for k in LIBRARIES if e.get(k))
    return f"Python {e['python']}, {libs}; {e['system']} {e['machine']}, {e['cpus']} CPUs"
