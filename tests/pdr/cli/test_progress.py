"""The CLI's progress bar: drawn on a terminal's stderr, silent otherwise, never on stdout."""

import io
import json
import sys
import threading

from pdr.cli import main, progress
from pdr.cli.progress import BAR_WIDTH, Progress


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_silent_when_stderr_is_not_a_terminal():
    stream = io.StringIO()
    with Progress(3, "work", stream=stream) as bar:
        for _ in range(3):
            bar.advance(note="x")
    assert stream.getvalue() == ""


def test_drawn_in_place_on_a_terminal_and_cleared_at_the_end():
    stream = Terminal()
    bar = Progress(4, "eval ipin", stream=stream)
    bar.advance(2, note="T01.txt")
    assert bar.line().startswith(f"eval ipin [{'#' * (BAR_WIDTH // 2)}{'.' * (BAR_WIDTH // 2)}] 2/4  T01.txt")
    bar.advance(2)
    drawn = stream.getvalue()
    assert drawn.startswith("\r") and "\n" not in drawn and "4/4" in drawn  # the last state is always drawn
    bar.close()
    assert stream.getvalue().endswith("\r") and stream.getvalue()[len(drawn):].strip() == ""


def test_each_counts_the_items_and_names_them(monkeypatch):
    stream = Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    seen = [p for p in progress.each(["a.txt", "b.txt"], "eval ms")]
    assert seen == ["a.txt", "b.txt"]
    assert "eval ms [" in stream.getvalue() and "2/2" in stream.getvalue()


def test_simulate_prints_its_summary_on_stdout_and_no_bar_when_piped(tmp_path, capsys):
    scenario = tmp_path / "s.json"
    scenario.write_text(json.dumps({"name": "p", "segments": [{"type": "walk", "duration_s": 3}]}))
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "rec")]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("wrote ") and captured.err == ""


def test_convert_and_train_draw_their_stages_on_a_terminal(tmp_path, monkeypatch, capsys):
    """The long commands of issue #29 besides the evaluations: a bar on a terminal's stderr, the result on stdout."""
    from tests.conftest import REPO_ROOT

    log = REPO_ROOT / "mobile_logs" / "sim" / "hand_escalator.zip"
    assert main(["convert", str(log), "--to", "native", str(tmp_path / "piped")]) == 0
    piped = capsys.readouterr()
    assert piped.out.startswith("wrote ") and piped.err == ""
    stream = Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    assert main(["convert", str(log), "--to", "native", str(tmp_path / "tty")]) == 0
    drawn = stream.getvalue()
    assert "convert [" in drawn and "reading hand_escalator.zip" in drawn and "2/2" in drawn
    assert capsys.readouterr().out.startswith("wrote ")
    stream.seek(0)
    stream.truncate()
    assert main(["train", "landmark", "--sim", "2", "--out", str(tmp_path / "lm")]) == 0
    drawn = stream.getvalue()
    assert "train landmark [" in drawn and "fitting on" in drawn and "3/3" in drawn
    assert capsys.readouterr().out.startswith("wrote ")


def test_a_drawn_bar_keeps_its_clock_running_during_a_long_stage_and_stops_at_close():
    stream = Terminal()
    bar = Progress(2, "bench load", stream=stream, tick_s=0.01)
    bar.set_note("uploading")
    first = stream.getvalue().count("\r")
    for _ in range(500):   # wait for the ticker's redraws (no progress is made meanwhile)
        if stream.getvalue().count("\r") >= first + 3:
            break
        threading.Event().wait(0.01)
    assert stream.getvalue().count("\r") >= first + 3
    assert stream.getvalue().rstrip().endswith("s") and "0/2  uploading" in stream.getvalue()
    bar.close()
    after = stream.getvalue()
    assert after.endswith("\r") and "pdr-progress" not in [t.name for t in threading.enumerate()]
    threading.Event().wait(0.05)
    assert stream.getvalue() == after   # nothing drawn after close
    silent = io.StringIO()
    piped = Progress(2, "piped", stream=silent, tick_s=0.01)   # not a terminal: no bar, no thread
    assert "pdr-progress" not in [t.name for t in threading.enumerate()]
    piped.close()
    assert silent.getvalue() == ""


def test_a_message_gets_its_own_line_above_the_bar_and_is_printed_when_piped_too():
    stream = Terminal()
    bar = Progress(2, "eval heading", stream=stream, tick_s=0)
    bar.advance(note="walk-1")
    bar.write("walk-2: no motion-capture truth, skipped")
    bar.advance()
    bar.close()
    lines = stream.getvalue().split("\n")
    # The bar's line is cleared before the message, and the bar is drawn again after it, on the next line.
    *drawn, cleared, message = lines[0].split("\r")
    assert message == "walk-2: no motion-capture truth, skipped" and cleared.strip() == "" and len(cleared) > 0
    assert drawn[-1].startswith("eval heading [")
    assert "2/2" in lines[1] and len(lines) == 2
    piped = io.StringIO()
    with Progress(2, "eval heading", stream=piped) as quiet:
        quiet.advance()
        quiet.write("a message")
    assert piped.getvalue() == "a message\n"


def test_eval_heading_draws_a_bar_and_says_which_recordings_it_skipped(tmp_path, monkeypatch, capsys):
    """A recording without motion-capture truth is skipped with a message (stderr, piped or not); the bar counts it."""
    from tests.conftest import REPO_ROOT

    log = REPO_ROOT / "mobile_logs" / "sim" / "hand_escalator.zip"
    assert main(["convert", str(log), "--to", "native", str(tmp_path / "rec.zip")]) == 0
    capsys.readouterr()
    main(["eval", "heading", str(tmp_path / "rec.zip"), "--json"])
    piped = capsys.readouterr()
    assert piped.err == "rec.zip: no motion-capture truth (walking path and attitude), skipped\n"
    stream = Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    main(["eval", "heading", str(tmp_path / "rec.zip"), "--json"])
    drawn = stream.getvalue()
    assert "rec.zip: no motion-capture truth" in drawn and "eval heading [" in drawn and "1/1" in drawn


def test_eval_classifier_draws_its_stages_on_a_terminal_and_prints_the_figures_after(tmp_path, monkeypatch, capsys):
    from tests.conftest import REPO_ROOT

    log = REPO_ROOT / "mobile_logs" / "sim" / "pocket_office.zip"
    stream = Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    assert main(["eval", "classifier", "motion_mode", "--timeline", "--data", str(log), "--json"]) == 0
    drawn = stream.getvalue()
    assert "eval classifier motion_mode [" in drawn and "reading the logs" in drawn and "2/2" in drawn
    assert drawn.endswith("\r")   # cleared before the figures are printed
    assert "command" in json.loads(capsys.readouterr().out)   # stdout holds the figures alone
