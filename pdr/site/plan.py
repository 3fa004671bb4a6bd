"""Floor plans of a site description: walkable areas per floor, floor altitudes, geographic north.

The ``floors`` section of a site JSON (the landmarks of the same file are :class:`pdr.phone.landmarks.Site`)::

    {"name": "...", "floor_height_m": 4.0,            # still accepted: altitude of floor k is k * floor_height_m
     "origin": {"lat": 30.30, "lon": 120.13},         # needed by floors in the "lonlat" frame
     "frame_bearing_deg": 0.0,                        # optional: compass bearing of the frame's +y axis
     "floors": [{"floor": 3, "altitude_m": 12.0,      # optional altitude (m) of the floor
                 "frame": "metric" | "lonlat",        # metric (default): site east/north metres
                 "walkable": <GeoJSON Polygon | MultiPolygon | Feature | FeatureCollection of them>}]}

A polygon's first ring bounds walkable area and its further rings are holes (shops, voids, walls). A point is
walkable when it lies inside some polygon's outer ring and inside none of its holes. Every ring edge is a wall.
Site frame: x east, y north (metres) unless ``frame_bearing_deg`` says the frame's y axis points elsewhere (it is
not the landmark section's ``grid_deg``, a main axis of the building for the heading's drift elimination);
``lonlat`` floors are projected about ``origin`` (:func:`pdr.frames.geodetic_to_local_enu`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.frames import geodetic_to_local_enu
from pdr.json_number import json_number
from pdr.site.document import floor_altitude_m, floor_height_m, floors_list, read_site_document
from pdr.site.geometry import points_in_rings, ring_area, ring_edges, ring_self_intersection
from pdr.site.wall_index import WallIndex

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

FRAMES: tuple[str, ...] = ("metric", "lonlat")
#: Largest distance (m) of a metric position from the frame's origin: beyond it no place on Earth is meant (UTM
#: northings stay below 1e7 m), and coordinates that large lose the centimetres of a wall.
MAX_COORDINATE_M = 1e8
#: Widest floor plan (m, either side of its bounding box): no building is wider; a plan this wide is in other units
#: (millimetres) or lon/lat given as metric.
MAX_FLOOR_EXTENT_M = 20_000.0
#: Largest floor number (either sign): no building has more floors.
MAX_FLOOR_NUMBER = 1000


@dataclass(frozen=True)
class WalkablePolygon:
    """One walkable polygon (metres, site frame): its outer ring and holes, each closed ``(n, 2)``."""

    outer: FloatArray
    holes: tuple[FloatArray, ...]


@dataclass(frozen=True)
class FloorPlan:
    """The walkable area of one floor (metres, site frame) and its altitude (m, None when not given)."""

    floor: int
    polygons: tuple[WalkablePolygon, ...]
    altitude_m: float | None = None

    def contains(self, points: FloatArray) -> BoolArray:
        """Whether each of ``points`` ``(k, 2)`` (m) is walkable: inside a polygon's outer ring, in none of its
        holes.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        edges, first, polygon, outer = self._rings
        inside = points_in_rings(p, edges, first)
        out = np.zeros(len(p), dtype=bool)
        for k in range(len(self.polygons)):
            mine = polygon == k
            out |= inside[:, mine & outer].any(axis=1) & ~inside[:, mine & ~outer].any(axis=1)
        return out

    @cached_property
    def _rings(self) -> tuple[FloatArray, NDArray[np.int64], NDArray[np.int64], BoolArray]:
        """All rings' edges, each ring's first edge, its polygon and whether it is an outer ring."""
        rings = [(k, r == 0, ring) for k, p in enumerate(self.polygons) for r, ring in enumerate((p.outer, *p.holes))]
        edges = np.vstack([ring_edges(ring) for _, _, ring in rings])
        first = np.cumsum([0] + [len(ring) - 1 for _, _, ring in rings[:-1]]).astype(np.int64)
        return (edges, first, np.array([k for k, _, _ in rings], dtype=np.int64),
                np.array([o for _, o, _ in rings], dtype=bool))

    def walls(self) -> FloatArray:
        """Every ring edge as ``(m, 4)`` ``x0, y0, x1, y1`` (m)."""
        rings = [r for p in self.polygons for r in (p.outer, *p.holes)]
        return np.vstack([ring_edges(r) for r in rings]) if rings else np.zeros((0, 4))

    @cached_property
    def wall_index(self) -> WallIndex:
        """The walls bucketed in a grid (built once per plan, :mod:`pdr.site.wall_index`)."""
        return WallIndex.build(self.walls())

    def bounds(self) -> tuple[float, float, float, float]:
        """``(min_x, min_y, max_x, max_y)`` of the outer rings (m)."""
        pts = np.vstack([p.outer for p in self.polygons])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    def to_geojson(self) -> dict[str, Any]:
        """The walkable area as a GeoJSON MultiPolygon in the site's metric frame."""
        return {"type": "MultiPolygon", "coordinates": [[p.outer.tolist(), *(h.tolist() for h in p.holes)]
                                                        for p in self.polygons]}


