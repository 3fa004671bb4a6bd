"""The site description of a scenario: where its stairs, elevators and escalators are and which way they face.

A scenario places landmarks implicitly: a ``stairs`` segment is a flight walked along the current walking
heading, an ``elevator`` segment a cabin entered at the current position, an ``escalator`` segment a ride
along the current heading. :func:`site_document` writes them as the site description JSON that
:class:`pdr.phone.landmarks.Site` reads (``{"name", "floor_height_m", "landmarks": [...]}``), so a simulated walk
can be processed with the landmarks (and the magnetic declination, ``declination_deg``) a surveyor would
have given for the same building (seed 003 Sec. 5:
each landmark carries an interval covering all possible user headings there; the pipeline takes its centre
as ``UH_landmark`` and a sixth of its width as the standard deviation).

Per landmark:

- ``type``: ``stairs_up`` / ``stairs_down`` (the flight as walked), ``elevator``, ``escalator``;
- ``east_m``, ``north_m``: the path point (ENU m, the scenario's start position included) where the segment
  starts: the foot of the flight, the cabin door, the start of the ride;
- ``floor``: the floor at that point;
- ``heading_deg``: compass heading (clockwise from north, deg) of the walk through the landmark, plus and
  minus a half width per type (:data:`HEADING_HALF_WIDTH_DEG`). Stairs and escalators: the heading in the
  middle of the segment. Elevators: the heading of entering it, i.e. the walking heading at the start of the
  ride (turns inside the cabin come after);
- ``radius_m``: match radius (m).

Nothing random is involved: the site depends on the scenario only (:func:`pdr.sim.trajectory.build_path`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from pdr.frames import yaw_to_heading_deg
from pdr.sim.scenario import Scenario, parse_scenario
from pdr.sim.trajectory import build_path

#: Half width (deg) of the heading interval per landmark type: a flight of stairs is walked within about
#: +/-10 degrees of its axis; an escalator or an elevator door leaves less freedom (seed 003 Sec. 5: user
#: heading of taking an escalator or entering an elevator has a smaller variance than walking stairs).
HEADING_HALF_WIDTH_DEG: MappingProxyType[str, float] = MappingProxyType(
    {"stairs": 10.0, "elevator": 5.0, "escalator": 5.0})
#: Match radius of every landmark (m).
DEFAULT_RADIUS_M = 8.0


def site_document(scenario: Scenario | Mapping[str, Any], half_width_deg: Mapping[str, float] | None = None,
                  radius_m: float = DEFAULT_RADIUS_M) -> dict[str, Any]:
    """The site description (JSON object for :meth:`pdr.phone.landmarks.Site.from_dict`) of a scenario's landmarks.

    Parameters
    ----------
    scenario
        A :class:`~pdr.sim.scenario.Scenario` or its JSON object.
    half_width_deg
        Half width of the heading interval (deg) by kind (``stairs``, ``elevator``, ``escalator``); missing
        kinds take :data:`HEADING_HALF_WIDTH_DEG`.
    radius_m
        Match radius of every landmark (m).
    """
    sc = scenario if isinstance(scenario, Scenario) else parse_scenario(scenario)
    widths = {**HEADING_HALF_WIDTH_DEG, **(half_width_deg or {})}
    path = build_path(sc)
    b = sc.boundaries_s
    landmarks: list[dict[str, Any]] = []
    counts: dict[str, int] = {}
    for i, seg in enumerate(sc.segments):
        if seg.kind not in ("stairs", "elevator", "escalator"):
            continue
        t_start = float(b[i])
        t_heading = t_start if seg.kind == "elevator" else 0.5 * (b[i] + b[i + 1])
        pos = path.position(np.array([t_start])).value[0]
        floor = float(path.floor(np.array([pos[2]]))[0])
        heading = float(yaw_to_heading_deg(path.heading.value(np.array([t_heading])).value[0]))
        half = float(widths[seg.kind])
        typ = seg.mode if seg.kind == "stairs" else seg.kind
        counts[seg.kind] = counts.get(seg.kind, 0) + 1
        landmarks.append({
            "id": f"{seg.kind}{counts[seg.kind]}", "type": typ, "east_m": float(pos[0]), "north_m": float(pos[1]),
            "floor": floor, "heading_deg": [float((heading - half) % 360.0), float((heading + half) % 360.0)],
            "radius_m": float(radius_m),
        })
    return {"name": sc.name or "simulated site", "floor_height_m": float(sc.floor_height_m),
            "declination_deg": math.degrees(sc.magnetic.declination_rad), "landmarks": landmarks}
