"""Issue 30's targets for the modes timeline, each figure beside its target (``pdr eval classifier MODEL --targets``).

The figures come from :func:`classifiers.timeline_eval.timeline_figures` (stops, car/vehicle labels in walks,
driving) and :func:`classifiers.floor_eval.floor_figures` (stairs legs, elevator rides, the elevator walk) on the
same recordings, each recording's step-mode timeline computed once; the module docstrings there define each one.
Below them, the per-class figures of that timeline per placement (:mod:`classifiers.timeline_scores`). The
pocket classifier's targets (macro-F1 and stairs F1 on unseen subjects) come from
``pdr eval classifier motion_mode --cv``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from classifiers.floor_eval import floor_figures
from classifiers.model import ContextModel
from classifiers.step_timeline import StepTimeline, step_timeline
from classifiers.timeline_eval import MIN_TRUTH_STOP_S, timeline_figures
from classifiers.timeline_scores import print_scores, timeline_scores
from pdr.phone.landmarks import Site
from pdr.recording import Recording

#: Share of the steps of a floor leg (or of its barometric stairs intervals) labelled stairs the right way.
STAIRS_SHARE_TARGET = 0.9
#: Share of a car trip's windows labelled vehicle.
DRIVING_TARGET = 0.9


def _row(name: str, value: Any, target: str, met: bool | None) -> dict[str, Any]:
    return {"target": name, "value": value, "wanted": target, "met": met}


def target_figures(model: ContextModel, recs: Sequence[Recording], site: Site | None = None) -> dict[str, Any]:
    """The timeline and floor figures and one row per target (``met`` None when the data has no case)."""
    cache: dict[int, StepTimeline] = {}

    def timeline_of(rec: Recording) -> StepTimeline:
        if id(rec) not in cache:
            cache[id(rec)] = step_timeline(rec, site)
        return cache[id(rec)]

    tl = timeline_figures(model, recs, timeline_of)
    fl = floor_figures(recs, site, timeline_of)
    scores = timeline_scores(recs, site, timeline_of)
    long_stops = [s for s in tl["stops"] if s["landmarks"] and s["t1_s"] - s["t0_s"] >= MIN_TRUTH_STOP_S]
    standing = [s for s in long_stops if s["kind"] == "standing"]
    rides = [s for s in long_stops if s["kind"] != "standing"]
    n_st, f_st = len(standing), sum(1 for s in standing if s["found"])
    n_2, f_2 = tl["short_stops"], tl["short_stops_found"]
    rows = [
        _row("stops of 5 s or more (IPIN landmarks) appearing as standing", f"{f_st} of {n_st}", "all",
             f_st == n_st if n_st else None),
        _row("stops of 2 s or more appearing as their own (still) entry", f"{f_2} of {n_2}", "all",
             f_2 == n_2 if n_2 else None),
        _row("elevator stops (IPIN landmarks) appearing as elevator entries",
             f"{sum(1 for s in rides if s['found'])} of {len(rides)}", "all",
             all(s["found"] for s in rides) if rides else None),
        _row("walking recordings with a car_*/vehicle label",
             f"{tl['walk_recordings_with_vehicle_labels']} of {tl['walk_recordings']}", "0",
             tl["walk_recordings_with_vehicle_labels"] == 0 if tl["walk_recordings"] else None),
        _row("driving windows labelled vehicle", tl["driving_vehicle_fraction"], f">= {DRIVING_TARGET}",
             None if tl["driving_vehicle_fraction"] is None else tl["driving_vehicle_fraction"] >= DRIVING_TARGET),
        _row("steps of stairs legs labelled stairs in the right direction", fl["stairs_leg_share"],
             f">= {STAIRS_SHARE_TARGET}",
             None if fl["stairs_leg_share"] is None else fl["stairs_leg_share"] >= STAIRS_SHARE_TARGET),
        _row("  the same inside the legs' barometric stairs intervals", fl["climbing_share"],
             f">= {STAIRS_SHARE_TARGET}",
             None if fl["climbing_share"] is None else fl["climbing_share"] >= STAIRS_SHARE_TARGET),
        _row("  the legs' level steps (pressure holding) labelled walking",
             f"{fl['level_walking']} of {fl['level_steps']}" if fl["stairs_leg_steps"] else None, "", None),
        _row("elevator rides reported with the right floor count",
             f"{fl['elevator_rides_floors_right']} of {fl['elevator_rides']} "
             f"({fl['elevator_rides_reported']} reported)", "all",
             fl["elevator_rides_floors_right"] == fl["elevator_rides"] if fl["elevator_rides"] else None),
        _row("steps labelled stairs in elevator walks", fl["elevator_walk_stairs_steps"], "0",
             fl["elevator_walk_stairs_steps"] == 0 if fl["elevator_walks"] else None),
    ]
    return {"targets": rows, "timeline": tl, "floors": fl, "classes": scores}


def print_targets(fig: dict[str, Any]) -> None:
    """One line per target: figure, target, met / MISSED / no data (a row with no target: a figure beside one)."""
    for r in fig["targets"]:
        v = r["value"]
        shown = f"{v:.3f}" if isinstance(v, float) else ("-" if v is None else str(v))
        state = "" if not r["wanted"] else "no data" if r["met"] is None else ("met" if r["met"] else "MISSED")
        print(f"{r['target']:64s} {shown:>22s}  target {r['wanted']:8s} {state}")
    print("(pocket classifier targets: pdr eval classifier motion_mode --data ... --cv)")
    print_scores(fig["classes"])
