"""Progress bars for the CLI's long commands, drawn by ``rich.progress`` on stderr, and nothing unless it is a terminal.

Results go to stdout and stay there; the bar is for a person watching (``pdr eval ipin DIR``, ``pdr allan LOG``,
``pdr simulate ...``); :meth:`Progress.write` prints a message line (a skipped file) above it. Piped, redirected
or run by CI (stderr not a TTY) the bar writes nothing, so logs and captured output stay clean. The decision rests
on ``stream.isatty()`` alone: rich's ``FORCE_COLOR`` / ``TTY_COMPATIBLE`` do not make a pipe draw a bar.

rich is imported only when a bar is drawn (a terminal), so ``pdr --help`` and piped runs do not pay its import.
"""

from __future__ import annotations

import io
import sys
import time
from collections.abc import Iterable, Iterator, Sequence, Sized
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, TextIO, TypeVar

if TYPE_CHECKING:
    from rich.progress import Progress as RichProgress
    from rich.progress import TaskID

    from pdr.recording import Recording

T = TypeVar("T")

#: Width of the bar in characters, and the shortest interval between two redraws on advance (s).
BAR_WIDTH = 24
REDRAW_S = 0.2
#: Interval (s) at which a drawn bar is redrawn on its own, so that its clock runs during a long stage.
TICK_S = 1.0
#: Longest note shown (characters).
NOTE_CHARS = 40


class Progress:
    """``label ━━━━━━╺━━━━━  3/10  note  0:00:12`` on ``stream`` (default stderr), redrawn in place by rich.

    Parameters
    ----------
    total
        Number of units of work (files, stages), at least 1; ``None`` when unknown (a pulsing bar, ``3/?``).
    label
        What is being done, e.g. ``"eval ipin"``.
    stream
        Where to draw; default ``sys.stderr`` at construction.
    enabled
        Force drawing on or off; default: only when ``stream`` is a terminal.
    tick_s
        A drawn bar is also redrawn every ``tick_s`` seconds by rich's refresh thread (its elapsed time goes on while
        one stage takes minutes, e.g. ``pdr bench load``'s upload); 0: only when the work advances.
    """

    def __init__(self, total: int | None, label: str, stream: TextIO | None = None, enabled: bool | None = None,
                 tick_s: float = TICK_S) -> None:
        self.total = None if total is None else max(int(total), 1)
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = bool(isatty and isatty()) if enabled is None else enabled
        self.done = 0
        self.note = ""
        self._t0 = time.monotonic()
        self._last = -float("inf")
        self._bar: RichProgress | None = None
        self._task: TaskID | None = None
        if self.enabled:
            self._bar, self._task = self._rich(self.stream, force_terminal=True, tick_s=float(tick_s))
            self._bar.start()

    def advance(self, n: int = 1, note: str | None = None) -> None:
        """Count ``n`` more units done; ``note`` (e.g. the next file's name) replaces the previous one."""
        self.done = self.done + n if self.total is None else min(self.done + n, self.total)
        if note is not None:
            self.note = note
        self._show(force=self.done == self.total)

    def set_note(self, note: str) -> None:
        """Say what is being worked on now, without counting progress."""
        self.note = note
        self._show(force=self.done == 0)  # the first note shows at once, later ones at the redraw rate

    def write(self, text: str) -> None:
        """Print ``text`` as a line of its own on the bar's stream, piped or not (a warning, a skipped file); a drawn
        bar is moved under it, so the two never share a line.
        """
        if self._bar is not None:
            from rich.text import Text

            self._bar.console.print(Text(text), soft_wrap=True)   # Text: no markup, emoji or highlighting
        else:
            self.stream.write(text + "\n")
            self.stream.flush()

    def close(self) -> None:
        """Clear the bar, so that what is printed next starts on a clean line; nothing is drawn after."""
        bar, self._bar = self._bar, None
        self.enabled = False
        if bar is not None:
            from rich.file_proxy import FileProxy

            if isinstance(sys.stderr, FileProxy):   # redirected by the bar (_rich): an unfinished line is printed
                sys.stderr.flush()
            bar.stop()   # stops rich's refresh thread, gives sys.stderr back; transient: the bar's line is erased

    def line(self) -> str:
        """The text of the bar as it is drawn now (drawn or not), without colours."""
        bar, task = self._rich(io.StringIO(), force_terminal=False, tick_s=0)
        bar.update(task, completed=self.done, note=self.note[:NOTE_CHARS])
        from rich.console import Console

        # Rendered as on a terminal (a bar without colours leaves its undone part blank), kept as plain text.
        console = Console(file=io.StringIO(), width=200, force_terminal=True, color_system="standard", record=True)
        console.print(bar.get_renderable())
        return console.export_text(styles=False).rstrip()

    def _rich(self, stream: TextIO, force_terminal: bool, tick_s: float) -> tuple[RichProgress, TaskID]:
        """A rich progress display of this bar on ``stream`` (not started) and its one task, clocked from ``_t0``."""
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
        from rich.progress import Progress as RichProgress

        console = Console(file=stream, force_terminal=force_terminal, force_jupyter=False)
        bar = RichProgress(TextColumn("{task.description}", markup=False), BarColumn(bar_width=BAR_WIDTH),
                           MofNCompleteColumn(), TextColumn("{task.fields[note]}", markup=False),
                           TimeElapsedColumn(), console=console, auto_refresh=tick_s > 0,
                           refresh_per_second=1.0 / tick_s if tick_s > 0 else 1.0, transient=True,
                           # stdout is the command's, untouched; lines others write to sys.stderr while the bar
                           # is drawn on it (a reader's warning) are printed above the bar instead of into its line.
                           redirect_stdout=False, redirect_stderr=stream is sys.stderr)
        task = bar.add_task(self.label, total=self.total, note="")
        bar.tasks[0].start_time = self._t0   # elapsed time since this bar was made, as time.monotonic
        return bar, task

    def _show(self, force: bool) -> None:
        bar, task = self._bar, self._task
        if bar is None or task is None:
            return
        bar.update(task, completed=self.done, note=self.note[:NOTE_CHARS])
        now = time.monotonic()
        if force or now - self._last >= REDRAW_S:
            self._last = now
            bar.refresh()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def each(items: Iterable[T], label: str, total: int | None = None, name: bool = True) -> Iterator[T]:
    """Yield ``items`` while a :class:`Progress` counts them (``note``: the item's name, for paths).

    ``total`` defaults to ``len(items)`` when it has one; an iterator of unknown length is not consumed ahead, its
    bar counts without a total.
    """
    count = total if total is not None else len(items) if isinstance(items, Sized) else None
    with Progress(count, label) as bar:
        for item in items:
            if name:
                bar.set_note(str(getattr(item, "name", item)))
            yield item
            bar.advance()


def each_recording(paths: Sequence[Path], label: str, rows: list[dict[str, Any]], key: str = "file"
                   ) -> Iterator[tuple[Path, Recording]]:
    """Yield each readable log of ``paths`` with its recording while a :class:`Progress` counts them; a log that
    cannot be read (:class:`pdr.errors.InputError`) becomes the row ``{key: its name, "error": why}`` in ``rows``
    (the evaluations' per-file output) and the loop goes on.
    """
    from pdr.errors import InputError
    from pdr.io import read_recording
    for path in each(paths, label):
        try:
            rec = read_recording(path)
        except InputError as exc:
            rows.append({key: path.name, "error": str(exc)})
            continue
        yield path, rec
