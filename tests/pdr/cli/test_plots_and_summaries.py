"""What ``pdr track --plot``, ``pdr foot`` and ``pdr eval ipin FILE`` show a user (issue #29, CLI items 2 and 3)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pdr.cli import main
from pdr.cli.plots import ALIGNED_NOTE, TURNED_NOTE, PlotTruth, track_figure
from pdr.evaluation.foot_metrics import pyshoe_turn, stride_summary
from pdr.evaluation.scoring import landmark_errors, start_offset
from pdr.foot.strides import stance_onsets
from tests.conftest import REPO_ROOT, data_path

SIM = REPO_ROOT / "mobile_logs" / "sim"


def _lines(fig):  # noqa: ANN001, ANN202 - a matplotlib figure
    return {ln.get_label(): ln.get_xydata() for ln in fig.axes[0].get_lines()}


def test_start_offset_puts_the_track_on_the_first_truth_point_as_the_scorer_does() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    en = np.array([[5.0, 5.0], [6.0, 5.0], [7.0, 5.0], [8.0, 5.0]])
    shift = start_offset(t, en, 1.5, np.array([0.0, 0.0]))
    assert shift == pytest.approx([-6.5, -5.0])
    # The landmark errors are those of the track moved by this offset.
    truth_t, truth_en = np.array([1.5, 2.5]), np.array([[0.0, 0.0], [1.0, 1.0]])
    moved = en + shift
    assert landmark_errors(t, en, truth_t, truth_en) == pytest.approx(
        [math.hypot(np.interp(2.5, t, moved[:, 0]) - 1.0, np.interp(2.5, t, moved[:, 1]) - 1.0)])


def test_track_figure_marks_start_and_end_and_aligns_at_the_first_truth_point() -> None:
    import matplotlib.pyplot as plt

    t = np.arange(5.0)
    en = np.column_stack([np.arange(5.0) + 10.0, np.full(5, 3.0)])
    truth = PlotTruth(np.array([1.0, 4.0]), np.array([[0.0, 0.0], [3.0, 1.0]]), "landmark")
    fig = track_figure(t, en, "walk", truth, label="PDR track")
    lines = _lines(fig)
    assert set(lines) == {"truth (landmark)", "PDR track", "start", "end"}
    # At the first truth time (t = 1 s) the drawn track is on the first truth point.
    drawn = lines["PDR track"]
    assert [np.interp(1.0, t, drawn[:, 0]), np.interp(1.0, t, drawn[:, 1])] == pytest.approx([0.0, 0.0])
    assert lines["start"][0] == pytest.approx(drawn[0]) and lines["end"][0] == pytest.approx(drawn[-1])
    legend = fig.axes[0].get_legend()
    assert legend is not None and [lg.get_text() for lg in legend.get_texts()] == [
        "truth (landmark)", "PDR track", "start", "end"]
    assert fig.axes[0].get_title().endswith(ALIGNED_NOTE)
    plt.close(fig)
    # Without truth: drawn where it is, no alignment note.
    fig = track_figure(t, en, "walk")
    assert _lines(fig)["track"] == pytest.approx(en)
    assert fig.axes[0].get_title() == "walk"
    plt.close(fig)


def test_a_foot_track_is_also_turned_onto_the_truth() -> None:
    import matplotlib.pyplot as plt

    # A straight walk north in truth; the foot's frame has it going east (its heading origin is arbitrary).
    t = np.linspace(0.0, 10.0, 101)
    truth = PlotTruth(t, np.column_stack([np.zeros_like(t), 1.2 * t]), "dense")
    en = np.column_stack([5.0 + 1.2 * t, np.full_like(t, -2.0)])
    assert pyshoe_turn(en - en[0], truth.en_m - truth.en_m[0]) == pytest.approx(math.pi / 2)
    fig = track_figure(t, en, "foot", truth, label="foot track", turn=True)
    assert _lines(fig)["foot track"] == pytest.approx(truth.en_m, abs=1e-9)
    assert fig.axes[0].get_title().endswith(TURNED_NOTE)
    plt.close(fig)


def test_stance_onsets_count_each_return_to_rest() -> None:
    zv = np.array([1, 1, 0, 0, 1, 1, 0, 1, 0, 0], dtype=bool)
    t = np.arange(10.0) * 0.5
    assert stance_onsets(zv, t).tolist() == [4, 7]
    pos = np.column_stack([np.arange(10.0), np.zeros(10), np.zeros(10)])
    assert stride_summary(t, pos, zv) == (2, pytest.approx(9.0), pytest.approx(4.5))


def test_a_stance_broken_by_a_shorter_motion_than_a_swing_is_one_stride() -> None:
    # 200 Hz: stand 1 s, swing 0.4 s, stance broken by a 0.05 s roll of the foot, swing 0.4 s, stance.
    runs = [(1, 200), (0, 80), (1, 30), (0, 10), (1, 30), (0, 80), (1, 60)]
    zv = np.concatenate([np.full(n, bool(v)) for v, n in runs])
    t = np.arange(zv.size) / 200.0
    assert stance_onsets(zv, t).tolist() == [280, 430]
    assert stance_onsets(zv, t, min_swing_s=0.0).tolist() == [280, 320, 430]
    # A record that starts moving: its first stance counts once the motion before it is a swing.
    assert stance_onsets(zv[150:], t[150:]).tolist() == [130, 280]
    assert stance_onsets(zv[270:], t[270:]).tolist() == [160]


@pytest.mark.data
def test_pdr_foot_counts_the_strides_of_a_real_walk(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # SensorConnect walk 31: 33 strides measured on the floor tiles (its .mat, numberOfStrides); the zero-velocity
    # detector breaks 15 of its stances into pieces (48 returns to rest).
    log = data_path("foot_stride_gcp", "own", "SensorConnectData_31.csv")
    assert main(["foot", str(log), "--out", str(tmp_path / "foot.csv")]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("33 strides, ")


def test_pdr_foot_prints_a_summary_and_plots_with_the_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    out, png = tmp_path / "foot.csv", tmp_path / "foot.png"
    assert main(["foot", str(SIM / "foot_walk_run.zip"), "--out", str(out), "--plot", str(png)]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    # The scenario: 35 s, walking and running along a 12 m corridor and back (its truth, SIM/foot_walk_run.json).
    assert line.endswith(f"s, method zupt (RTS-smoothed) -> {out}")
    strides, dist = int(line.split()[0]), float(line.split()[2])
    assert " strides, " in line and "m walked in 35.0 s" in line
    assert 20 <= strides <= 40 and 30.0 < dist < 45.0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_pdr_track_plot_titles_the_walk(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, png = tmp_path / "t.csv", tmp_path / "t.png"
    assert main(["track", str(SIM / "hand_escalator.zip"), "--out", str(out), "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert " steps, " in capsys.readouterr().out


@pytest.mark.parametrize("command", ["track", "foot"])
def test_a_plot_name_without_an_extension_says_where_the_png_went(tmp_path: Path, command: str,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """``--plot out/p`` wrote out/p.png (matplotlib adds the suffix) without a word, and checked that out/p, not
    out/p.png, could be written: the user is now told the file written, and that file is the one checked first."""
    log = SIM / ("hand_escalator.zip" if command == "track" else "foot_walk_run.zip")
    plot = tmp_path / "plots" / "p"
    (tmp_path / "plots" / "p.png").mkdir(parents=True)      # the real target cannot be written: refused first
    assert main([command, str(log), "--out", str(tmp_path / "o.csv"), "--plot", str(plot)]) == 2
    err = capsys.readouterr().err
    assert f"note: --plot {plot} has no extension: the PNG is written to {plot}.png" in err
    assert err.strip().splitlines()[-1].startswith(f"error: {plot}.png") and not (tmp_path / "o.csv").exists()
    (tmp_path / "plots" / "p.png").rmdir()
    assert main([command, str(log), "--out", str(tmp_path / "o.csv"), "--plot", str(plot)]) == 0
    assert f"the PNG is written to {plot}.png" in capsys.readouterr().err
    assert Path(f"{plot}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and not plot.exists()


@pytest.mark.parametrize("command", ["track", "foot", "site"])
def test_a_plot_format_matplotlib_cannot_write_is_refused_before_the_work(tmp_path: Path, command: str,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """``--plot p.weird`` was refused by matplotlib only once the plot was drawn: after the track was computed and
    its CSV written (``pdr track``, ``pdr foot``), or with matplotlib's traceback (``pdr site check``)."""
    plot, out = tmp_path / "p.weird", tmp_path / "o.csv"
    args = {"track": ["track", str(SIM / "hand_escalator.zip"), "--out", str(out)],
            "foot": ["foot", str(SIM / "foot_walk_run.zip"), "--out", str(out)],
            "site": ["site", "check", str(tmp_path / "missing_site.json")]}[command]
    assert main([*args, "--plot", str(plot)]) == 2
    err = capsys.readouterr().err
    assert f"{plot}: matplotlib cannot write '.weird' images; use one of " in err and ".png" in err
    assert not out.exists() and not plot.exists()


