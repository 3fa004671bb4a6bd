"""Which reader takes a given path: explicit list of reader modules, tried in order.

A zip that no reader takes as it is (a reader of folders only, such as a MobiFall trial or a driving trip, or a
zip of one log file) is read from its content: unpacked into a temporary folder (:func:`unzipped`: the zip's one top
folder, its files flat under the zip's name, or the one file it holds), detected and read there, and the
recording's names then point at the zip (:func:`relocated`), never at the temporary folder.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

from pdr.errors import InputError, UnknownFormatError
from pdr.io import notices
from pdr.io.bundle import is_zip, starts_with
from pdr.io.gz import GZIP_MAGIC
from pdr.io.matfile import is_mat
from pdr.io.matfile import load as load_mat
from pdr.io.text import read_bytes
from pdr.recording import Recording
from pdr.units import check_ranges

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

#: The end of the message of a log no reader recognises: how the command line forces a format. Another front end
#: (the service's upload form field ``format``) replaces it with its own way.
FORCE_FORMAT_HINT = "pass --format to force one"


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


class UnrecognisedLogError(UnknownFormatError):
    """No reader recognises the input, nor sees a log of its format lacking something (``near_miss``)."""


def detect_format(path: str | Path) -> str:
    """Name of the format of ``path``; :class:`UnknownFormatError` if no reader recognises it."""
    return str(_detect(Path(path)).FORMAT)


def _check_path(p: Path) -> None:
    """:class:`InputError` unless ``p`` is a file or a folder: a device, pipe or socket is no log (``/dev/zero`` would
    be read without end, a named pipe would wait for a writer).
    """
    if not p.exists():
        raise InputError("a symbolic link that leads nowhere (a loop, or its target is missing)" if p.is_symlink()
                         else "no such file or folder", source=str(p))
    if not (p.is_file() or p.is_dir()):
        raise InputError("not a regular file or folder (a device, pipe or socket): no log is read from it",
                         source=str(p))


def _detect(p: Path) -> ModuleType:
    """The reader module of ``p`` (:func:`detect_format`). The readers are imported in their sniffing order up to the
    first that recognises ``p``: an IPIN log does not import the eleven readers after it (7-11 ms of a process).
    """
    _check_path(p)
    for name in READER_MODULES:
        module = importlib.import_module(name)
        if module.sniff(p):
            return module
    if p.is_file() and is_zip(p):
        with unzipped(p) as inner:
            for module in _modules():
                if module.sniff(inner):
                    return module
    if p.is_file() and (p.name.endswith(".gz") or starts_with(p, GZIP_MAGIC)):
        read_bytes(p)       # a gzip damaged at its start, or a plain file named .gz: InputError naming it
    if is_mat(p):
        load_mat(p)         # a MATLAB file no reader recognised may be one cut short: InputError naming it
    if p.is_file() and p.stat().st_size == 0:      # no format to force either: say what it is
        raise UnrecognisedLogError("an empty file (0 bytes): no log in it", source=str(p))
    if p.is_dir() and not any(not c.name.startswith(".") for c in p.iterdir()):
        raise UnrecognisedLogError("an empty folder: no log in it", source=str(p))
    with notices.collecting() as notes:
        for module in _modules():
            # A reader may recognise a log of its format that lacks what it needs (``near_miss``: why, or None).
            why = module.near_miss(p) if hasattr(module, "near_miss") else None
            if why:
                raise _with_notices(UnknownFormatError(f"not a readable log: {why}", source=str(p)), notes)
    raise UnrecognisedLogError(
        "not a supported log format (supported: " + ", ".join(format_names()) + "); " + FORCE_FORMAT_HINT,
        source=str(p))


#: At most this many entries of a folder are sniffed for :func:`_logs_in`.
_MAX_LISTED = 50
#: How many folder levels :func:`_logs_in` looks down for logs (a dataset's ``logfiles/``, ``sub2/ADL/WAL/``).
_MAX_DEPTH = 3


def _logs_in(folder: Path) -> list[Path]:
    """The entries a reader recognises among those of ``folder`` (files and sub-folders, the first
    :data:`_MAX_LISTED` by name), else among those of its sub-folders, and so on down to :data:`_MAX_DEPTH` levels
    (at most :data:`_MAX_LISTED` entries sniffed per level): the first level that holds any.
    """
    level = [folder]
    for _ in range(_MAX_DEPTH):
        entries = [c for f in level for c in sorted(f.iterdir()) if not c.name.startswith(".")][:_MAX_LISTED]
        found = [c for c in entries if any(m.sniff(c) for m in _modules())]
        if found:
            return found
        level = [c for c in entries if c.is_dir()]
    return []


def read_recording(path: str | Path, format: str | None = None) -> Recording:
    """Read a log into a :class:`Recording`, detecting its format unless ``format`` is given. A gzip file or member
    cut short is read as far as it decompresses, and a folder member that is no file (a folder, a named pipe, a link
    that loops) is not read, each with a warning naming it first (:mod:`pdr.io.notices`), or said in the error when
    the log is refused.
    A sensor value beyond any sensor's range is an :class:`InputError` (:func:`pdr.units.check_ranges`).
    """
    p = Path(path)
    try:
        module: ModuleType | None = _detect(p) if format is None else _by_name().get(format)
    except UnrecognisedLogError:
        logs = _logs_in(p) if p.is_dir() else []
        if logs:    # a folder of several logs (a dataset's trials), not one log: --format would not help either
            shown = ", ".join(str(c.relative_to(p)) for c in logs[:3]) + (", ..." if len(logs) > 3 else "")
            many = f"{len(logs)}{'+' if len(logs) >= _MAX_LISTED else ''}"
            raise UnknownFormatError(f"not one log but a folder that holds logs ({many} of its entries: {shown}); "
                                     "pass one of them", source=str(p)) from None
        raise
    if module is None:
        raise UnknownFormatError(f"unknown format '{format}' (supported: {', '.join(format_names())})",
                                 source=str(p))
    _check_path(p)
    with notices.collecting() as notes:
        try:
            rec = _read(module, p)
        except InputError as exc:
            raise _with_notices(exc, notes) from None
    check_ranges(rec, str(p))
    return dataclasses.replace(rec, warnings=(*dict.fromkeys(notes), *rec.warnings)) if notes else rec


def _with_notices(exc: InputError, notes: list[str]) -> InputError:
    """``exc`` with the notices of :mod:`pdr.io.notices` added to its message (e.g. the member it lacks is there, but
    a folder), or ``exc`` itself when there are none.
    """
    if not notes:
        return exc
    return type(exc)(f"{exc.message} ({'; '.join(dict.fromkeys(notes))})", source=exc.source, line=exc.line,
                     field=exc.field)


def _read(module: ModuleType, p: Path) -> Recording:
    """``module``'s recording of ``p``, from the content of a zip that the module reads as a folder or file. A stream
    that the data model refuses (a value or time the reader's own checks let through) is said naming ``p``.
    """
    try:
        return _read_module(module, p)
    except InputError as exc:
        kind = re.fullmatch(r"stream '(\w+)'", exc.source or "")
        if kind is None:
            raise
        raise InputError(exc.message, source=str(p), line=exc.line, field=exc.field or kind[1]) from None


def _read_module(module: ModuleType, p: Path) -> Recording:
    if p.is_file() and is_zip(p) and not module.sniff(p):
        with unzipped(p) as inner:
            if module.sniff(inner):  # a reader of folders (or of the one file zipped): read the content
                return relocated(module.read(inner), inner, str(p))
    rec: Recording = module.read(p)
    return rec


@contextmanager
def unzipped(path: Path) -> Iterator[Path]:
    """The content of a zip in a temporary folder: its one top folder, else a folder named as the zip holding its
    files, or the one file it holds. A member whose name would leave the folder is skipped.
    """
    with tempfile.TemporaryDirectory(prefix="pdr-unzip-") as tmp:
        root = Path(tmp) / (path.name[:-4] if path.name.lower().endswith(".zip") else path.stem)
        try:
            with zipfile.ZipFile(path) as zf:
                for info in zf.infolist():
                    name = info.filename
                    if name.startswith(("__MACOSX/", "/")) or ".." in Path(name).parts:
                        continue
                    zf.extract(info, root)
        except (zipfile.BadZipFile, OSError, EOFError, ValueError, zlib.error) as exc:
            raise InputError(f"not a readable zip archive ({exc})", source=str(path)) from None
        entries = list(root.iterdir()) if root.is_dir() else []
        yield entries[0] if len(entries) == 1 else root


def relocated(recording: Recording, folder: Path, name: str, *, forget: str | None = None) -> Recording:
    """``recording`` read from ``folder`` with that folder's path replaced by ``name`` in its source, warnings and
    metadata (e.g. a temporary copy of an upload or of a zip's content, named by the original).

    With ``forget`` (a temporary folder's name), a metadata string or device name that still holds it after the
    renaming (a name a reader took from the folder itself) is emptied, and a warning names ``name`` instead.
    """
    def rename(text: str) -> str:
        text = text.replace(str(folder), name)
        return "" if forget and forget in text else text

    def walk(value: Any) -> Any:
        if isinstance(value, str):
            return rename(value)
        if isinstance(value, dict):
            return {k: walk(v) for k, v in value.items()}
        if isinstance(value, list | tuple):
            return type(value)(walk(v) for v in value)
        return value

    def warning(text: str) -> str:
        text = text.replace(str(folder), name)
        return text.replace(forget, name) if forget else text

    device = recording.device
    return dataclasses.replace(
        recording, source=rename(recording.source) or name, warnings=tuple(warning(w) for w in recording.warnings),
        meta=walk(dict(recording.meta)),
        device=dataclasses.replace(device, model=rename(device.model), device_id=rename(device.device_id)))
