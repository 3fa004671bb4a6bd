"""The CLI's progress bar (rich): drawn on a terminal's stderr, silent on a pipe, never on stdout.

stderr is a real pseudo-terminal (``pty``) or a real pipe, read from the other end; :func:`screen` replays what a
terminal shows after the bytes written to it.
"""

from __future__ import annotations

import hashlib
import json
import os
import pty
import re
import shutil
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from pdr.cli import main, progress
from pdr.cli.progress import Progress
from tests.conftest import REPO_ROOT

SIM = REPO_ROOT / "mobile_logs" / "sim"
_CSI = re.compile(r"\x1b\[(\??)([\d;]*)([A-Za-z])")
_SGR = re.compile(r"\x1b\[[\d;]*m")


def plain(raw: str) -> str:
    """``raw`` without its colours."""
    return _SGR.sub("", raw)


def screen(raw: str) -> list[str]:
    """The lines a terminal shows after ``raw`` (colours dropped), trailing blank lines removed.

    Handles the control sequences of rich's live display (carriage return, line feed, erase in line, cursor up,
    cursor shown/hidden, colours); any other fails the test, since it could not be replayed.
    """
    lines, row, col = [""], 0, 0
    i = 0
    while i < len(raw):
        m = _CSI.match(raw, i)
        if m:
            private, n, code = m.groups()
            if private or code == "m":
                pass
            elif code == "K":
                lines[row] = "" if n == "2" else lines[row][:col] if n in ("", "0") else lines[row][col:]
            elif code == "A":
                row = max(row - int(n or 1), 0)
            else:
                raise AssertionError(f"control sequence {m.group()!r} not replayed")
            i = m.end()
            continue
        ch = raw[i]
        if ch == "\r":
            col = 0
        elif ch == "\n":
            row += 1
            lines += [""] * (row + 1 - len(lines))
        else:
            line = lines[row].ljust(col)
            lines[row] = line[:col] + ch + line[col + 1:]
            col += 1
        i += 1
    shown = [line.rstrip() for line in lines]
    while shown and not shown[-1]:
        shown.pop()
    return shown


def _drain(fd: int, chunks: list[bytes]) -> None:
    """Read ``fd`` into ``chunks`` until its writing end is closed."""
    while True:
        try:
            data = os.read(fd, 65536)
        except OSError:   # a pty's master side reads EIO once its terminal side is closed
            break
        if not data:
            break
        chunks.append(data)


def frames(raw: str) -> list[str]:
    """The bar's line as shown just before each redraw erased it."""
    return [screen(raw[:m.start()])[-1] for m in re.finditer(re.escape("\x1b[2K"), raw)]


def _before_close(raw: str) -> str:
    """What was written up to the bar's close (rich shows the cursor again there, then erases the bar)."""
    return raw[:raw.rindex("\x1b[?25h")]


class Stderr:
    """A pseudo-terminal (``tty=True``) or a pipe whose writing end is ``file``; a thread reads the other end."""

    def __init__(self, tty: bool) -> None:
        self._read_fd, write_fd = pty.openpty() if tty else os.pipe()
        self.file = open(write_fd, "w", encoding="utf-8")   # closed by close()
        self._chunks: list[bytes] = []
        self._reader = threading.Thread(target=_drain, args=(self._read_fd, self._chunks), daemon=True)
        self._reader.start()
        self.text = ""

    def so_far(self) -> str:
        self.file.flush()
        return b"".join(self._chunks).decode("utf-8", "replace")

    def close(self) -> str:
        """Everything written, once the writing end is closed."""
        if not self.file.closed:
            self.file.close()
            self._reader.join(timeout=30)
            os.close(self._read_fd)
            self.text = b"".join(self._chunks).decode("utf-8", "replace")
        return self.text


@pytest.fixture
def stderr_on(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[bool], Stderr]]:
    """``stderr_on(tty)``: sys.stderr becomes a new pseudo-terminal or pipe. rich is told to draw on a pipe too
    (``FORCE_COLOR``, ``TTY_COMPATIBLE``): the bar must still stay silent there.
    """
    monkeypatch.setenv("COLUMNS", "120")   # pytest's captured fds give rich no terminal size
    monkeypatch.setenv("FORCE_COLOR", "1")
    monkeypatch.setenv("TTY_COMPATIBLE", "1")
    monkeypatch.setenv("TERM", "xterm-256color")
    opened: list[Stderr] = []

    def redirect(tty: bool) -> Stderr:
        s = Stderr(tty)
        opened.append(s)
        monkeypatch.setattr(sys, "stderr", s.file)
        return s

    yield redirect
    for s in opened:
        s.close()


def _work(total: int | None) -> None:
    with Progress(total, "eval ipin") as bar:
        bar.set_note("T01.txt")
        for name in ("T02.txt", "T03.txt", None):
            bar.advance(note=name)


