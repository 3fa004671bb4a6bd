"""Corridors about a path (the map-matching benchmark's building): analytic areas and a valid floor plan."""

from __future__ import annotations

import numpy as np

from pdr.site.geometry import corridor_ring, ring_area, ring_self_intersection, simplify_path
from pdr.site.plan import SitePlan


def test_simplify_keeps_corners_and_drops_points_on_straight_legs() -> None:
    leg1 = np.column_stack([np.zeros(11), np.linspace(0.0, 10.0, 11)])
    leg2 = np.column_stack([np.linspace(0.0, -10.0, 11), np.full(11, 10.0)])
    path = np.vstack([leg1, leg2[1:]]) + np.array([0.0, 0.0])
    path[3, 0] += 0.05                                       # a wobble under the tolerance
    assert simplify_path(path, 0.1).tolist() == [[0.0, 0.0], [0.0, 10.0], [-10.0, 10.0]]


def test_an_l_shaped_corridor_has_the_analytic_area_and_contains_its_path() -> None:
    path = np.array([[0.0, 0.0], [0.0, 10.0], [-10.0, 10.0]])
    w = 1.5
    ring = corridor_ring(path, w)
    assert ring_self_intersection(ring) is None
    # Two legs of 10 m with 1.5 m end caps, 3 m wide, mitred at the corner: (10 + 1.5 + 1.5) * 3 m on each leg,
    # less the corner square counted twice, plus the end caps: (13 + 13) * 3 - 3 * 3 = 69 m^2.
    assert abs(abs(ring_area(ring)) - 69.0) < 1e-9
    plan = SitePlan.from_dict({"floors": [{"floor": 0, "walkable": {"type": "Polygon",
                                                                    "coordinates": [ring.tolist()]}}]})
    inside = np.vstack([np.linspace(path[i], path[i + 1], 20) for i in range(2)])
    assert plan.floors[0].contains(inside).all()
    assert not plan.floors[0].contains(np.array([[2.0, 5.0], [-5.0, 12.0], [-5.0, 5.0]])).any()
