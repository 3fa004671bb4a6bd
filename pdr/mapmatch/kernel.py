"""Compiled per-step kernels of the map matcher: carry the offsets and scales, move every particle one step and
test it against the walls (:func:`advance_particles`, which also tells how squarely each dead particle met its
wall), then replace the dead by survivors and summarise the cloud (:func:`resample_summary`).

Equations in :mod:`pdr.mapmatch.particles` (module doc); a loop over the particles instead of a dozen numpy
passes, the wall tests of :func:`pdr.site.wall_index.step_crosses` (and ``step_hit`` for the dead) inside it. The
random draws stay with the caller's numpy generator (its state resumes bit-identically); the kernels apply the
same floating-point operations in the same order as the numpy expressions they replaced.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit
from pdr.site.wall_index import WallIndex, step_crosses, step_hit

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@cached_njit()
def _move(pos: FloatArray, offset: FloatArray, scale: FloatArray, noise: FloatArray, yaw: float, length_m: float,
          heading_sigma: float, length_sigma: float, walls: FloatArray, start: NDArray[np.int64],
          wall_ids: NDArray[np.int64], ox: float, oy: float, cell: float, reach: float, nx: int, ny: int
          ) -> tuple[FloatArray, BoolArray, FloatArray]:
    n = pos.shape[0]
    new = np.empty_like(pos)
    alive = np.empty(n, dtype=np.bool_)
    across = np.zeros(n)
    for i in range(n):
        psi = yaw + offset[i] + heading_sigma * noise[0, i]
        length = max(length_m * scale[i] + length_sigma * noise[1, i], 0.0)
        c, s = math.cos(psi), math.sin(psi)
        new[i, 0] = pos[i, 0] + length * c
        new[i, 1] = pos[i, 1] + length * s
        alive[i] = not step_crosses(pos[i, 0], pos[i, 1], new[i, 0], new[i, 1], walls, start, wall_ids, ox, oy,
                                    cell, reach, nx, ny)
        if not alive[i]:                # which wall it met first (the dead only: the living pay no more)
            k = step_hit(pos[i, 0], pos[i, 1], new[i, 0], new[i, 1], walls, start, wall_ids, ox, oy, cell, reach, nx,
                         ny)
            wx, wy = walls[k, 2] - walls[k, 0], walls[k, 3] - walls[k, 1]
            norm = math.hypot(wx, wy)
            across[i] = abs(c * wy - s * wx) / norm if norm > 0.0 else 1.0
    return new, alive, across


def advance_particles(pos: FloatArray, offset: FloatArray, scale: FloatArray, noise: FloatArray, turn: float,
                      relax: float, offset_walk_rad: float, scale_walk: float, scale_bounds: tuple[float, float],
                      yaw: float, length_m: float, heading_sigma_rad: float, length_sigma_m: float,
                      walls: WallIndex, retry_inflate: float) -> tuple[FloatArray, BoolArray, FloatArray, int]:
    """One step of every particle; ``offset`` and ``scale`` are updated in place.

    ``offset_i = (offset_i + turn) * relax + offset_walk_rad * noise[0, i]`` (rad; eqs. (a), (b) and the random
    walk), ``scale_i = clip(scale_i + scale_walk * noise[1, i], *scale_bounds)``, then the move of ``length_m``
    (m) at ``yaw`` (rad) with the per-step heading and length noise ``noise[2:]`` (standard normal, scaled by
    ``heading_sigma_rad`` and ``length_sigma_m``); if no particle survives, the move is retried once with that
    noise times ``retry_inflate``. Returns the new positions ``(n, 2)`` (m), which crossed no wall, how far
    across the first wall it met each dead particle's step went (``|sin|`` of the angle between step and wall: 1
    head-on, near 0 grazing; 0 for the living), and how many survived.
    """
    return _advance(pos, offset, scale, noise, turn, relax, offset_walk_rad, scale_walk, scale_bounds[0],
                    scale_bounds[1], yaw, length_m, heading_sigma_rad, length_sigma_m, retry_inflate, walls.walls,
                    walls.start, walls.wall_ids, walls.origin[0], walls.origin[1], walls.cell_m, walls.reach_m,
                    walls.nx, walls.ny)


@cached_njit()
def _advance(pos: FloatArray, offset: FloatArray, scale: FloatArray, noise: FloatArray, turn: float, relax: float,
             offset_walk: float, scale_walk: float, lo: float, hi: float, yaw: float, length_m: float,
             heading_sigma: float, length_sigma: float, inflate: float, walls: FloatArray, start: NDArray[np.int64],
             wall_ids: NDArray[np.int64], ox: float, oy: float, cell: float, reach: float, nx: int, ny: int
             ) -> tuple[FloatArray, BoolArray, FloatArray, int]:
    n = pos.shape[0]
    for i in range(n):
        offset[i] = (offset[i] + turn) * relax + offset_walk * noise[0, i]
        scale[i] = min(max(scale[i] + scale_walk * noise[1, i], lo), hi)
    new, alive, across = _move(pos, offset, scale, noise[2:], yaw, length_m, heading_sigma, length_sigma, walls,
                               start, wall_ids, ox, oy, cell, reach, nx, ny)
    n_alive = int(alive.sum())
    if n_alive == 0:
        new, alive, across = _move(pos, offset, scale, noise[2:], yaw, length_m, inflate * heading_sigma,
                                   inflate * length_sigma, walls, start, wall_ids, ox, oy, cell, reach, nx, ny)
        n_alive = int(alive.sum())
    return new, alive, across, n_alive


@cached_njit()
def resample_summary(new: FloatArray, offset: FloatArray, scale: FloatArray, alive: BoolArray,
                     draws: NDArray[np.int64], across: FloatArray, graze_sin: float
                     ) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.int64], float, float, float, float,
                                float]:
    """Each dead particle replaced by the survivor ``draws[j]`` (the ``j``-th dead, in index order; survivors
    counted in index order): positions, offsets, scales and parent indices of the new cloud, and its
    :func:`cloud_summary`. A dead particle takes the survivor's position and corrects only what its death gave
    evidence about (module doc of :mod:`pdr.mapmatch.particles`): one whose step met its wall at a grazing angle
    (``across[i] < graze_sin``, the sines of :func:`advance_particles`) takes the survivor's heading offset and
    keeps its own step-length scale; one that met it head-on takes the survivor's scale and keeps its own offset.
    """
    n = new.shape[0]
    survivors = np.flatnonzero(alive)
    pick = np.arange(n)
    j = 0
    for i in range(n):
        if not alive[i]:
            pick[i] = survivors[draws[j]]
            j += 1
    pos = np.empty_like(new)
    off = np.empty_like(offset)
    sc = np.empty_like(scale)
    for i in range(n):
        k = pick[i]
        pos[i, 0] = new[k, 0]
        pos[i, 1] = new[k, 1]
        off[i] = offset[i] if across[i] >= graze_sin else offset[k]
        sc[i] = scale[i] if across[i] < graze_sin else scale[k]
    mx, my, spread, mean_off, mean_scale = cloud_summary(pos, off, sc)
    return pos, off, sc, pick, mx, my, spread, mean_off, mean_scale


@cached_njit()
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
