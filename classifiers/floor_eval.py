"""Figures of the modes timeline on multi-floor walks with surveyed landmarks (IPIN trials 51-53).

The timeline is the one the service builds for a phone the shipped mode model does not take (hand-held,
torso): :func:`classifiers.step_timeline.step_timeline`.

A *floor leg* is the interval between two consecutive landmarks on different floors. It is a stairs leg when
the barometric vertical intervals inside it (:func:`classifiers.datasets.ipin_mode_labels`) are stepped, an
elevator leg when they are not (a rider stands in the cabin); without a barometer, by the landmarks' horizontal
distance (``ELEVATOR_MAX_DISTANCE_M``: switchback stairs end 2-3 m from where they start, so distance alone
misnames them):

* **stairs leg**: the share of its steps
  labelled ``stairs_up``/``stairs_down`` in the direction of the floor change (issue 30 target: >= 90 %).
  A leg also holds the level walk to and from the stairs, so the share is also given over the steps inside
  the leg's barometric stairs intervals (:func:`classifiers.datasets.ipin_mode_labels`: pressure changing, the
  phone stepping); that truth comes from the same barometer the pipeline reads, so it checks the labelling and
  its lag, not the barometer. The leg's other steps are *level* (the pressure holds: the walk to and from the
  stairs, a landing); how many of them show ``walking`` is given too;
* **elevator leg**: *reported* when an ``elevator_up/down`` entry of the right direction
  overlaps it, with the floor count the entry states (target: every ride reported, with its floor count).

A recording whose floor legs are all elevator legs is an *elevator walk*: its steps labelled stairs are counted
(target: none).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from classifiers.datasets import ELEVATOR_MAX_DISTANCE_M, ipin_mode_labels
from classifiers.step_timeline import TimelineOf, step_timeline
from classifiers.timeline import STAIRS_MODES
from pdr.phone.landmarks import Site
from pdr.recording import Recording


@dataclass(frozen=True)
class FloorLeg:
    """Two consecutive landmarks on different floors: ``[t0_s, t1_s]`` (log clock), floors, kind."""

    t0_s: float
    t1_s: float
    from_floor: float
    to_floor: float
    kind: str  # "stairs" or "elevator"

    @property
    def direction(self) -> str:
        return "up" if self.to_floor > self.from_floor else "down"


def floor_legs(rec: Recording) -> list[FloorLeg]:
    """The recording's floor legs from its landmark truth (module docstring); empty without landmarks."""
    vertical = ipin_mode_labels(rec)
    pos = rec.truth.positions
    if pos is None or pos.kind != "landmark" or pos.floor is None or len(pos) < 2:
        return []
    out = []
    for i in range(len(pos) - 1):
        f0, f1 = float(pos.floor[i]), float(pos.floor[i + 1])
        if not (np.isfinite(f0) and np.isfinite(f1)) or f0 == f1:
            continue
        t0, t1 = float(pos.t_s[i]), float(pos.t_s[i + 1])
        kinds = set() if vertical is None else {
            name.split("_")[0] for a, b, name in zip(vertical.t_start_s, vertical.t_end_s, vertical.label, strict=True)
            if b > t0 and a < t1 and name.split("_")[0] in ("stairs", "elevator")}
        if len(kinds) != 1:
            dist = float(np.linalg.norm(pos.pos_m[i + 1, :2] - pos.pos_m[i, :2]))
            kinds = {"elevator" if dist < ELEVATOR_MAX_DISTANCE_M else "stairs"}
        out.append(FloorLeg(t0, t1, f0, f1, kinds.pop()))
    return out


