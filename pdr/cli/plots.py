"""The horizontal-track PNG of ``pdr track --plot`` and ``pdr foot --plot``: one drawing for both.

The track is drawn east/north in metres with its start and end marked; when the log carries reference positions
the truth is drawn too and the track is moved to start at the first truth point (the track interpolated at the
first truth time lands on it, :func:`pdr.evaluation.scoring.start_offset`), which is how ``pdr eval`` scores it,
so the gap seen in the plot is the error the scorer reports. Matplotlib (Agg, no display) is imported on use.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.evaluation.foot_metrics import pyshoe_turn
from pdr.evaluation.scoring import start_offset
from pdr.recording import Recording

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

#: Second title line of a plot whose track was moved to the first truth point.
ALIGNED_NOTE = "track moved to start at the first truth point, as pdr eval scores it"
#: ... and of one also turned about that point (a foot track's heading is relative: PyShoe's alignment).
TURNED_NOTE = "track moved to the first truth point and turned onto it, as pdr eval foot scores it"
#: Title lines wrap at this many characters (the 6-inch figure's width at 9 pt).
TITLE_CHARS = 80


def _identity(en: FloatArray) -> FloatArray:
    return en


def _aligner(t: FloatArray, en: FloatArray, truth: PlotTruth, turn: bool) -> Callable[[FloatArray], FloatArray]:
    """The map that moves positions of this track (and tracks in its frame) to start at the first truth point
    (:func:`~pdr.evaluation.scoring.start_offset`) and, with ``turn``, also turns them about it by
    :func:`~pdr.evaluation.foot_metrics.pyshoe_turn` (the track and the truth compared at the truth's times).
    """
    shift = start_offset(t, en, float(truth.t_s[0]), truth.en_m[0])
    if not turn:
        return lambda p: p + shift
    at = np.column_stack([np.interp(truth.t_s, t, en[:, 0]), np.interp(truth.t_s, t, en[:, 1])])
    start = at[0]
    a = pyshoe_turn(at - start, truth.en_m - truth.en_m[0])
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return lambda p: truth.en_m[0] + (p - start) @ rot.T


@dataclass(frozen=True)
class PlotTruth:
    """Reference positions for the plot: times (K,) s on the track's clock, east/north (K, 2) m, and their kind."""

    t_s: FloatArray
    en_m: FloatArray
    kind: str


def truth_of(rec: Recording) -> PlotTruth | None:
    """The log's reference positions on the log's own clock (``t0_ns / 1e9 + t_s``), or None without at least 2."""
    pt = rec.truth.positions
    if pt is None or len(pt) < 2:
        return None
    return PlotTruth(rec.origin_ns / 1e9 + np.asarray(pt.t_s, dtype=np.float64),
                     np.asarray(pt.pos_m, dtype=np.float64)[:, :2], pt.kind)


def track_figure(t_s: FloatArray, en_m: FloatArray, title: str, truth: PlotTruth | None = None,
                 label: str = "track", extra: dict[str, FloatArray] | None = None, turn: bool = False) -> Figure:
    """The figure of one track (``t_s`` (N,) s, ``en_m`` (N, 2) east/north m) with start and end markers.

    With ``truth`` (and at least 2 track positions) every line is moved by the track's
    :func:`~pdr.evaluation.scoring.start_offset` and the title says so. ``extra``: more tracks by name (east/north
    (M, 2) m in the same frame, e.g. the two feet), moved with the main track. ``turn``: also turn the tracks about
    the first truth point as PyShoe's scorer does (for foot tracks, whose heading origin is arbitrary).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    en = np.asarray(en_m, dtype=np.float64).reshape(-1, 2)
    t = np.asarray(t_s, dtype=np.float64)
    aligned = truth is not None and t.size >= 2
    move: Callable[[FloatArray], FloatArray] = _identity
    if truth is not None and aligned:
        move = _aligner(t, en, truth, turn)
    fig, ax = plt.subplots(figsize=(6, 6))
    if truth is not None:
        ax.plot(truth.en_m[:, 0], truth.en_m[:, 1], "--", color="0.45", lw=0.9,
                marker="o" if len(truth.t_s) <= 200 else None, ms=3, label=f"truth ({truth.kind})", zorder=1)
    for k, (name, other) in enumerate((extra or {}).items()):
        o = move(np.asarray(other, dtype=np.float64).reshape(-1, 2))
        ax.plot(o[:, 0], o[:, 1], lw=0.7, color=f"C{k + 1}", label=name, zorder=2)
    if en.shape[0]:
        moved = move(en)
        ax.plot(moved[:, 0], moved[:, 1], "-", color="C0", lw=1.1, label=label, zorder=3)
        ax.plot(*moved[0], "o", color="tab:green", ms=8, mec="k", label="start", zorder=4)
        ax.plot(*moved[-1], "s", color="tab:red", ms=8, mec="k", label="end", zorder=4)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3, alpha=0.6)
    lines = textwrap.wrap(title, TITLE_CHARS) + ([TURNED_NOTE if turn else ALIGNED_NOTE] if aligned else [])
    ax.set_title("\n".join(lines), fontsize=9)
    if ax.get_legend_handles_labels()[0]:     # an empty track without truth has nothing to list
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def plot_track(path: str | Path, t_s: FloatArray, en_m: FloatArray, title: str, truth: PlotTruth | None = None,
               label: str = "track", extra: dict[str, FloatArray] | None = None, turn: bool = False) -> None:
    """Write :func:`track_figure`'s PNG to ``path``."""
    import matplotlib.pyplot as plt

    fig = track_figure(t_s, en_m, title, truth, label, extra, turn)
    try:
        fig.savefig(path, dpi=100)
    except ValueError as exc:   # an image format matplotlib does not write, from the name's suffix (e.g. '.pdfx')
        raise InputError(str(exc), source=str(path), field="--plot") from None
    finally:
        plt.close(fig)
