"""A small progress bar for the CLI's long commands: one line on stderr, and nothing unless stderr is a terminal.

Results go to stdout and stay there; the bar is for a person watching (``pdr eval ipin DIR``, ``pdr allan LOG``,
``pdr simulate ...``); :meth:`Progress.write` prints a message line (a skipped file) above it. Piped, redirected
or run by CI (stderr not a TTY) the bar writes nothing, so logs and captured output stay clean. tqdm would do the
same; the project does not depend on it for one line.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterable, Iterator
from types import TracebackType
from typing import TextIO, TypeVar

T = TypeVar("T")

#: Width of the bar in characters, and the shortest interval between two redraws (s).
BAR_WIDTH = 24
REDRAW_S = 0.2
#: Interval (s) at which a drawn bar is redrawn on its own, so that its clock runs during a long stage.
TICK_S = 1.0


class Progress:
    """``label [######..........]  3/10  note  12 s`` on ``stream`` (default stderr), redrawn in place.

    Parameters
    ----------
    total
        Number of units of work (files, stages); at least 1.
    label
        What is being done, e.g. ``"eval ipin"``.
    stream
        Where to draw; default ``sys.stderr`` at construction.
    enabled
        Force drawing on or off; default: only when ``stream`` is a terminal.
    tick_s
        A drawn bar is also redrawn every ``tick_s`` seconds by a daemon thread (its elapsed time goes on while one
        stage takes minutes, e.g. ``pdr bench load``'s upload); 0: only when the work advances.
    """

    def __init__(self, total: int, label: str, stream: TextIO | None = None, enabled: bool | None = None,
                 tick_s: float = TICK_S) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = bool(isatty and isatty()) if enabled is None else enabled
        self.done = 0
        self.note = ""
        self._t0 = time.monotonic()
        self._last = -1.0
        self._width = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._draw(force=True)
        self._ticker: threading.Thread | None = None
        if self.enabled and tick_s > 0:
            self._ticker = threading.Thread(target=self._tick, args=(float(tick_s),), name="pdr-progress",
                                            daemon=True)
            self._ticker.start()

    def advance(self, n: int = 1, note: str | None = None) -> None:
        """Count ``n`` more units done; ``note`` (e.g. the next file's name) replaces the previous one."""
        self.done = min(self.done + n, self.total)
        if note is not None:
            self.note = note
        self._draw(force=self.done == self.total)

    def set_note(self, note: str) -> None:
        """Say what is being worked on now, without counting progress."""
        self.note = note
        self._draw(force=self.done == 0)  # the first note shows at once, later ones at the redraw rate

    def write(self, text: str) -> None:
        """Print ``text`` as a line of its own on the bar's stream, piped or not (a warning, a skipped file); a drawn
        bar is cleared first and drawn again under it, so the two never share a line.
        """
        with self._lock:
            if self.enabled and self._width:
                self.stream.write("\r" + " " * self._width + "\r")
                self._width = 0
            self.stream.write(text + "\n")
            self.stream.flush()
        self._draw(force=True)

    def close(self) -> None:
        """Clear the line, so that what is printed next starts on a clean line; nothing is drawn after."""
        self._stop.set()
        with self._lock:
            if self.enabled and self._width:
                self.stream.write("\r" + " " * self._width + "\r")
                self.stream.flush()
                self._width = 0
            self.enabled = False
        if self._ticker is not None and self._ticker is not threading.current_thread():
            self._ticker.join(timeout=1.0)

    def line(self) -> str:
        """The text of the bar as it is drawn now."""
        filled = round(BAR_WIDTH * self.done / self.total)
        elapsed = time.monotonic() - self._t0
        note = f"  {self.note[:40]}" if self.note else ""
        return (f"{self.label} [{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {self.done}/{self.total}{note}"
                f"  {elapsed:.0f} s")

    def _tick(self, every_s: float) -> None:
        while not self._stop.wait(every_s):
            self._draw(force=True)

    def _draw(self, force: bool) -> None:
        with self._lock:   # the ticker thread and the worker draw the same line
            if not self.enabled:
                return
            now = time.monotonic()
            if not force and now - self._last < REDRAW_S:
                return
            self._last = now
            text = self.line()
            pad = max(self._width - len(text), 0)
            self.stream.write("\r" + text + " " * pad)
            self.stream.flush()
            self._width = len(text)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def each(items: Iterable[T], label: str, total: int | None = None, name: bool = True) -> Iterator[T]:
    """Yield ``items`` while a :class:`Progress` counts them (``note``: the item's name, for paths)."""
    seq = list(items) if total is None else items
    count = len(seq) if total is None else total  # type: ignore[arg-type]
    with Progress(count, label) as bar:
        for item in seq:
            if name:
                bar.set_note(str(getattr(item, "name", item)))
            yield item
            bar.advance()