@dataclass(frozen=True)
class SitePlan:
    """The floor plans of a site, the floor height and the bearing of the frame's north axis.

    ``frame_bearing_deg`` (deg clockwise from geographic north, of the frame's +y axis): None or 0 when the frame
    is east/north.
    """

    floors: dict[int, FloorPlan]
    floor_height_m: float = 4.0
    frame_bearing_deg: float | None = None
    origin: tuple[float, float] | None = None

    def floor(self, floor: int, source: str = "site") -> FloorPlan:
        """The plan of ``floor``; a floor the site does not describe is refused naming the known ones."""
        plan = self.floors.get(int(floor))
        if plan is None:
            raise InputError(f"no floor plan for floor {floor} (the site has floors {sorted(self.floors)})",
                             source=source, field="floors")
        return plan

    def start_floor(self, floor: int | None, source: str = "start") -> int:
        """The floor a walk starts on: ``floor`` if the site has it, else (None) the site's only floor; refused
        naming ``source`` when the site has no such floor or several to choose from.
        """
        if floor is None:
            if len(self.floors) != 1:
                raise InputError(f"the start needs a floor: the site has floors {sorted(self.floors)}",
                                 source=source, field="start")
            return next(iter(self.floors))
        self.floor(floor, source)
        return int(floor)

    def check_walkable(self, point_en: tuple[float, float], floor: int, source: str = "start") -> FloorPlan:
        """The plan of ``floor`` if ``point_en`` (m) is walkable on it; else a refusal naming ``source``'s start."""
        plan = self.floor(floor, source)
        if not plan.contains(np.array([point_en], dtype=np.float64))[0]:
            raise InputError(f"start ({point_en[0]:.2f}, {point_en[1]:.2f}) m is outside floor {floor}'s walkable "
                             "area", source=source, field="start")
        return plan

    def altitude_m(self, floor: int) -> float:
        """Altitude of ``floor`` (m): the site's per-floor altitude, else ``floor * floor_height_m``."""
        plan = self.floors.get(int(floor))
        if plan is not None and plan.altitude_m is not None:
            return plan.altitude_m
        return float(floor) * self.floor_height_m

    @classmethod
    def from_dict(cls, d: Any, source: str = "site") -> SitePlan:
        """Parse and validate a site description's floors (errors name the floor, polygon, ring and field)."""
        if not isinstance(d, dict):
            raise InputError("a site description is a JSON object", source=source)
        floors_raw = floors_list(d, source)
        origin = _origin(d.get("origin"), source)
        fh = floor_height_m(d, source)
        grid = d.get("frame_bearing_deg")
        if grid is not None and abs(json_number(grid, source, "frame_bearing_deg")) > 360:
            raise InputError(f"frame_bearing_deg must be a bearing within +/-360 deg, not {grid:g}", source=source,
                             field="frame_bearing_deg")
        floors: dict[int, FloorPlan] = {}
        for i, f in enumerate(floors_raw):
            plan = _floor(f, origin, f"{source} floors[{i}]")
            if plan.floor in floors:
                raise InputError(f"floor {plan.floor} is described twice", source=f"{source} floors[{i}]",
                                 field="floor")
            floors[plan.floor] = plan
        landmarks = d.get("landmarks")
        for j, lm in enumerate(landmarks if isinstance(landmarks, list) else []):  # else the landmarks' reader refuses
            try:
                floor = float(lm["floor"]) if isinstance(lm, dict) and "floor" in lm else math.nan
            except (TypeError, ValueError, OverflowError):  # no number: the landmarks' reader refuses it
                floor = math.nan
            if math.isfinite(floor) and int(floor) not in floors:
                raise InputError(f"landmark on floor {lm['floor']}, which has no floor plan (floors "
                                 f"{sorted(floors)})", source=f"{source} landmark {j}", field="floor")
        return cls(floors, fh, None if grid is None else float(grid), origin)

    @classmethod
    def load(cls, path: str | Path) -> SitePlan:
        return cls.from_dict(read_site_document(path), source=str(path))

    def to_dict(self) -> dict[str, Any]:
        """The floors section in the metric frame (merge it into a site description with landmarks)."""
        out: dict[str, Any] = {"floor_height_m": self.floor_height_m}
        if self.frame_bearing_deg is not None:
            out["frame_bearing_deg"] = self.frame_bearing_deg
        if self.origin is not None:
            out["origin"] = {"lat": self.origin[0], "lon": self.origin[1]}
        out["floors"] = [{"floor": p.floor, **({"altitude_m": p.altitude_m} if p.altitude_m is not None else {}),
                          "frame": "metric", "walkable": p.to_geojson()} for p in self.floors.values()]
        return out


