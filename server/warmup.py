"""Compile (or load from numba's on-disk cache) the kernels of the processing paths before the first upload.

The first call of a numba kernel compiles it (about 100 s for all of the library on a fresh install); with
``cache=True`` the machine code is kept in ``NUMBA_CACHE_DIR`` and later processes load it in well under a
second. :func:`start` runs :func:`warm_up` in a background thread, so that ``pdr serve`` answers at once and
its health says ``"warming up"`` (:func:`status`) until the phone path is compiled. Set ``NUMBA_CACHE_DIR``
(:func:`use_cache_dir`) before numba is first imported: numba reads it once.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

_lock = threading.Lock()
_state: dict[str, Any] = {"state": "cold", "seconds": None, "error": None}

#: A short hand-held walk: straight, a turn, straight, so that steps, headings and the smoother all run.
_WALK = {"name": "warm_up", "placement": "hand", "start": {"position_m": [0, 0, 0], "heading_deg": 0},
         "rates_hz": {"acc": 100.0, "gyro": 100.0, "mag": 100.0, "baro": 10.0},
         "segments": [{"type": "stand", "duration_s": 2.0}, {"type": "walk", "duration_s": 12.0, "speed_mps": 1.3},
                      {"type": "turn", "angle_deg": 90, "duration_s": 2.0},
                      {"type": "walk", "duration_s": 12.0, "speed_mps": 1.3}]}
#: A few GetSensorData records, for the text reader's compiled number parser.
_IPIN_TEXT = (b"% 'GetSensorData'\nACCE;0.05;100.000;0.1;0.2;9.8;3\nACCE;0.07;100.020;0.1;0.2;9.8;3\n"
              b"POSI;0.08;1;49.4611;11.1110;0;100\n")


def use_cache_dir(path: str | Path) -> Path:
    """Make ``path`` numba's persistent cache (``NUMBA_CACHE_DIR``) unless one is set; returns the one in use.

    Effective only before numba is imported in this process (and for child processes, which inherit it).
    """
    p = Path(os.environ.setdefault("NUMBA_CACHE_DIR", str(path)))
    p.mkdir(parents=True, exist_ok=True)
    return p


def warm_up(extra: Sequence[Callable[[Any], object]] = ()) -> float:
    """Run the phone path once on a short simulated walk (pipeline, smoother, reader) and each of ``extra`` on
    that recording; returns the wall time in s.
    """
    import tempfile

    from pdr.io import ipin
    from pdr.phone.heading_smoother import smooth_track
    from pdr.phone.pipeline import PdrPipeline, track_rows
    from pdr.sim import simulate

    t0 = time.perf_counter()
    rec = simulate(_WALK, 0)
    smooth_track(track_rows(PdrPipeline().run(rec)))
    with tempfile.TemporaryDirectory(prefix="pdr-warm-up-") as tmp:
        p = Path(tmp) / "warm_up.txt"
        p.write_bytes(_IPIN_TEXT)
        ipin.read(p)
    for f in extra:
        f(rec)
    return time.perf_counter() - t0


def start(extra: Sequence[Callable[[Any], object]] = ()) -> threading.Thread:
    """:func:`warm_up` in a daemon thread; :func:`status` follows it."""
    def run() -> None:
        try:
            seconds = warm_up(extra)
        except Exception as exc:  # a failed warm-up only means the first upload compiles: say so, go on
            log.warning("warm-up of the compiled kernels failed: %s", exc)
            with _lock:
                _state.update(state="ready", error=f"{type(exc).__name__}: {exc}")
            return
        log.info("compiled kernels ready in %.1f s", seconds)
        with _lock:
            _state.update(state="ready", seconds=round(seconds, 2))

    with _lock:
        _state.update(state="warming up", seconds=None, error=None)
    thread = threading.Thread(target=run, name="pdr-warm-up", daemon=True)
    thread.start()
    return thread


def status() -> dict[str, Any]:
    """``{"state": "cold" | "warming up" | "ready", "seconds": warm-up wall time or None, "error": ...}``."""
    with _lock:
        return dict(_state)
