"""Log readers and writers: one module per format family, with autodetection.

Use :func:`read_recording` to read any supported log (file, ``.gz``, ``.zip`` or folder) and
:func:`detect_format` to ask which reader would take it. Every reader module defines

``FORMAT``
    its short name (``ipin``, ``sensor_logger``, ...);
``DESCRIPTION``
    one line for ``pdr inspect --formats``;
``sniff(path) -> bool``
    a cheap check (file name, first bytes, header) that never raises on foreign input;
``read(path) -> Recording`` (or ``read_all(path) -> list[Recording]`` for multi-device logs)
    which raises :class:`pdr.errors.InputError` naming file, line or field on bad input;

and may define

``near_miss(path) -> str | None``
    why a path that looks like its format (a trip folder's ``viagem.json``) is not one it can read (a missing
    file), said instead of the generic "not a supported log format" when no reader takes the path.
"""

from pdr.io.registry import detect_format, format_names, read_recording

__all__ = ["detect_format", "format_names", "read_recording"]
