"""Notices of what the readers' shared helpers meet in a log's files, for the recording's warnings.

A gzip cut short (:func:`pdr.io.gz.gunzip`) or a folder member that is no file (:func:`pdr.io.text.is_member_file`)
is met below the reader, which does not see it. Within :func:`collecting` (:func:`pdr.io.registry.read_recording`
reads every log so) such a helper appends a notice naming the file; the registry puts the notices first among the
recording's warnings, or adds them to the error when the log is refused. Outside, a cut gzip is refused and a skipped
member is not said.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

#: The notices being collected (None: none are).
_NOTES: ContextVar[list[str] | None] = ContextVar("reading_notices", default=None)


@contextmanager
def collecting() -> Iterator[list[str]]:
    """Within: notices of the helpers are appended to the yielded list."""
    notes: list[str] = []
    token = _NOTES.set(notes)
    try:
        yield notes
    finally:
        _NOTES.reset(token)


def active() -> list[str] | None:
    """The list notices go to, or None outside :func:`collecting`."""
    return _NOTES.get()


def note(text: str) -> None:
    """Append a notice when they are collected (else nothing)."""
    notes = _NOTES.get()
    if notes is not None:
        notes.append(text)