def test_an_empty_track_without_truth_plots_without_a_legend_warning() -> None:
    """No steps and no truth (pdr track --plot on the car trip driving_phone_mount/17): no legend, and no matplotlib
    'No artists with labels found to put in legend' UserWarning on stderr as before."""
    import warnings

    import matplotlib.pyplot as plt

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = track_figure(np.zeros(0), np.zeros((0, 2)), "pdr track trip: 0 steps, 0.0 m")
    assert fig.axes[0].get_legend() is None
    plt.close(fig)


def test_a_plot_name_of_an_image_format_matplotlib_cannot_write_is_a_clean_error(tmp_path: Path) -> None:
    """``--plot F.pdfx``: 'error: F, field '--plot': Format 'pdfx' is not supported ...' (an InputError); it was
    matplotlib's ValueError traceback after the CSV was written."""
    from pdr.cli.plots import plot_track
    from pdr.errors import InputError

    bad = tmp_path / "track.pdfx"
    with pytest.raises(InputError, match="'pdfx' is not supported") as err:
        plot_track(bad, np.arange(3.0), np.zeros((3, 2)), "walk")
    assert str(err.value).startswith(f"{bad}, field '--plot'")
    svg = tmp_path / "track.svg"                # a format it writes is still written
    plot_track(svg, np.arange(3.0), np.zeros((3, 2)), "walk")
    assert svg.read_bytes().lstrip().startswith(b"<?xml")


