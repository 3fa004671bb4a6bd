"""Compile (or load from numba's on-disk cache) the kernels of the processing paths before the first upload.

The first call of a numba kernel compiles it (about a minute for all of the phone path on a fresh install, on a
quiet 2-core machine); with ``cache=True`` the machine code is kept in ``NUMBA_CACHE_DIR`` and later processes load
it in well under a second. :func:`start` runs :func:`server.warmup_walk.warm_up` in a background thread, so that
``pdr serve`` answers at once and its health says ``"warming up"`` (:func:`status`) until the phone path is
compiled. Set ``NUMBA_CACHE_DIR`` (:func:`use_cache_dir`) before numba is first imported: numba reads it once.

**Two processes on a fresh cache.** When the attitude filter's UKF kernel is not in the cache yet, :func:`start`
also runs ``python -m server.warmup_walk``: the same walk with a stand-in for the attitude filter, which compiles
every other kernel (and the reader's and the classifier's) into the shared cache while this process compiles the
filter's, the critical path (:mod:`pdr.phone.warm_up` module doc). With the kernel cached, no child is started.
"""

from __future__ import annotations

import logging
import os
import subprocess
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

log = logging.getLogger(__name__)

_lock = threading.Lock()
_state: dict[str, Any] = {"state": "cold", "seconds": None, "error": None, "helper": None}

#: The module the child process runs (:func:`_start_helper`).
HELPER_MODULE = "server.warmup_walk"


def use_cache_dir(path: str | Path) -> Path:
    """Make ``path`` numba's persistent cache (``NUMBA_CACHE_DIR``) unless one is set; returns the one in use.

    Effective only before numba is imported in this process (and for child processes, which inherit it).
    """
    p = Path(os.environ.setdefault("NUMBA_CACHE_DIR", str(path)))
    p.mkdir(parents=True, exist_ok=True)
    return p


@dataclass
class _Child:
    """The warm-up's child process and the file its stderr goes to (a file, not a pipe: nothing reads it until the
    child ends, and a full pipe would stall it).
    """

    process: subprocess.Popen[bytes]
    stderr: IO[bytes]


def _start_helper() -> _Child | None:
    """``python -m server.warmup_walk`` (:func:`pdr.phone.warm_up.compile_alongside`), inheriting this process'
    environment (its ``NUMBA_CACHE_DIR``); None, logged, when there is no second core or it cannot be started (the
    warm-up then compiles alone).
    """
    from pdr.phone.warm_up import compile_alongside

    err = tempfile.TemporaryFile()
    process = compile_alongside(HELPER_MODULE, stderr=err)
    if process is None:
        err.close()
        log.warning("warm-up child process not started (one core, or no process could be started): compiling alone")
        return None
    return _Child(process, err)


def _end_helper(child: _Child) -> dict[str, Any]:
    """Wait for the child (:func:`pdr.phone.warm_up.wait_alongside`); its exit code and, if it failed, why."""
    from pdr.phone.warm_up import ALONGSIDE_WAIT_S, wait_alongside

    with child.stderr:
        out = wait_alongside(child.process)
        if out is None:
            return {"exit": None, "error": f"stopped after {ALONGSIDE_WAIT_S:g} s"}
        if child.process.returncode != 0:
            child.stderr.seek(0)
            last = child.stderr.read().decode("utf-8", "replace").strip().splitlines()[-1:]
            reason = last[0] if last else f"exit {child.process.returncode}"
            log.warning("warm-up child process failed: %s", reason)
            return {"exit": child.process.returncode, "error": reason}
    return {"exit": 0, "seconds": float(out.decode().strip() or "nan")}


def start() -> threading.Thread:
    """:func:`server.warmup_walk.warm_up` in a daemon thread, with a child process on a fresh cache (module doc);
    :func:`status` follows it.
    """
    def run() -> None:
        helper = None
        try:
            from pdr.phone.warm_up import filter_kernel_cached
            from server.warmup_walk import warm_up
            helper = None if filter_kernel_cached() else _start_helper()
            seconds = warm_up()
        except Exception as exc:  # a failed warm-up only means the first upload compiles: say so, go on
            log.warning("warm-up of the compiled kernels failed: %s", exc)
            with _lock:
                _state.update(state="ready", error=f"{type(exc).__name__}: {exc}")
            return
        finally:
            helped = None if helper is None else _end_helper(helper)
            with _lock:
                _state.update(helper=helped)
        log.info("compiled kernels ready in %.1f s%s", seconds, "" if helper is None else " (with a second process)")
        with _lock:
            _state.update(state="ready", seconds=round(seconds, 2))

    with _lock:
        _state.update(state="warming up", seconds=None, error=None, helper=None)
    thread = threading.Thread(target=run, name="pdr-warm-up", daemon=True)
    thread.start()
    return thread


def status() -> dict[str, Any]:
    """``{"state": "cold" | "warming up" | "ready", "seconds": warm-up wall time or None, "error": ..., "helper":
    None (no child process: the cache was warm) or {"exit": code, "seconds" or "error"}}``.
    """
    with _lock:
        return dict(_state)
