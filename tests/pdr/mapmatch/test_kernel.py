"""The map matcher's compiled step kernels equal the numpy expressions of the module doc, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pdr.mapmatch.kernel import advance_particles, cloud_summary, resample_summary
from pdr.site.geometry import segments_cross
from pdr.site.wall_index import WallIndex

# A room 10 m x 4 m with a 2 m wall sticking into it from the south at x = 5.
WALLS = np.array([[0, 0, 10, 0], [10, 0, 10, 4], [10, 4, 0, 4], [0, 4, 0, 0], [5, 0, 5, 2]], dtype=np.float64)


def first_wall_sine(p0, p1):
    """|sin| of the angle between the step p0 -> p1 and the first wall it meets (0 when it meets none)."""
    hits = [(t, k) for k, w in enumerate(WALLS) if (t := crossing_fraction(p0, p1, w)) is not None]
    if not hits:
        return 0.0
    w = WALLS[min(hits)[1]]
    d, e = p1 - p0, w[2:] - w[:2]
    return abs(d[0] * e[1] - d[1] * e[0]) / (np.hypot(*d) * np.hypot(*e))


def crossing_fraction(p0, p1, w):
    """Where along p0 -> p1 (0..1) it crosses the wall segment ``w`` (None: it does not)."""
    if not segments_cross(np.array([[*p0, *p1]]), w[None, :])[0, 0]:
        return None
    r, s = p1 - p0, w[2:] - w[:2]
    den = r[0] * s[1] - r[1] * s[0]
    q = w[:2] - p0
    return 0.0 if den == 0 else min(max((q[0] * s[1] - q[1] * s[0]) / den, 0.0), 1.0)


def reference_step(pos, offset, scale, noise, turn, relax, walk, scale_walk, bounds, yaw, length, hs, ls, inflate):
    """The per-step update written as numpy expressions (the form the kernels replaced)."""
    offset = (offset + turn) * relax + walk * noise[0]
    scale = np.clip(scale + scale_walk * noise[1], *bounds)
    for f in (1.0, inflate):
        psi = yaw + offset + f * hs * noise[2]
        step = np.maximum(length * scale + f * ls * noise[3], 0.0)
        new = pos + step[:, None] * np.column_stack([np.cos(psi), np.sin(psi)])
        alive = ~segments_cross(np.hstack([pos, new]), WALLS).any(axis=1)
        if alive.any():
            break
    across = np.array([first_wall_sine(a, b) for a, b in zip(pos, new, strict=True)])
    return offset, scale, new, alive, across


@pytest.mark.parametrize("length", [0.7, 30.0])       # 30 m: every particle crosses a wall, the retry also fails
def test_advance_and_resample_equal_the_numpy_expressions(length: float) -> None:
    rng = np.random.default_rng(3)
    n = 500
    pos = np.column_stack([rng.uniform(0.5, 9.5, n), rng.uniform(0.5, 3.5, n)])
    offset, scale = rng.normal(0, 0.3, n), rng.normal(1, 0.1, n)
    noise = rng.standard_normal((4, n))
    args = (0.05, math.exp(-0.7 / 40.0), math.radians(2.0), 0.001, (0.6, 1.6), 0.3, length, math.radians(3.0), 0.05)
    want_off, want_scale, want_new, want_alive, want_across = reference_step(pos, offset, scale, noise, *args, 3.0)
    off, sc = offset.copy(), scale.copy()
    new, alive, across, n_alive = advance_particles(pos, off, sc, noise, *args, WallIndex.build(WALLS), 3.0)
    assert np.array_equal(off, want_off) and np.array_equal(sc, want_scale)
    assert np.array_equal(new, want_new) and alive.tolist() == want_alive.tolist()
    assert np.allclose(across, want_across, atol=1e-12)
    assert n_alive == int(want_alive.sum())
    if length > 10:
        assert n_alive == 0
        return
    assert 0 < n_alive < n                 # some particles walked into the walls
    draws = rng.integers(0, n_alive, n - n_alive)
    pick = np.arange(n)
    pick[~alive] = np.flatnonzero(alive)[draws]
    graze = math.sin(math.radians(45.0))
    want_sc = np.where(across < graze, sc, sc[pick])        # a grazing death keeps its own scale,
    want_off = np.where(alive | (across < graze), off[pick], off)      # a head-on death its own heading offset
    assert 0 < np.sum(~alive & (across < graze)) < np.sum(~alive)      # both kinds of death occur
    got = resample_summary(new, off, sc, alive, draws, across, graze)
    for a, b in zip(got[:4], (new[pick], want_off, want_sc, pick), strict=True):
        assert np.array_equal(a, b)
    assert got[4:] == cloud_summary(new[pick], want_off, want_sc)
    plain = resample_summary(new, off, sc, alive, draws, across, 0.0)     # every death head-on: own offsets
    assert np.array_equal(plain[1], off) and np.array_equal(plain[2], sc[pick])