def _origin(o: Any, source: str) -> tuple[float, float] | None:
    if o is None:
        return None
    if not isinstance(o, dict) or "lat" not in o or "lon" not in o:
        raise InputError("origin must be {\"lat\": deg, \"lon\": deg}", source=source, field="origin")
    lat, lon = json_number(o["lat"], source, "origin.lat"), json_number(o["lon"], source, "origin.lon")
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise InputError(f"origin ({lat}, {lon}) is not a latitude/longitude", source=source, field="origin")
    return lat, lon


def _floor(f: Any, origin: tuple[float, float] | None, where: str) -> FloorPlan:
    if not isinstance(f, dict):
        raise InputError("a floor plan is an object", source=where)
    if "floor" not in f:
        raise InputError("missing field 'floor'", source=where, field="floor")
    if isinstance(f["floor"], bool) or not isinstance(f["floor"], int | float):
        raise InputError(f"floor must be an integer, not {type(f['floor']).__name__} {f['floor']!r:.40}",
                         source=where, field="floor")
    try:
        number = float(f["floor"])
    except OverflowError:
        raise InputError("floor must be an integer of a building", source=where, field="floor") from None
    if not number.is_integer():
        raise InputError(f"floor must be an integer, not {number}", source=where, field="floor")
    if abs(number) > MAX_FLOOR_NUMBER:
        raise InputError(f"floor {number:.0f} is not a floor of a building (at most {MAX_FLOOR_NUMBER} either side of "
                         f"the ground floor)", source=where, field="floor")
    alt = None if f.get("altitude_m") is None else floor_altitude_m(f["altitude_m"], where)
    frame = f.get("frame", "metric")
    if frame not in FRAMES:
        raise InputError(f"frame must be one of {FRAMES}, not {frame!r}", source=where, field="frame")
    if frame == "lonlat" and origin is None:
        raise InputError("a lonlat floor needs the site's origin {\"lat\", \"lon\"} to resolve its frame",
                         source=where, field="origin")
    if "walkable" not in f:
        raise InputError("missing field 'walkable' (GeoJSON polygons)", source=where, field="walkable")
    polys = [_polygon(p, frame, origin, f"{where} walkable polygon {k}")
             for k, p in enumerate(_geojson_polygons(f["walkable"], f"{where} walkable"))]
    if not polys:
        raise InputError("no polygon in 'walkable'", source=where, field="walkable")
    plan = FloorPlan(int(number), tuple(polys), alt)
    x0, y0, x1, y1 = plan.bounds()
    extent = max(x1 - x0, y1 - y0)
    if extent > MAX_FLOOR_EXTENT_M:
        raise InputError(f"the walkable area spans {extent / 1000:.4g} km: a floor plan is in metres and at most "
                         f"{MAX_FLOOR_EXTENT_M / 1000:.0f} km wide (millimetres? lon/lat without \"frame\": "
                         f"\"lonlat\"?)", source=where, field="walkable")
    return plan


