"""Shared fixtures: location of the real datasets (``../shared/data``), skipped cleanly when absent."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from types import ModuleType

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("PDR_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))
# One numba cache for every server the tests start: `pdr serve` would otherwise compile all kernels afresh into each
# test's new data directory (server.warmup). Set before numba is imported; inherited by the child processes.
os.environ.setdefault("NUMBA_CACHE_DIR", str(REPO_ROOT / ".pytest_cache" / "numba"))


def load_tool(name: str) -> ModuleType:
    """The script ``tools/<name>.py`` as a module (the tools folder is not a package)."""
    spec = importlib.util.spec_from_file_location(name, REPO_ROOT / "tools" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def data_path(*parts: str) -> Path:
    """Path inside the shared datasets; skips the calling test when it does not exist."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"shared dataset not available: {p}")
    return p


@pytest.fixture
def shared_data() -> Path:
    """Root of ../shared/data (test skipped when absent)."""
    return data_path()