def test_a_bar_is_drawn_on_a_terminal_and_erased_at_the_end(stderr_on):
    tty = stderr_on(True)
    _work(3)
    raw = tty.close()
    first = frames(raw)[1]   # drawn at start, then at once with the first note
    assert first.startswith("eval ipin ━") and first.split()[-3:-1] == ["0/3", "T01.txt"]
    last = screen(_before_close(raw))   # the last state is always drawn
    assert last[0].startswith("eval ipin ━") and last[0].split()[-3:-1] == ["3/3", "T03.txt"]
    assert screen(raw) == []   # closed: the line is erased


def test_nothing_is_written_on_a_pipe(stderr_on):
    pipe = stderr_on(False)
    _work(3)
    _work(None)
    assert pipe.close() == ""


def test_an_unknown_total_counts_without_one(stderr_on):
    tty = stderr_on(True)
    _work(None)
    raw = tty.close()
    assert "eval ipin ━" in plain(raw) and "3/? T03.txt" in plain(raw) and screen(raw) == []
    assert Progress(None, "scan", enabled=False).line().startswith("scan ━")


def test_each_counts_the_items_and_names_them_and_streams_an_iterator(stderr_on):
    tty = stderr_on(True)
    seen = [p for p in progress.each(["a.txt", "b.txt"], "eval ms")]
    assert seen == ["a.txt", "b.txt"]
    consumed: list[int] = []

    def items() -> Iterator[int]:
        for i in range(3):
            consumed.append(i)
            yield i

    for i in progress.each(items(), "eval steps", name=False):
        assert consumed[-1] == i   # not read ahead to count it
    raw = tty.close()
    assert "eval ms ━" in plain(raw) and "2/2 b.txt" in plain(raw) and "eval steps ━" in plain(raw)
    assert "3/? " in plain(raw)


def test_a_message_gets_its_own_line_above_the_bar_and_is_printed_on_a_pipe_too(stderr_on):
    def work() -> None:
        with Progress(2, "eval heading", tick_s=0) as bar:
            bar.advance(note="walk-1")
            bar.write("walk-2: no motion-capture truth, skipped [not markup] :smile:")
            bar.advance()

    tty = stderr_on(True)
    work()
    raw = tty.close()
    message = "walk-2: no motion-capture truth, skipped [not markup] :smile:"
    assert screen(raw) == [message]   # the message stays, the bar is gone
    assert "2/2" in plain(raw.split(message)[1])   # the bar was drawn again under it
    pipe = stderr_on(False)
    work()
    assert pipe.close() == message + "\n"


def test_a_line_written_to_stderr_by_other_code_goes_above_the_bar(stderr_on):
    tty = stderr_on(True)
    with Progress(2, "eval ms", tick_s=0) as bar:
        bar.advance(note="a.txt")
        print("a.txt: time repeats, sample dropped", file=sys.stderr)   # e.g. a reader's warning
        bar.advance(note="b.txt")
        sys.stderr.write("an unfinished line")
    assert sys.stderr is tty.file   # given back at close
    raw = tty.close()
    assert screen(raw) == ["a.txt: time repeats, sample dropped", "an unfinished line"]
    assert "2/2 b.txt" in plain(raw.split("dropped")[1])


def test_a_drawn_bar_keeps_its_clock_running_during_a_long_stage_and_stops_at_close(stderr_on):
    tty = stderr_on(True)
    bar = Progress(2, "bench load", tick_s=0.01)
    try:
        bar.set_note("uploading")
        first = tty.so_far().count("\x1b[2K")
        for _ in range(500):   # wait for rich's redraws (no progress is made meanwhile)
            if tty.so_far().count("\x1b[2K") >= first + 3:
                break
            threading.Event().wait(0.01)
        assert tty.so_far().count("\x1b[2K") >= first + 3 and "0/2 uploading" in plain(tty.so_far())
    finally:
        bar.close()
    closed = re.compile(re.escape("\x1b[?25h") + r".*\x1b\[2K$", re.S)   # cursor shown again, the bar erased
    for _ in range(500):   # the reading thread catches up
        if closed.search(tty.so_far()):
            break
        threading.Event().wait(0.01)
    after = tty.so_far()
    threading.Event().wait(0.05)   # 5 of the bar's redraw periods
    assert closed.search(after) and tty.so_far() == after and screen(after) == []   # nothing drawn after close


def _sha(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}


def _run_on(stderr_on, tty: bool, capsys, argv: list[str], out: Path) -> tuple[str, str, dict[str, str]]:
    """stderr, stdout and the written files of ``pdr ARGV`` with stderr on a terminal or a pipe."""
    shutil.rmtree(out, ignore_errors=True)
    out.unlink(missing_ok=True)
    capsys.readouterr()
    stream = stderr_on(tty)
    assert main(argv) == 0
    err = stream.close()
    files = _sha(out) if out.is_dir() else {out.name: hashlib.sha256(out.read_bytes()).hexdigest()}
    return err, capsys.readouterr().out, files


