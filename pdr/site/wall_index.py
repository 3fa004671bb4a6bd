"""A grid of wall segments for many short-segment crossing tests (the map matcher's particle steps).

The floor's bounding box is cut into square cells of ``cell_m`` (larger where the box would need more than
:data:`MAX_CELLS` of them, or the walls more than :data:`MAX_ENTRIES` listings: a step's test stays exact, a cell
only lists more walls); each cell lists the walls whose bounding box
meets the cell grown by ``reach_m`` on every side. A step that starts in a cell and is at most ``reach_m`` long
lies in that grown cell, so only the cell's list is tested; a longer step, or one that starts outside the grid,
is tested against every wall. The per-step loop is compiled (numba): a few walls per particle instead of
thousands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Most cells of one floor's grid (the index holds an int64 per cell): 1000 x 1000 cells of 2 m cover 2 km square.
MAX_CELLS = 1_000_000
#: Most (cell, wall) entries (an int64 each): a long diagonal wall is listed in every cell of its bounding box.
MAX_ENTRIES = 10_000_000


@dataclass(frozen=True)
class WallIndex:
    """Walls ``(m, 4)`` (m) bucketed in a grid: cell ``k``'s walls are ``wall_ids[start[k]:start[k + 1]]``."""

    walls: FloatArray
    origin: tuple[float, float]
    cell_m: float
    reach_m: float
    nx: int
    ny: int
    start: IntArray
    wall_ids: IntArray

    @classmethod
    def build(cls, walls: FloatArray, cell_m: float = 2.0, reach_m: float = 2.0) -> WallIndex:
        w = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
        if len(w) == 0:
            return cls(w, (0.0, 0.0), cell_m, reach_m, 1, 1, np.zeros(2, dtype=np.int64), np.zeros(0, np.int64))
        w_lo, w_hi = np.minimum(w[:, :2], w[:, 2:]), np.maximum(w[:, :2], w[:, 2:])
        while True:
            lo = w_lo.min(axis=0) - cell_m
            hi = w_hi.max(axis=0) + cell_m
            nx, ny = (int(math.ceil((hi[i] - lo[i]) / cell_m)) for i in range(2))
            i0 = np.clip(np.floor((w_lo - reach_m - lo) / cell_m).astype(np.int64), 0, [nx - 1, ny - 1])
            i1 = np.clip(np.floor((w_hi + reach_m - lo) / cell_m).astype(np.int64), 0, [nx - 1, ny - 1])
            span = i1 - i0 + 1                                   # cells per wall along x and y
            count = span[:, 0] * span[:, 1]
            if nx * ny <= MAX_CELLS and (int(count.sum()) <= MAX_ENTRIES or nx * ny <= 16):
                break               # (a grid of 4 x 4 cells lists each wall a few times: linear in the walls)
            cell_m *= 1.25          # a huge plan, or long diagonal walls: coarser cells (module doc)
        wid = np.repeat(np.arange(len(w), dtype=np.int64), count)
        rank = np.arange(wid.size) - np.repeat(np.cumsum(count) - count, count)   # position in the wall's box
        cell = (i0[wid, 1] + rank // span[wid, 0]) * nx + i0[wid, 0] + rank % span[wid, 0]
        order = np.argsort(cell, kind="stable")
        start = np.zeros(nx * ny + 1, dtype=np.int64)
        np.add.at(start, cell + 1, 1)
        return cls(w, (float(lo[0]), float(lo[1])), cell_m, reach_m, nx, ny, np.cumsum(start),
                   np.ascontiguousarray(wid[order]))

    def crosses(self, x0: FloatArray, y0: FloatArray, x1: FloatArray, y1: FloatArray) -> BoolArray:
        """Whether each step ``(x0, y0) -> (x1, y1)`` (m) meets a wall (touching counts)."""
        return _crosses(np.ascontiguousarray(x0, dtype=np.float64), np.ascontiguousarray(y0, dtype=np.float64),
                        np.ascontiguousarray(x1, dtype=np.float64), np.ascontiguousarray(y1, dtype=np.float64),
                        self.walls, self.start, self.wall_ids, self.origin[0], self.origin[1], self.cell_m,
                        self.reach_m, self.nx, self.ny)


@cached_njit()
def _segment_hits(ax0: float, ay0: float, ax1: float, ay1: float, w: FloatArray, k: int) -> bool:
    bx0, by0, bx1, by1 = w[k, 0], w[k, 1], w[k, 2], w[k, 3]
    if (min(ax0, ax1) > max(bx0, bx1) or min(bx0, bx1) > max(ax0, ax1)
            or min(ay0, ay1) > max(by0, by1) or min(by0, by1) > max(ay0, ay1)):
        return False
    d1 = (bx1 - bx0) * (ay0 - by0) - (by1 - by0) * (ax0 - bx0)
    d2 = (bx1 - bx0) * (ay1 - by0) - (by1 - by0) * (ax1 - bx0)
    d3 = (ax1 - ax0) * (by0 - ay0) - (ay1 - ay0) * (bx0 - ax0)
    d4 = (ax1 - ax0) * (by1 - ay0) - (ay1 - ay0) * (bx1 - ax0)
    return d1 * d2 <= 0.0 and d3 * d4 <= 0.0


@cached_njit()
def _start_cell(x0: float, y0: float, x1: float, y1: float, ox: float, oy: float, cell: float, reach: float,
                nx: int, ny: int) -> int:
    """The grid cell (row-major index) whose wall list covers the step ``(x0, y0) -> (x1, y1)`` (m): the cell of its
    start; -1 when the step is longer than ``reach`` (m) or starts outside the grid (every wall must be tested).
    """
    gx = int(math.floor((x0 - ox) / cell))
    gy = int(math.floor((y0 - oy) / cell))
    if math.hypot(x1 - x0, y1 - y0) > reach or gx < 0 or gy < 0 or gx >= nx or gy >= ny:
        return -1
    return gy * nx + gx


@cached_njit()
def step_crosses(x0: float, y0: float, x1: float, y1: float, walls: FloatArray, start: IntArray, wall_ids: IntArray,
                 ox: float, oy: float, cell: float, reach: float, nx: int, ny: int) -> bool:
    """Compiled test of one step against the indexed walls (the arrays of a :class:`WallIndex`)."""
    c = _start_cell(x0, y0, x1, y1, ox, oy, cell, reach, nx, ny)
    if c < 0:
        for k in range(walls.shape[0]):
            if _segment_hits(x0, y0, x1, y1, walls, k):
                return True
        return False
    for j in range(start[c], start[c + 1]):
        if _segment_hits(x0, y0, x1, y1, walls, wall_ids[j]):
            return True
    return False


@cached_njit()
def _hit_fraction(ax0: float, ay0: float, ax1: float, ay1: float, w: FloatArray, k: int) -> float:
    """Where along the step ``a`` (fraction 0..1) it meets wall ``k``; 2 when it does not."""
    if not _segment_hits(ax0, ay0, ax1, ay1, w, k):
        return 2.0
    bx0, by0, bx1, by1 = w[k, 0], w[k, 1], w[k, 2], w[k, 3]
    rx, ry, sx, sy = ax1 - ax0, ay1 - ay0, bx1 - bx0, by1 - by0
    den = rx * sy - ry * sx
    if den == 0.0:                          # collinear overlap: met at the start
        return 0.0
    return min(max(((bx0 - ax0) * sy - (by0 - ay0) * sx) / den, 0.0), 1.0)


@cached_njit()
def step_hit(x0: float, y0: float, x1: float, y1: float, walls: FloatArray, start: IntArray, wall_ids: IntArray,
             ox: float, oy: float, cell: float, reach: float, nx: int, ny: int) -> int:
    """The first wall (index into ``walls``) that the step ``(x0, y0) -> (x1, y1)`` (m) meets; -1: none. Meets a
    wall exactly when :func:`step_crosses` says so.
    """
    best, first = 2.0, -1
    c = _start_cell(x0, y0, x1, y1, ox, oy, cell, reach, nx, ny)
    if c < 0:
        for k in range(walls.shape[0]):
            f = _hit_fraction(x0, y0, x1, y1, walls, k)
            if f < best:
                best, first = f, k
        return first
    for j in range(start[c], start[c + 1]):
        f = _hit_fraction(x0, y0, x1, y1, walls, wall_ids[j])
        if f < best:
            best, first = f, wall_ids[j]
    return first


@cached_njit()
def _crosses(x0: FloatArray, y0: FloatArray, x1: FloatArray, y1: FloatArray, walls: FloatArray, start: IntArray,
             wall_ids: IntArray, ox: float, oy: float, cell: float, reach: float, nx: int, ny: int) -> BoolArray:
    out = np.zeros(x0.shape[0], dtype=np.bool_)
    for i in range(x0.shape[0]):
        out[i] = step_crosses(x0[i], y0[i], x1[i], y1[i], walls, start, wall_ids, ox, oy, cell, reach, nx, ny)
    return out
