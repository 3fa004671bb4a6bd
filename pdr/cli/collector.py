"""Python's cyclic garbage collector paused where a command makes many long-lived objects and little cyclic garbage
(:func:`collection_paused`), and kept from the interpreter's last collections at exit (:func:`freeze_at_exit`).

A collection runs after every 700 net new container objects and walks the young ones; every tenth a middle
generation, and now and then all of them. Loading a command's modules (numba's typing and target registries, the
pipeline's classes) and tracking a recording (a history of arrays, an event and a row per step) make hundreds of
thousands of objects that stay alive to the end: the collector walks them over and over and frees next to nothing.
In a one-hour ``pdr track`` process that was 0.13-0.15 s of CPU in about 290 collections. Reference counting still
frees every object that is not part of a cycle at once; cycles made inside the block are freed by the first
collection after it.

That first collection walks every object the block made, survivors included: 25-40 ms after ``pdr`` loads a
command's modules. :func:`pdr.cli.main` moves them into the permanent generation (:func:`gc.freeze`, which also
restarts the collector's count) before the pause ends, so that no collection walks them while the command runs,
and back into the oldest generation (:func:`gc.unfreeze`) when it returns: a process that runs several commands
(the tests) collects them as before.

At exit the interpreter collects everything once more (and again while it tears the modules down), walking every
object still alive only to free memory the process returns anyway: in a one-hour ``pdr track`` process about 0.2 s of
CPU after the command had finished. Objects moved into the permanent generation (:func:`gc.freeze`) are not walked.
"""

from __future__ import annotations

import atexit
import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collection_paused() -> Iterator[None]:
    """No automatic cyclic collection inside the block; the collector's former state (on or off) is restored after."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


_freeze_registered = False


def freeze_at_exit() -> None:
    """Move every object into the collector's permanent generation when the process exits, before the interpreter's
    own last collections (an :mod:`atexit` handler, registered once; handlers registered later run before it).
    """
    global _freeze_registered
    if not _freeze_registered:
        atexit.register(gc.freeze)
        _freeze_registered = True