def test_eval_ipin_refuses_what_it_cannot_score(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A file that is not an IPIN log, a folder without any, a missing path: each a clear error, never "ALL (0 files)".
    assert main(["eval", "ipin", str(SIM / "hand_escalator.zip")]) == 2
    assert "not a log this evaluation reads" in capsys.readouterr().err
    assert main(["eval", "ipin", str(tmp_path)]) == 2
    assert "no *.txt or *.txt.gz or *.mat files in this folder" in capsys.readouterr().err
    assert main(["eval", "ipin", str(tmp_path / "missing.txt")]) == 2
    assert "no such file or folder" in capsys.readouterr().err
    # An IPIN-named file without landmarks: named, and nothing scored is an error.
    empty = tmp_path / "no-truth.txt"
    empty.write_text("ACCE;0.0;0.0;0.0;0.0;9.8;3\n")
    assert main(["eval", "ipin", str(empty)]) == 2
    err = capsys.readouterr().err
    assert "0 files" not in err and "no-truth.txt" in err
    # A dataset folder's README.txt is not a log: left out and named, and the logs beside it are still read.
    (tmp_path / "supplementary").mkdir()
    (tmp_path / "supplementary" / "ZZ_README.txt").write_text("This folder holds the competition's maps.\n")
    assert main(["eval", "ipin", str(tmp_path / "supplementary")]) == 2
    err = capsys.readouterr().err
    assert "ZZ_README.txt" in err and "that a reader recognises" in err
    assert main(["eval", "ipin", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "left out 1 file(s)" in err and "supplementary/ZZ_README.txt" in err and "no-truth.txt" in err


@pytest.mark.data
@pytest.mark.slow
def test_eval_ipin_scores_one_file(capsys: pytest.CaptureFixture[str]) -> None:
    log = data_path("ipin2023_t3", "logfiles") / "IPIN2023_T3_TrainingTrial22_repetition01.txt"
    assert main(["eval", "ipin", str(log), "--smoother", "off"]) == 0
    out = capsys.readouterr().out
    assert "ALL (1 files)" in out and log.name in out
