"""A site description from a Microsoft Indoor Location floor folder (``geojson_map.json``, ``floor_info.json``).

The dataset's floor map is lon/lat GeoJSON: the first feature is the floor's outline, the others are shops and
other rooms. Its waypoints are in metres in a frame whose origin is the south-west corner of the outline's
bounding box, x east and y north, scaled so that the box measures ``floor_info.json``'s ``width`` by ``height``
(metres). The walkable area is the outline with every room as a hole; the frame's +y axis is geographic north
(``frame_bearing_deg`` absent: 0).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.site.plan import SitePlan

_FLOOR_NAME = re.compile(r"^(?P<kind>[BF])(?P<n>\d+)$", re.IGNORECASE)


def ms_floor_number(name: str) -> int:
    """``F3`` -> 3, ``B1`` -> -1 (the dataset's floor folder names)."""
    m = _FLOOR_NAME.match(name)
    if m is None:
        raise InputError(f"floor folder name {name!r} is not F<n> or B<n>", source=name, field="floor")
    n = int(m["n"])
    return -n if m["kind"].upper() == "B" else n


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"cannot read ({exc})", source=str(path)) from None


def site_from_ms_floor(floor_dir: str | Path) -> dict[str, Any]:
    """The site description (dict, metric frame of the floor's waypoints) of one MS floor folder."""
    d = Path(floor_dir)
    gj, info = _read_json(d / "geojson_map.json"), _read_json(d / "floor_info.json")
    try:
        width, height = float(info["map_info"]["width"]), float(info["map_info"]["height"])
    except (KeyError, TypeError, ValueError):
        raise InputError("expected map_info.width and map_info.height (m)", source=str(d / "floor_info.json"),
                         field="map_info") from None
    feats = gj.get("features") if isinstance(gj, dict) else None
    if not isinstance(feats, list) or len(feats) < 1:
        raise InputError("expected a FeatureCollection whose first feature is the floor outline",
                         source=str(d / "geojson_map.json"), field="features")
    polys = [_polygons(f, f"{d / 'geojson_map.json'} feature {k}") for k, f in enumerate(feats)]
    outline = polys[0]
    pts = np.vstack([np.asarray(r, dtype=np.float64)[:, :2] for p in outline for r in p])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = np.array([width / (hi[0] - lo[0]), height / (hi[1] - lo[1])])

    def metric(ring: Any) -> list[list[float]]:
        return ((np.asarray(ring, dtype=np.float64)[:, :2] - lo) * scale).tolist()

    holes = [metric(p[0]) for rooms in polys[1:] for p in rooms]
    walkable = {"type": "MultiPolygon",
                "coordinates": [[metric(p[0]), *(metric(h) for h in p[1:]), *holes] for p in outline]}
    floor = ms_floor_number(d.name)
    doc = {"name": f"{d.parent.name} {d.name}", "floor_height_m": 4.0, "landmarks": [],
           "floors": [{"floor": floor, "frame": "metric", "walkable": walkable}]}
    SitePlan.from_dict(doc, source=str(d))        # refuse a folder whose plan does not validate
    return doc


def _polygons(feature: Any, where: str) -> list[Any]:
    g = feature.get("geometry") if isinstance(feature, dict) else None
    if not isinstance(g, dict):
        raise InputError("feature without a geometry", source=where, field="geometry")
    if g.get("type") == "Polygon":
        return [g["coordinates"]]
    if g.get("type") == "MultiPolygon":
        return list(g["coordinates"])
    raise InputError(f"geometry type {g.get('type')!r}: expected Polygon or MultiPolygon", source=where,
                     field="type")
