"""Which reader takes a given path: explicit list of reader modules, tried in order."""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

from pdr.errors import InputError, UnknownFormatError
from pdr.recording import Recording

#: Reader modules in the order they are sniffed (more specific formats first).
READER_MODULES: tuple[str, ...] = (
    "pdr.io.native",
    "pdr.io.ipin",
    "pdr.io.ms_indoor",
    "pdr.io.oxford",
    "pdr.io.tyrex",
    "pdr.io.mobifall",
    "pdr.io.driving",
    "pdr.io.pyshoe",
    "pdr.io.sensorconnect",
    "pdr.io.xio",
    "pdr.io.static_npz",
    "pdr.io.sensor_logger",
    "pdr.io.phyphox",
)


def _modules() -> list[ModuleType]:
    return [importlib.import_module(name) for name in READER_MODULES]


def _by_name() -> dict[str, ModuleType]:
    return {m.FORMAT: m for m in _modules()}


def format_names() -> list[str]:
    """Short names of every supported format."""
    return list(_by_name())


def format_descriptions() -> dict[str, str]:
    """Short name -> one-line description (the module's ``DESCRIPTION``) of every supported format."""
    return {name: str(getattr(m, "DESCRIPTION", "")) for name, m in _by_name().items()}


def detect_format(path: str | Path) -> str:
    """Name of the format of ``path``; :class:`UnknownFormatError` if no reader recognises it."""
    p = Path(path)
    if not p.exists():
        raise InputError("no such file or folder", source=str(p))
    for module in _modules():
        if module.sniff(p):
            return str(module.FORMAT)
    raise UnknownFormatError(
        "not a supported log format (supported: " + ", ".join(format_names()) + "); "
        "pass --format to force one", source=str(p))


def read_recording(path: str | Path, format: str | None = None) -> Recording:
    """Read a log into a :class:`Recording`, detecting its format unless ``format`` is given."""
    p = Path(path)
    name = format or detect_format(p)
    module = _by_name().get(name)
    if module is None:
        raise UnknownFormatError(f"unknown format '{name}' (supported: {', '.join(format_names())})",
                                 source=str(p))
    if not p.exists():
        raise InputError("no such file or folder", source=str(p))
    rec: Recording = module.read(p)
    return rec
