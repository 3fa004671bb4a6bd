"""Figures of the modes timeline on real recordings, per recording (``pdr eval classifier MODEL --timeline``).

* **Vehicle labels in walks**: for every recording whose truth is neither a car trip nor a car step-in/out
  clip, the windows of the model's timeline (:meth:`classifiers.model.ContextModel.classify`, transitions
  gated) labelled ``car_*`` or ``vehicle``, and the same count without the transition gate. Recordings the
  model cannot take (no gyroscope) are listed as such: the service gives them step modes (no vehicle class).
  The model is applied whatever the recording's placement, although the service applies it to trouser-pocket
  phones only (the placement is printed with each recording).
* **Driving**: for a recording whose truth modes are ``vehicle``, the fraction of its windows labelled vehicle.
* **Stops**: in recordings with surveyed landmarks (IPIN), a truth stop is two consecutive landmarks at the same
  place (under ``SAME_PLACE_M`` apart horizontally) passed at least ``MIN_STOP_S`` (2 s, the timeline's shortest
  stop) apart; on the same floor it is standing, on different floors an elevator ride (the rider stands in the
  cabin). In recordings with mode truth (simulated logs), every interval labelled one of ``STILL_TRUTH_LABELS`` for
  ``MIN_STOP_S`` or more is a standing stop. A stop *appears* when the entries of its kind in the timeline the
  service shows for the recording's placement cover at least ``MIN_COVERAGE`` of it: for a phone the shipped model
  takes (:func:`classifiers.installed.placement_model`, placement from the log's metadata) the model's windows
  labelled one of ``STILL_CLASSES`` (each window holds the hop around its centre); otherwise the step-mode timeline
  (:func:`classifiers.step_timeline.step_timeline`: the phone pipeline, the stop rule, the rides) and its
  ``standing`` or ``elevator_up/down`` entries. ``coverage_rule`` is the same for the stop rule alone
  (:func:`classifiers.stops.stop_intervals` on :func:`classifiers.stops.step_intervals`), any label. The issue's
  two stop targets are the stops of ``MIN_TRUTH_STOP_S`` (5 s) or more in the landmark walks, and every stop of
  ``MIN_STOP_S`` or more as its own entry.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from classifiers.installed import placement_model
from classifiers.model import ContextModel, WindowResults
from classifiers.posture import window_gravity
from classifiers.step_timeline import TimelineOf, step_timeline
from classifiers.stops import MIN_STOP_S, STOP_LABEL, Stop, step_intervals, stop_intervals
from classifiers.transitions import TRANSITIONS
from classifiers.windows import make_windows
from pdr.errors import InputError
from pdr.phone.configure import placement_group
from pdr.recording import Recording

#: Landmarks closer than this (m) horizontally are the same place.
SAME_PLACE_M = 1.0
#: Shortest landmark stop (s) of the issue's standing target (every stop of 5 s or more in the IPIN walks).
MIN_TRUTH_STOP_S = 5.0
#: Truth mode labels of a person at rest (simulated logs, MobiFall).
STILL_TRUTH_LABELS = ("standing", "stationary", "sitting")
#: The shipped model's classes of a person at rest (a stop on a pocket phone's timeline).
STILL_CLASSES = ("stationary", "sitting")
#: Fraction of a truth stop the detected stops must cover for it to count as found.
MIN_COVERAGE = 0.5

VEHICLE_LABELS = ("vehicle", *TRANSITIONS)


def truth_stops(rec: Recording, min_s: float = MIN_TRUTH_STOP_S) -> list[tuple[float, float, str]]:
    """Truth stops ``(t0_s, t1_s, kind)`` of ``min_s`` (s) or more from consecutive landmarks at one place
    (module docstring).
    """
    pos = rec.truth.positions
    if pos is None or pos.kind != "landmark" or len(pos) < 2:
        return []
    out = []
    for i in range(len(pos) - 1):
        dt = float(pos.t_s[i + 1] - pos.t_s[i])
        if dt < min_s or np.linalg.norm(pos.pos_m[i + 1, :2] - pos.pos_m[i, :2]) >= SAME_PLACE_M:
            continue
        assert pos.floor is not None
        f0, f1 = float(pos.floor[i]), float(pos.floor[i + 1])
        kind = "standing" if not (np.isfinite(f0) and np.isfinite(f1)) or f0 == f1 else \
            ("elevator_up" if f1 > f0 else "elevator_down")
        out.append((float(pos.t_s[i]), float(pos.t_s[i + 1]), kind))
    return out


def mode_truth_stops(rec: Recording, min_s: float = MIN_STOP_S) -> list[tuple[float, float, str]]:
    """Standing stops ``(t0_s, t1_s, "standing")`` of ``min_s`` (s) or more from the mode truth (module docstring);
    adjacent still intervals (standing, then sitting) are one stop.
    """
    m = rec.truth.modes
    if m is None:
        return []
    still = sorted((float(a), float(b)) for a, b, lab in zip(m.t_start_s, m.t_end_s, m.label, strict=True)
                   if lab in STILL_TRUTH_LABELS)
    merged: list[list[float]] = []
    for a, b in still:
        if merged and a <= merged[-1][1] + 1e-6:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return [(a, b, STOP_LABEL) for a, b in merged if b - a >= min_s]


def still_windows(res: WindowResults, hop_s: float) -> list[Stop]:
    """The model's windows labelled one of ``STILL_CLASSES``, each as the ``hop_s`` (s) around its centre."""
    mid = 0.5 * (np.asarray(res.t_start_s) + np.asarray(res.t_end_s))
    still = np.isin(np.asarray(res.label, dtype=object), STILL_CLASSES)
    return [Stop(float(c - 0.5 * hop_s), float(c + 0.5 * hop_s)) for c in mid[still]]