def _geojson_polygons(g: Any, where: str) -> list[Any]:
    """The polygon coordinate lists of a GeoJSON geometry, feature or feature collection."""
    if not isinstance(g, dict) or "type" not in g:
        raise InputError("not a GeoJSON object (no 'type')", source=where, field="walkable")
    t = g["type"]
    if t == "FeatureCollection":
        feats = g.get("features")
        if not isinstance(feats, list):
            raise InputError("FeatureCollection without a 'features' list", source=where, field="features")
        return [p for k, ft in enumerate(feats) for p in _geojson_polygons(ft, f"{where} feature {k}")]
    if t == "Feature":
        return _geojson_polygons(g.get("geometry"), f"{where} geometry")
    coords = g.get("coordinates")
    if t == "Polygon":
        return [coords]
    if t == "MultiPolygon":
        if not isinstance(coords, list):
            raise InputError("MultiPolygon coordinates must be a list of polygons", source=where,
                             field="coordinates")
        return list(coords)
    raise InputError(f"geometry type {t!r}: expected Polygon or MultiPolygon", source=where, field="type")


def _polygon(coords: Any, frame: str, origin: tuple[float, float] | None, where: str) -> WalkablePolygon:
    if not isinstance(coords, list) or not coords:
        raise InputError("a polygon is a non-empty list of rings", source=where, field="coordinates")
    rings = []
    for r, ring in enumerate(coords):
        rw = f"{where} ring {r}"
        if not isinstance(ring, list) or not all(
                isinstance(pos, list) and all(isinstance(c, int | float) and not isinstance(c, bool) for c in pos)
                for pos in ring):
            raise InputError("ring is not a list of [x, y] positions of numbers", source=rw, field="coordinates")
        try:
            a = np.asarray(ring, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("ring is not a list of [x, y] positions", source=rw, field="coordinates") from None
        if a.ndim != 2 or a.shape[1] < 2 or a.shape[0] < 4:
            raise InputError("a ring needs at least 4 [x, y] positions", source=rw, field="coordinates")
        a = a[:, :2]
        if not np.isfinite(a).all():
            raise InputError("ring has a non-finite coordinate", source=rw, field="coordinates")
        if frame == "metric" and (np.abs(a) > MAX_COORDINATE_M).any():
            raise InputError(f"ring has a position more than {MAX_COORDINATE_M:.0e} m from the frame's origin",
                             source=rw, field="coordinates")
        if not np.array_equal(a[0], a[-1]):
            raise InputError("ring is not closed (its last position must repeat the first)", source=rw,
                             field="coordinates")
        if frame == "lonlat":
            assert origin is not None
            if (np.abs(a[:, 1]) > 90).any() or (np.abs(a[:, 0]) > 180).any():
                raise InputError("lonlat ring has a position outside [-180, 180] x [-90, 90]", source=rw,
                                 field="coordinates")
            a = geodetic_to_local_enu(a[:, 1], a[:, 0], origin[0], origin[1])
        keep = np.r_[True, np.any(np.diff(a, axis=0) != 0, axis=1)]     # repeated positions: one vertex
        a = a[keep]
        if a.shape[0] < 4:
            raise InputError("a ring needs at least 3 distinct positions", source=rw, field="coordinates")
        bad = ring_self_intersection(a)
        if bad is not None:
            raise InputError(f"ring intersects itself (edges {bad[0]} and {bad[1]})", source=rw,
                             field="coordinates")
        if abs(ring_area(a)) <= 0:
            raise InputError("ring encloses no area", source=rw, field="coordinates")
        rings.append(a)
    return WalkablePolygon(rings[0], tuple(rings[1:]))