def floor_figures(recs: Sequence[Recording], site: Site | None = None,
                  timeline_of: TimelineOf | None = None) -> dict[str, Any]:
    """Per-leg and per-recording figures over the recordings with floor legs (module docstring); ``site``: as for
    :func:`step_timeline`; ``timeline_of``: the timeline of a recording (default :func:`step_timeline` with ``site``).
    """
    legs_out: list[dict[str, Any]] = []
    elevator_walks: list[dict[str, Any]] = []
    for rec in recs:
        legs = floor_legs(rec)
        if not legs:
            continue
        name = Path(rec.source).name if rec.source else "?"
        tl = timeline_of(rec) if timeline_of is not None else step_timeline(rec, site)
        vertical = ipin_mode_labels(rec)
        mid = 0.5 * (tl.step_t0_s + tl.step_t1_s)
        on_stairs = (np.asarray(vertical.at(mid), dtype=object) if vertical is not None
                     else np.full(mid.size, "", dtype=object))
        for leg in legs:
            row: dict[str, Any] = {"recording": name, "t0_s": leg.t0_s, "t1_s": leg.t1_s, "kind": leg.kind,
                                   "from_floor": leg.from_floor, "to_floor": leg.to_floor}
            if leg.kind == "stairs":
                inside = (tl.step_t0_s >= leg.t0_s) & (tl.step_t1_s <= leg.t1_s)
                right = inside & (tl.step_label == f"stairs_{leg.direction}")
                climbing = inside & (on_stairs == f"stairs_{leg.direction}")
                level = inside & ~np.isin(on_stairs, STAIRS_MODES)
                row.update(steps=int(inside.sum()), stairs_right=int(right.sum()),
                           share=float(right.sum() / inside.sum()) if inside.any() else 0.0,
                           climbing_steps=int(climbing.sum()), climbing_right=int((climbing & right).sum()),
                           level_steps=int(level.sum()),
                           level_walking=int((level & (tl.step_label == "walking")).sum()))
            else:
                found = [en for en in tl.entries if en.label == f"elevator_{leg.direction}"
                         and en.t_end_s > leg.t0_s and en.t_start_s < leg.t1_s]
                floors = [en.data.get("floors") for en in found]
                row.update(reported=bool(found), floors_reported=floors,
                           floors_right=any(f is not None and f == abs(leg.to_floor - leg.from_floor)
                                            for f in floors))
            legs_out.append(row)
        if all(leg.kind == "elevator" for leg in legs):
            stairs = int(np.isin(tl.step_label, STAIRS_MODES).sum())
            elevator_walks.append({"recording": name, "steps": int(tl.step_label.size), "stairs_steps": stairs})
    stairs_legs = [r for r in legs_out if r["kind"] == "stairs"]
    rides = [r for r in legs_out if r["kind"] == "elevator"]
    n_steps = sum(r["steps"] for r in stairs_legs)
    n_climb = sum(r["climbing_steps"] for r in stairs_legs)
    return {
        "legs": legs_out, "elevator_walks": elevator_walks,
        "stairs_leg_steps": n_steps,
        "stairs_leg_share": (sum(r["stairs_right"] for r in stairs_legs) / n_steps) if n_steps else None,
        "climbing_steps": n_climb,
        "climbing_share": (sum(r["climbing_right"] for r in stairs_legs) / n_climb) if n_climb else None,
        "level_steps": sum(r["level_steps"] for r in stairs_legs),
        "level_walking": sum(r["level_walking"] for r in stairs_legs),
        "elevator_rides": len(rides), "elevator_rides_reported": sum(1 for r in rides if r["reported"]),
        "elevator_rides_floors_right": sum(1 for r in rides if r["floors_right"]),
        "elevator_walk_stairs_steps": sum(w["stairs_steps"] for w in elevator_walks),
    }


def print_floor_figures(fig: dict[str, Any]) -> None:
    """Human-readable summary of :func:`floor_figures`."""
    share = fig["stairs_leg_share"]
    print(f"stairs legs: {share:.3f} of {fig['stairs_leg_steps']} steps labelled stairs in the right direction"
          if share is not None else "stairs legs: none")
    if fig["climbing_share"] is not None:
        print(f"  inside the barometric stairs intervals: {fig['climbing_share']:.3f} of {fig['climbing_steps']} steps")
        print(f"  level steps of the legs (pressure holding): {fig['level_walking']} of {fig['level_steps']} "
              "labelled walking")
    for r in fig["legs"]:
        head = f"  {r['recording']} {r['t0_s']:7.1f}-{r['t1_s']:7.1f} s {r['kind']:8s} " \
               f"{r['from_floor']:+.0f}->{r['to_floor']:+.0f}"
        if r["kind"] == "stairs":
            print(f"{head}: {r['stairs_right']}/{r['steps']} steps, climbing {r['climbing_right']}/"
                  f"{r['climbing_steps']}, level walking {r['level_walking']}/{r['level_steps']}")
        else:
            print(f"{head}: {'reported' if r['reported'] else 'MISSED'}, floors {r['floors_reported']}")
    print(f"elevator rides: {fig['elevator_rides_reported']} of {fig['elevator_rides']} reported, "
          f"{fig['elevator_rides_floors_right']} with the right floor count")
    for w in fig["elevator_walks"]:
        print(f"elevator walk {w['recording']}: {w['stairs_steps']} of {w['steps']} steps labelled stairs")