def coverage(stops: Sequence[Stop], t0: float, t1: float) -> float:
    """Fraction of ``[t0, t1]`` (s) covered by ``stops``."""
    return sum(max(0.0, min(t1, s.t_end_s) - max(t0, s.t_start_s)) for s in stops) / (t1 - t0)


def _is_driving(rec: Recording) -> bool:
    return rec.truth.modes is not None and "vehicle" in rec.truth.modes.label


def _is_car_scene(rec: Recording) -> bool:
    """A clip of getting into or out of a car (MobiFall CSI/CSO): neither a walk nor a trip."""
    return rec.truth.modes is not None and any(lab in TRANSITIONS for lab in rec.truth.modes.label)


def timeline_figures(model: ContextModel, recs: Sequence[Recording],
                     timeline_of: TimelineOf = step_timeline) -> dict[str, Any]:
    """Per-recording figures and totals (module docstring); ``timeline_of``: the step-mode timeline of a recording."""
    walks: list[dict[str, Any]] = []
    driving: list[dict[str, Any]] = []
    stops_rows: list[dict[str, Any]] = []
    pocket = placement_model("pocket")
    for rec in recs:
        name = Path(rec.source).name if rec.source else "?"
        res = raw_res = None
        try:
            model.check_recording(rec)
        except InputError:
            pass
        else:
            windows = make_windows(rec, model.window, margin_s=model.margin_s)
            raw_res = model.predict_windows(windows)
            res = model.gated(raw_res, window_gravity(windows))
        truth = truth_stops(rec, MIN_STOP_S) + mode_truth_stops(rec)
        if truth and not rec.device.is_foot:  # a shoe IMU's modes come from pdr foot, not a phone timeline
            by_model = res is not None and pocket is not None and \
                placement_model(placement_group(rec.device.placement)) == pocket
            if by_model:
                assert res is not None
                shown: dict[str, list[Stop]] = {STOP_LABEL: still_windows(res, model.window.hop_s)}
            else:
                shown = {}
                for e in timeline_of(rec).entries:
                    shown.setdefault(e.label, []).append(Stop(e.t_start_s, e.t_end_s))
            found = stop_intervals(rec, step_intervals(rec))
            for t0, t1, kind in truth:
                cov = coverage(shown.get(kind, []), t0, t1)
                stops_rows.append({"recording": name, "t0_s": t0, "t1_s": t1, "kind": kind,
                                   "landmarks": rec.truth.positions is not None
                                   and rec.truth.positions.kind == "landmark",
                                   "timeline": "model" if by_model else "steps", "coverage": cov,
                                   "coverage_rule": coverage(found, t0, t1), "found": cov >= MIN_COVERAGE})
        if _is_car_scene(rec):
            continue
        if res is None:
            if not _is_driving(rec):
                walks.append({"recording": name, "windows": 0, "vehicle_labels": 0, "ungated_vehicle_labels": 0,
                              "note": "not classifiable (missing stream): step modes"})
            continue
        assert raw_res is not None
        labels = np.asarray(res.label, dtype=object)
        ungated = np.asarray(raw_res.label, dtype=object)
        if _is_driving(rec):
            driving.append({"recording": name, "windows": int(labels.size),
                            "vehicle_fraction": float(np.mean(labels == "vehicle")) if labels.size else 0.0})
        else:
            bad = int(np.isin(labels, VEHICLE_LABELS).sum())
            raw = int(np.isin(ungated, VEHICLE_LABELS).sum())
            walks.append({"recording": name, "placement": rec.device.placement, "windows": int(labels.size),
                          "vehicle_labels": bad, "ungated_vehicle_labels": raw})
    long_stops = [r for r in stops_rows if r["landmarks"] and r["t1_s"] - r["t0_s"] >= MIN_TRUTH_STOP_S]
    return {
        "walks": walks, "driving": driving, "stops": stops_rows,
        "walk_recordings": len(walks),
        "walk_recordings_with_vehicle_labels": sum(1 for w in walks if w["vehicle_labels"]),
        "walk_vehicle_windows": sum(w["vehicle_labels"] for w in walks),
        "walk_vehicle_windows_ungated": sum(w["ungated_vehicle_labels"] for w in walks),
        "driving_vehicle_fraction": (float(np.average([d["vehicle_fraction"] for d in driving],
                                                      weights=[d["windows"] for d in driving]))
                                     if driving and sum(d["windows"] for d in driving) else None),
        "truth_stops": len(long_stops),
        "truth_stops_found": sum(1 for s in long_stops if s["found"]),
        "short_stops": sum(1 for s in stops_rows if s["kind"] == STOP_LABEL),
        "short_stops_found": sum(1 for s in stops_rows if s["kind"] == STOP_LABEL and s["found"]),
    }


