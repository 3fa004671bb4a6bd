"""Registry look-ups for reader tests, skipped while a registered reader module is not written yet."""

from __future__ import annotations

from pathlib import Path

import pytest

from pdr.io import registry
from pdr.recording import Recording


def detect_or_skip(path: Path) -> str:
    try:
        return registry.detect_format(path)
    except ModuleNotFoundError as exc:
        pytest.skip(f"reader module not available yet: {exc.name}")


def read_or_skip(path: Path) -> Recording:
    try:
        return registry.read_recording(path)
    except ModuleNotFoundError as exc:
        pytest.skip(f"reader module not available yet: {exc.name}")
