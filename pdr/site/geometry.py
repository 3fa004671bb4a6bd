"""Vectorised planar geometry on rings (closed polylines, metres): point in ring, segment crossings.

A ring is an ``(n, 2)`` array whose last vertex equals the first. Edges are ``(m, 4)`` arrays ``x0, y0, x1, y1``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def ring_edges(ring: FloatArray) -> FloatArray:
    """The ``(n-1, 4)`` edges of a closed ring."""
    r = np.asarray(ring, dtype=np.float64)
    return np.hstack([r[:-1], r[1:]])


def points_in_rings(points: FloatArray, edges: FloatArray, first: NDArray[np.int64]) -> BoolArray:
    """Crossing-number test of ``points`` ``(k, 2)`` against rings whose edges ``(m, 4)`` are concatenated, ring
    ``j``'s from row ``first[j]`` on (:func:`ring_edges`): a ``(k, rings)`` matrix (boundary points: either side).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    x0, y0, x1, y1 = edges[:, 0], edges[:, 1], edges[:, 2], edges[:, 3]
    out = np.zeros((len(p), len(first)), dtype=bool)
    for lo in range(0, len(p), 128):
        px, py = p[lo:lo + 128, 0:1], p[lo:lo + 128, 1:2]
        with np.errstate(divide="ignore", invalid="ignore"):
            hit = ((y0 > py) != (y1 > py)) & (px < x0 + (py - y0) * (x1 - x0) / (y1 - y0))
        out[lo:lo + 128] = (np.add.reduceat(hit.astype(np.int32), first, axis=1) % 2) == 1
    return out


def segments_cross(a: FloatArray, b: FloatArray) -> BoolArray:
    """Whether segments ``a`` ``(k, 4)`` and ``b`` ``(m, 4)`` properly intersect, as a ``(k, m)`` matrix.

    Orientation test: the end points of each segment lie strictly on opposite sides of the other's line, or
    touch it (a zero orientation counts as a crossing, so a step that ends exactly on a wall crosses it); collinear
    segments cross when their bounding boxes overlap.
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    ax0, ay0, ax1, ay1 = (a[:, i:i + 1] for i in range(4))
    bx0, by0, bx1, by1 = (b[None, :, i] for i in range(4))

    def orient(px: FloatArray, py: FloatArray, qx: FloatArray, qy: FloatArray, rx: FloatArray,
               ry: FloatArray) -> FloatArray:
        return np.asarray((qx - px) * (ry - py) - (qy - py) * (rx - px))

    d1 = orient(bx0, by0, bx1, by1, ax0, ay0)
    d2 = orient(bx0, by0, bx1, by1, ax1, ay1)
    d3 = orient(ax0, ay0, ax1, ay1, bx0, by0)
    d4 = orient(ax0, ay0, ax1, ay1, bx1, by1)
    boxes = ((np.minimum(ax0, ax1) <= np.maximum(bx0, bx1)) & (np.minimum(bx0, bx1) <= np.maximum(ax0, ax1))
             & (np.minimum(ay0, ay1) <= np.maximum(by0, by1)) & (np.minimum(by0, by1) <= np.maximum(ay0, ay1)))
    return np.asarray((d1 * d2 <= 0) & (d3 * d4 <= 0) & boxes)


def ring_self_intersection(ring: FloatArray) -> tuple[int, int] | None:
    """The first pair of non-adjacent edges of a closed ring that intersect, else None (edges 0-based)."""
    e = ring_edges(ring)
    n = len(e)
    for lo in range(0, n, 512):
        hit = segments_cross(e[lo:lo + 512], e)
        i = np.arange(lo, min(lo + 512, n))[:, None]
        j = np.arange(n)[None, :]
        adjacent = (np.abs(i - j) <= 1) | ((i == 0) & (j == n - 1)) | ((i == n - 1) & (j == 0))
        hit &= ~adjacent
        bad = np.argwhere(hit)
        if bad.size:
            return int(bad[0, 0] + lo), int(bad[0, 1])
    return None


def ring_area(ring: FloatArray) -> float:
    """Signed shoelace area of a closed ring (m^2, positive counter-clockwise)."""
    r = np.asarray(ring, dtype=np.float64)
    return float(0.5 * np.sum(r[:-1, 0] * r[1:, 1] - r[1:, 0] * r[:-1, 1]))


def simplify_path(path: FloatArray, tolerance_m: float) -> FloatArray:
    """Douglas-Peucker simplification of an open polyline ``(n, 2)`` (m): the vertices that keep every dropped one
    within ``tolerance_m`` of the result.
    """
    p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    if len(p) < 3:
        return p.copy()
    keep = np.zeros(len(p), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(p) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        d = p[b] - p[a]
        rel = p[a + 1:b] - p[a]
        norm = float(np.hypot(*d))
        dist = (np.abs(d[0] * rel[:, 1] - d[1] * rel[:, 0]) / norm if norm > 0 else np.hypot(rel[:, 0], rel[:, 1]))
        k = int(np.argmax(dist))
        if dist[k] > tolerance_m:
            keep[a + 1 + k] = True
            stack += [(a, a + 1 + k), (a + 1 + k, b)]
    return p[keep]


def corridor_ring(path: FloatArray, half_width_m: float) -> FloatArray:
    """A closed ring bounding a corridor of ``half_width_m`` either side of an open polyline ``(n, 2)`` (m), with
    mitred corners (the miter is capped at twice the half width) and ends ``half_width_m`` beyond the path's.
    Valid (not self-intersecting) when every leg is longer than the corridor is wide and the path does not come back
    near itself.
    """
    p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    seg = np.diff(p, axis=0)
    unit = seg / np.hypot(seg[:, 0], seg[:, 1])[:, None]
    p = p.copy()
    p[0] -= unit[0] * half_width_m                  # end caps: the path's ends lie inside
    p[-1] += unit[-1] * half_width_m
    before = np.vstack([unit[:1], unit])             # direction of the leg into each vertex
    after = np.vstack([unit, unit[-1:]])             # and of the leg out of it
    normal_in = np.column_stack([-before[:, 1], before[:, 0]])
    bisector = np.column_stack([-(before + after)[:, 1], (before + after)[:, 0]])
    length = np.hypot(bisector[:, 0], bisector[:, 1])
    bisector = np.where(length[:, None] > 1e-9, bisector / np.maximum(length, 1e-12)[:, None], normal_in)
    cos_half = np.clip(np.sum(bisector * normal_in, axis=1), 0.5, 1.0)
    offset = bisector * (half_width_m / cos_half)[:, None]
    left, right = p + offset, p - offset
    return np.vstack([left, right[::-1], left[:1]])
