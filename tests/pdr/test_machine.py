"""What a benchmark prints besides its figures (pdr.machine)."""

from __future__ import annotations

import os
import platform

import numpy as np

from pdr.machine import LIBRARIES, environment, environment_line


def test_environment_is_this_interpreter_and_machine() -> None:
    env = environment()
    assert env["python"] == platform.python_version()
    assert env["numpy"] == np.__version__
    assert env["cpus"] == os.cpu_count() and env["machine"] == platform.machine()
    assert set(LIBRARIES) <= set(env)


def test_line_names_each_installed_library_and_skips_absent_ones() -> None:
    env = {"python": "3.11.9", "numpy": "2.1.3", "numba": None, "llvmlite": "0.43.0", "scipy": "1.14.1",
           "machine": "x86_64", "system": "Linux", "cpus": 2}
    assert environment_line(env) == ("Python 3.11.9, numpy 2.1.3, llvmlite 0.43.0, scipy 1.14.1; Linux x86_64, "
                                     "2 CPUs")
    assert environment_line().startswith(f"Python {platform.python_version()}, numpy {np.__version__}")
