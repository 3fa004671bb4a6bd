"""Per-class figures of the service's step-mode timeline (hand-held and torso phones) on walks with landmarks.

Truth, on a ``GRID_S`` grid from the first to the last landmark of each recording (IPIN):

* ``standing`` and ``elevator_up/down``: the truth stops of :func:`classifiers.timeline_eval.truth_stops`
  (two consecutive landmarks at one place, passed at least 5 s apart; on different floors a ride);
* ``stairs_up/down``: the stairs intervals of :func:`classifiers.datasets.ipin_mode_labels` (the barometric
  altitude changing between two landmarks on different floors that are apart: the same barometer the pipeline
  reads, so this checks the labelling and its lag, not the barometer);
* ``walking``: the rest.

Predicted: the label the timeline shows at that time (:meth:`classifiers.step_timeline.StepTimeline.label_at`).
Each class's precision, recall and F1 are over time (support in seconds), pooled over the recordings, and
given per placement group. The figures evaluate a rule (no training), so every recording is held out.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from classifiers.datasets import ipin_mode_labels
from classifiers.evaluation import classification_metrics
from classifiers.step_timeline import TimelineOf, step_timeline
from classifiers.timeline_eval import truth_stops
from pdr.phone.configure import placement_group
from pdr.phone.landmarks import Site
from pdr.recording import Recording

#: Time step (s) of the comparison grid.
GRID_S = 0.5
CLASSES = ("standing", "walking", "stairs_up", "stairs_down", "elevator_up", "elevator_down")


def truth_labels(rec: Recording, t_s: np.ndarray) -> np.ndarray:
    """Truth label at each time (module docstring)."""
    out = np.full(t_s.shape, "walking", dtype=object)
    vertical = ipin_mode_labels(rec)
    if vertical is not None:
        for a, b, name in zip(vertical.t_start_s, vertical.t_end_s, vertical.label, strict=True):
            if name in ("stairs_up", "stairs_down"):
                out[(t_s >= a) & (t_s < b)] = name
    for a, b, kind in truth_stops(rec):
        out[(t_s >= a) & (t_s < b)] = kind
    return out


def timeline_scores(recs: Sequence[Recording], site: Site | None = None,
                    timeline_of: TimelineOf | None = None) -> dict[str, Any]:
    """Per-class figures over the recordings with landmarks, pooled and per placement group (module docstring);
    ``site`` and ``timeline_of`` as for :func:`classifiers.floor_eval.floor_figures`.
    """
    truth: dict[str, list[np.ndarray]] = {}
    pred: dict[str, list[np.ndarray]] = {}
    names: dict[str, list[str]] = {}
    for rec in recs:
        pos = rec.truth.positions
        if pos is None or pos.kind != "landmark" or len(pos) < 2:
            continue
        group = placement_group(rec.device.placement) or "unknown"
        t = np.arange(float(pos.t_s[0]), float(pos.t_s[-1]), GRID_S)
        truth.setdefault(group, []).append(truth_labels(rec, t))
        tl = timeline_of(rec) if timeline_of is not None else step_timeline(rec, site)
        pred.setdefault(group, []).append(tl.label_at(t))
        names.setdefault(group, []).append(Path(rec.source).name if rec.source else "?")
    out: dict[str, Any] = {"grid_s": GRID_S, "groups": {}}
    for group in truth:
        y, p = np.concatenate(truth[group]), np.concatenate(pred[group])
        m = classification_metrics(y, p, np.ones(y.size), list(CLASSES))
        out["groups"][group] = {
            "recordings": names[group], "seconds": float(y.size * GRID_S), "macro_f1": m["macro_f1"],
            "per_class": {c: {k: (v * GRID_S if k == "support" else v) for k, v in m["per_class"][c].items()}
                          for c in CLASSES if c in m["per_class"]}}
    return out


def print_scores(fig: dict[str, Any]) -> None:
    """Human-readable :func:`timeline_scores`."""
    for group, g in fig["groups"].items():
        print(f"step-mode timeline, placement {group}: {len(g['recordings'])} recordings, {g['seconds']:.0f} s, "
              f"macro-F1 {g['macro_f1']:.3f} (time-weighted, {fig['grid_s']} s grid)")
        for c, m in g["per_class"].items():
            print(f"  {c:14s} P {m['precision']:.3f}  R {m['recall']:.3f}  F1 {m['f1']:.3f}  {m['support']:.0f} s")
