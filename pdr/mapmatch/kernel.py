"""Compiled per-step kernel of the map matcher: move every particle one step and test it against the walls.

Equations in :mod:`pdr.mapmatch.particles` (module doc); one loop over the particles instead of a dozen numpy
passes, the wall test of :func:`pdr.site.wall_index.step_crosses` inside it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from pdr.site.wall_index import WallIndex, step_crosses

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def move_particles(pos: FloatArray, offset: FloatArray, scale: FloatArray, noise: FloatArray, yaw: float,
                   length_m: float, heading_sigma_rad: float, length_sigma_m: float, walls: WallIndex
                   ) -> tuple[FloatArray, BoolArray]:
    """New positions ``(n, 2)`` (m) of a step of ``length_m`` at ``yaw`` (rad), and which crossed no wall.

    ``noise`` ``(2, n)``: standard normal draws for the per-step heading and length noise.
    """
    return _move(pos, offset, scale, noise, yaw, length_m, heading_sigma_rad, length_sigma_m, walls.walls,
                 walls.start, walls.wall_ids, walls.origin[0], walls.origin[1], walls.cell_m, walls.reach_m,
                 walls.nx, walls.ny)


@njit(cache=True)
def _move(pos: FloatArray, offset: FloatArray, scale: FloatArray, noise: FloatArray, yaw: float, length_m: float,
          heading_sigma: float, length_sigma: float, walls: FloatArray, start: NDArray[np.int64],
          wall_ids: NDArray[np.int64], ox: float, oy: float, cell: float, reach: float, nx: int, ny: int
          ) -> tuple[FloatArray, BoolArray]:
    n = pos.shape[0]
    new = np.empty_like(pos)
    alive = np.empty(n, dtype=np.bool_)
    for i in range(n):
        psi = yaw + offset[i] + heading_sigma * noise[0, i]
        length = max(length_m * scale[i] + length_sigma * noise[1, i], 0.0)
        new[i, 0] = pos[i, 0] + length * math.cos(psi)
        new[i, 1] = pos[i, 1] + length * math.sin(psi)
        alive[i] = not step_crosses(pos[i, 0], pos[i, 1], new[i, 0], new[i, 1], walls, start, wall_ids, ox, oy,
                                    cell, reach, nx, ny)
    return new, alive


@njit(cache=True)
def cloud_summary(pos: FloatArray, offset: FloatArray, scale: FloatArray) -> tuple[float, float, float, float, float]:
    """Mean position (m), RMS distance from it (m), circular mean of the offsets (rad) and mean scale."""
    n = pos.shape[0]
    mx = my = s = c = k = 0.0
    for i in range(n):
        mx += pos[i, 0]
        my += pos[i, 1]
        s += math.sin(offset[i])
        c += math.cos(offset[i])
        k += scale[i]
    mx /= n
    my /= n
    spread = 0.0
    for i in range(n):
        spread += (pos[i, 0] - mx) ** 2 + (pos[i, 1] - my) ** 2
    return mx, my, math.sqrt(spread / n), math.atan2(s, c), k / n