def print_timeline(fig: dict[str, Any]) -> None:
    """Human-readable summary of :func:`timeline_figures`."""
    print(f"walking recordings: {fig['walk_recordings']}, with a car_*/vehicle window: "
          f"{fig['walk_recordings_with_vehicle_labels']} ({fig['walk_vehicle_windows']} windows; without the "
          f"transition gate {fig['walk_vehicle_windows_ungated']})")
    for w in fig["walks"]:
        if w["vehicle_labels"] or w["ungated_vehicle_labels"]:
            print(f"  {w['recording']} ({w.get('placement') or 'placement unknown'}): {w['vehicle_labels']} of "
                  f"{w['windows']} windows (ungated {w['ungated_vehicle_labels']})")
    for d in fig["driving"]:
        print(f"driving {d['recording']}: {d['vehicle_fraction']:.3f} of {d['windows']} windows vehicle")
    print(f"truth stops of {MIN_TRUTH_STOP_S:.0f} s or more (IPIN landmarks): {fig['truth_stops_found']} of "
          f"{fig['truth_stops']} covered >= {MIN_COVERAGE:.0%} by timeline entries of their kind")
    print(f"standing stops of {MIN_STOP_S:.0f} s or more (landmarks, mode truth): {fig['short_stops_found']} of "
          f"{fig['short_stops']} covered >= {MIN_COVERAGE:.0%} by still entries")
    for s in fig["stops"]:
        print(f"  {s['recording']} {s['t0_s']:7.1f}-{s['t1_s']:7.1f} s {s['kind']:13s} coverage "
              f"{s['coverage']:.2f} on the {s['timeline']} timeline (stop rule alone {s['coverage_rule']:.2f})"
              f"{'' if s['found'] else '  MISSED'}")
