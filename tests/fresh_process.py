"""Run Python code in a fresh interpreter and read what it prints as JSON: the tests of what a process imports."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Mapping
from typing import Any


def python_json(code: str, timeout_s: float = 120.0, env: Mapping[str, str] | None = None) -> Any:
    """The JSON value that ``code``, run by ``python -c`` in a new process (with the environment ``env``, else this
    one's), prints (the process must succeed).
    """
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=timeout_s,
                         env=None if env is None else dict(env))
    return json.loads(out.stdout)