def test_simulate_and_convert_draw_on_a_terminal_only_with_the_same_stdout_and_files(stderr_on, capsys, tmp_path):
    scenario = tmp_path / "s.json"
    scenario.write_text(json.dumps({"name": "p", "segments": [{"type": "walk", "duration_s": 3}]}))
    rec = tmp_path / "rec"
    argv = ["simulate", str(scenario), "--seed", "3", "--out", str(rec)]
    err_tty, out_tty, files_tty = _run_on(stderr_on, True, capsys, argv, rec)
    err_pipe, out_pipe, files_pipe = _run_on(stderr_on, False, capsys, argv, rec)
    assert "simulate ━" in plain(err_tty) and "2/2" in plain(err_tty) and screen(err_tty) == []
    assert err_pipe == "" and out_tty == out_pipe and out_tty.startswith("wrote ") and files_tty == files_pipe

    out = tmp_path / "conv"
    argv = ["convert", str(SIM / "hand_escalator.zip"), "--to", "native", str(out)]
    err_tty, out_tty, files_tty = _run_on(stderr_on, True, capsys, argv, out)
    err_pipe, out_pipe, files_pipe = _run_on(stderr_on, False, capsys, argv, out)
    assert "convert ━" in plain(err_tty) and "reading hand_escalator.zip" in err_tty and "2/2" in plain(err_tty)
    assert err_pipe == "" and out_tty == out_pipe and out_tty.startswith("wrote ") and files_tty == files_pipe


def test_train_draws_its_stages_on_a_terminal(stderr_on, capsys, tmp_path):
    err, out, _ = _run_on(stderr_on, True, capsys, ["train", "landmark", "--sim", "2", "--out", str(tmp_path / "lm")],
                          tmp_path / "lm")
    assert "train landmark ━" in plain(err) and "fitting on" in err and "3/3" in plain(err) and screen(err) == []
    assert out.startswith("wrote ")


def test_eval_heading_says_which_recordings_it_skipped_on_a_terminal_and_a_pipe(stderr_on, capsys, tmp_path):
    """A recording without motion-capture truth is skipped with a message (stderr, piped or not); the bar counts it."""
    rec = tmp_path / "rec.zip"
    assert main(["convert", str(SIM / "hand_escalator.zip"), "--to", "native", str(rec)]) == 0
    message = "rec.zip: no motion-capture truth (walking path and attitude), skipped"
    for tty in (True, False):
        capsys.readouterr()
        stream = stderr_on(tty)
        main(["eval", "heading", str(rec), "--json"])
        err = stream.close()
        if tty:
            assert screen(err) == [message] and "eval heading ━" in plain(err) and "1/1" in plain(err)
        else:
            assert err == message + "\n"


def test_eval_classifier_draws_its_stages_and_prints_the_figures_alone_on_stdout(stderr_on, capsys):
    capsys.readouterr()
    tty = stderr_on(True)
    argv = ["eval", "classifier", "motion_mode", "--timeline", "--data", str(SIM / "pocket_office.zip"), "--json"]
    assert main(argv) == 0
    err = tty.close()
    assert "eval classifier motion_mode ━" in plain(err) and "reading the logs" in err and "2/2" in plain(err)
    assert screen(err) == []   # erased before the figures are printed
    assert "command" in json.loads(capsys.readouterr().out)


_SCRIPT = ("import sys; from pdr.cli.progress import Progress\n"
           "with Progress(3, 'work') as bar:\n"
           "    for _ in range(3): bar.advance(note='step')\n"
           "    print('result', flush=True)\n"   # stdout written while the bar is drawn stays stdout
           "print('rich' in sys.modules, file=sys.stderr)\n")


def test_a_process_whose_stderr_is_a_terminal_draws_and_a_piped_one_never_imports_rich(tmp_path):
    """The whole process: its real sys.stderr is a pseudo-terminal, or a pipe (where rich is not even imported)."""
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT), "COLUMNS": "100", "FORCE_COLOR": "1",
           "TERM": "xterm-256color"}
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-c", _SCRIPT], stdout=subprocess.PIPE, stderr=slave, env=env)
    os.close(slave)
    chunks: list[bytes] = []
    _drain(master, chunks)   # until the process exits
    out, _ = proc.communicate(timeout=120)
    os.close(master)
    err = b"".join(chunks).decode()
    assert out == b"result\n" and "work ━" in plain(err) and "3/3 step" in plain(err) and screen(err) == ["True"]
    piped = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, env=env, timeout=120, check=True)
    assert piped.stdout == b"result\n" and piped.stderr == b"False\n"
