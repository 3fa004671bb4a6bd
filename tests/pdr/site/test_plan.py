"""Floor plans: geometry, validation of bad sites (naming the field), the wall index, the MS floor folders."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.site.geometry import points_in_rings, ring_edges, segments_cross
from pdr.site.plan import SitePlan
from pdr.site.wall_index import MAX_CELLS, MAX_ENTRIES, WallIndex, step_hit
from tests.conftest import data_path


def square(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]


def site(walkable: Any, **floor: Any) -> dict[str, Any]:
    return {"name": "t", "floors": [{"floor": 0, "walkable": walkable, **floor}]}


ROOM = {"type": "Polygon", "coordinates": [square(0, 0, 10, 10), square(4, 4, 6, 6)]}


def test_walkable_is_inside_the_outer_ring_and_outside_the_holes() -> None:
    plan = SitePlan.from_dict(site(ROOM)).floor(0)
    pts = np.array([[1, 1], [5, 5], [11, 5], [4.5, 7]])
    assert plan.contains(pts).tolist() == [True, False, False, True]
    assert plan.walls().shape == (8, 4)
    rings = [np.array(square(0, 0, 10, 10), float), np.array(square(4, 4, 6, 6), float)]
    inside = points_in_rings(pts, np.vstack([ring_edges(r) for r in rings]), np.array([0, 4]))
    assert inside.tolist() == [[True, False], [True, True], [False, False], [True, False]]


def test_segment_crossings_including_touching_and_collinear() -> None:
    wall = np.array([[0.0, 0.0, 10.0, 0.0]])
    steps = np.array([[5, -1, 5, 1], [5, 1, 5, 2], [5, 1, 5, 0], [11, 0, 12, 0], [9, 0, 12, 0]], float)
    assert segments_cross(steps, wall)[:, 0].tolist() == [True, False, True, False, True]


def test_the_wall_index_agrees_with_testing_every_wall() -> None:
    rng = np.random.default_rng(3)
    holes = [square(x, y, x + 1.5, y + 1.0) for x in range(2, 40, 4) for y in range(2, 30, 3)]
    plan = SitePlan.from_dict(site({"type": "Polygon", "coordinates": [square(0, 0, 44, 33), *holes]})).floor(0)
    walls = plan.walls()
    idx = WallIndex.build(walls, cell_m=1.5, reach_m=1.2)
    start = rng.uniform(-2, 46, (4000, 2))
    ang, length = rng.uniform(0, 2 * np.pi, 4000), rng.uniform(0, 2.0, 4000)   # some longer than the reach
    end = start + length[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    got = idx.crosses(start[:, 0], start[:, 1], end[:, 0], end[:, 1])
    want = segments_cross(np.hstack([start, end]), walls).any(axis=1)
    assert got.tolist() == want.tolist()
    assert 0.05 < got.mean() < 0.95
    a = np.hstack([start, end])
    hit = [step_hit(s[0], s[1], s[2], s[3], idx.walls, idx.start, idx.wall_ids, idx.origin[0], idx.origin[1],
                    idx.cell_m, idx.reach_m, idx.nx, idx.ny) for s in a]
    assert [k >= 0 for k in hit] == want.tolist()          # meets a wall exactly when crosses() says so
    for s, k in zip(a, hit, strict=True):                   # ... and names the first one along the step
        if k >= 0:
            others = segments_cross(s[None, :], walls)[0]
            assert others[k]
            assert _fraction(s, walls[k]) <= min(_fraction(s, w) for w in walls[others]) + 1e-12


def test_a_wide_plan_or_long_diagonal_walls_get_coarser_cells_with_the_same_answers() -> None:
    # A 19 km plan at 2 m cells would be 9500^2 cells; diagonal walls list every cell of their bounding box.
    rng = np.random.default_rng(5)
    wide = np.array([[0.0, 0.0, 19_000.0, 0.0], [0.0, 0.0, 0.0, 12_000.0]]
                    + [[x, 0.0, x + 9_000.0, 9_000.0] for x in range(0, 10_000, 500)])
    idx = WallIndex.build(wide)
    assert idx.nx * idx.ny <= MAX_CELLS
    assert idx.wall_ids.size <= MAX_ENTRIES
    assert idx.cell_m > 2.0
    k, u = rng.integers(0, len(wide), 3000), rng.uniform(0, 1, (3000, 1))     # steps starting beside the walls
    start = wide[k, :2] + u * (wide[k, 2:] - wide[k, :2]) + rng.normal(0, 1.5, (3000, 2))
    ang, length = rng.uniform(0, 2 * np.pi, 3000), rng.uniform(0, 3.0, 3000)
    end = start + length[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    got = idx.crosses(start[:, 0], start[:, 1], end[:, 0], end[:, 1])
    assert got.tolist() == segments_cross(np.hstack([start, end]), wide).any(axis=1).tolist()
    assert 0.1 < got.mean() < 0.9
    # A building-sized plan keeps its 2 m cells.
    assert WallIndex.build(np.array([[0.0, 0.0, 300.0, 200.0]])).cell_m == 2.0


def _fraction(step: np.ndarray, w: np.ndarray) -> float:
    """Where along ``step`` (0..1) it meets the line of wall ``w`` (0 when collinear)."""
    r, s, q = step[2:] - step[:2], w[2:] - w[:2], w[:2] - step[:2]
    den = r[0] * s[1] - r[1] * s[0]
    return 0.0 if den == 0 else float(np.clip((q[0] * s[1] - q[1] * s[0]) / den, 0.0, 1.0))


@pytest.mark.parametrize(("doc", "words"), [
    ({"floors": [{"floor": 0, "walkable": {"coordinates": []}}]}, ["no 'type'", "walkable"]),
    (site({"type": "LineString", "coordinates": [[0, 0], [1, 1]]}), ["LineString"]),
    (site({"type": "Polygon", "coordinates": [[[0, 0], [4, 4], [4, 0], [0, 4], [0, 0]]]}),
     ["ring 0", "intersects itself"]),
    (site({"type": "Polygon", "coordinates": [[[0, 0], [4, 0], [4, 4], [0, 4]]]}), ["not closed"]),
    (site({"type": "Polygon", "coordinates": [[[0, 0], [4, 0], ["a", 4], [0, 0]]]}), ["ring 0"]),
    (site(ROOM, frame="lonlat"), ["origin", "frame"]),
    (site(ROOM, frame="utm"), ["frame", "utm"]),
    (site(ROOM, floor=1.5), ["integer"]),
    ({**site(ROOM), "landmarks": [{"type": "elevator", "floor": 2}]}, ["landmark 0", "floor 2"]),
    ({"floors": [{"floor": 0, "walkable": ROOM}, {"floor": 0, "walkable": ROOM}]}, ["floor 0", "twice"]),
    ({"floors": []}, ["floors"]),
    ({**site(ROOM), "origin": {"lat": 100, "lon": 0}}, ["origin"]),
    # Sizes no building has: accepted, they broke or exhausted the map matcher's wall index (a TypeError for
    # every batch of a session using the site; a grid growing with the square of the plan's width).
    (site({"type": "Polygon", "coordinates": [square(0, 0, 1e308, 1e308)]}), ["ring 0", "from the frame's origin"]),
    (site({"type": "Polygon", "coordinates": [square(0, 0, 200_000, 100_000)]}), ["200 km", "millimetres"]),
    (site(ROOM, floor=10 ** 30), ["floor 1000000000000000019884624838656", "building"]),
    # Numbers read loosely (a service sweep): strings and booleans were coerced, absurd sizes kept.
    (site({"type": "Polygon", "coordinates": [[["0", 0], [4, 0], [4, 4], [0, 4], ["0", 0]]]}),
     ["ring 0", "positions of numbers"]),
    (site({"type": "Polygon", "coordinates": [[[True, 0], [4, 0], [4, 4], [0, 4], [True, 0]]]}),
     ["ring 0", "positions of numbers"]),
    (site(ROOM, floor="0"), ["floor must be an integer, not str '0'"]),
    (site(ROOM, floor=True), ["floor must be an integer, not bool"]),
    (site(ROOM, altitude_m=1e300), ["altitude_m", "10000"]),
    (site(ROOM, altitude_m="3"), ["altitude_m must be a number, not str"]),
    ({**site(ROOM), "floor_height_m": "3"}, ["floor_height_m must be a number, not str"]),
    ({**site(ROOM), "floor_height_m": 1e308}, ["floor_height_m", "at most 100 m"]),
    ({**site(ROOM), "floor_height_m": 0}, ["floor_height_m", "positive"]),
    ({**site(ROOM), "frame_bearing_deg": 1e300}, ["frame_bearing_deg", "360"]),
    ({**site(ROOM), "origin": {"lat": "45", "lon": 5}}, ["origin.lat must be a number"]),
])
def test_bad_sites_are_refused_naming_what_is_wrong(doc: dict[str, Any], words: list[str]) -> None:
    with pytest.raises(InputError) as exc:
        SitePlan.from_dict(doc, source="s.json")
    text = str(exc.value)
    assert "s.json" in text
    for w in words:
        assert w in text


def test_lonlat_floors_are_projected_about_the_origin() -> None:
    lat0, lon0 = 30.3, 120.13
    d = 1e-4          # about 11 m north, 9.6 m east
    ring = [[lon0, lat0], [lon0 + d, lat0], [lon0 + d, lat0 + d], [lon0, lat0 + d], [lon0, lat0]]
    doc = {"origin": {"lat": lat0, "lon": lon0},
           "floors": [{"floor": 2, "altitude_m": 7.5, "frame": "lonlat",
                       "walkable": {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring]}}}]}
    plan = SitePlan.from_dict(doc)
    x0, y0, x1, y1 = plan.floor(2).bounds()
    assert (x0, y0) == pytest.approx((0, 0), abs=1e-9)
    assert x1 == pytest.approx(9.6, abs=0.05) and y1 == pytest.approx(11.1, abs=0.05)
    assert plan.altitude_m(2) == 7.5 and plan.altitude_m(3) == 12.0       # unlisted: floor_height_m 4
    with pytest.raises(InputError, match="no floor plan for floor 5"):
        plan.floor(5)
    again = SitePlan.from_dict(plan.to_dict())
    assert np.array_equal(again.floor(2).walls(), plan.floor(2).walls())


@pytest.mark.data
@pytest.mark.parametrize("floor", ["F3", "F4"])
def test_every_ms_waypoint_lies_in_the_walkable_area(floor: str) -> None:
    from pdr.io import read_recording
    from pdr.site.ms import site_from_ms_floor
    d = data_path("ms_indoor_location", "site2", floor)
    plan = SitePlan.from_dict(site_from_ms_floor(d)).floor(int(floor[1:]))
    pts = []
    for f in sorted((d / "path_data_files").iterdir()):
        truth = read_recording(f).truth.positions
        assert truth is not None
        pts.append(truth.pos_m[:, :2])
    p = np.vstack(pts)
    assert len(p) > 150
    assert plan.contains(p).all()
    # and the plan is not everything: the bounding box's corners and the rooms are not walkable
    assert plan.contains(np.array([[0.5, 0.5]])).tolist() == [False]


@pytest.mark.parametrize(("body", "match"), [
    ('{"floors": ' + "9" * 5000 + "}", r"Exceeds the limit \(4300 digits\)"),
    ('{"floors": ' + "[" * 100_000 + "]" * 100_000 + "}", "maximum recursion depth"),
])
def test_site_json_beyond_the_parser_names_the_file(tmp_path, body, match):
    """`pdr track --site` with an integer of 5000 digits or arrays nested 100 000 deep failed with a traceback
    (ValueError: Exceeds the limit (4300 digits) for integer string conversion; RecursionError)."""
    from pdr.site.document import read_site_document

    p = tmp_path / "site.json"
    p.write_text(body)
    with pytest.raises(InputError, match=f"cannot read site description .*{match}") as err:
        read_site_document(p)
    assert err.value.source == str(p)
