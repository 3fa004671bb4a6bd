"""Map matching of a finished track: the pipeline's step rows in, the same rows on the floor plan out.

What ``pdr track --site --start`` and ``pdr eval ms --map`` run on the pipeline's output (until the matcher is a
pipeline stage). The rows' floors are relative to the walk's first step; ``floor`` names the site floor the walk
starts on, and each row's floor becomes ``floor`` plus its change since the first step.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from pdr.mapmatch.particles import MapMatchConfig, MapMatcher, smooth_walk, steps_from_rows
from pdr.site.plan import SitePlan


def match_rows(rows: Sequence[dict[str, Any]], site: SitePlan, start_en: tuple[float, float], floor: int,
               config: MapMatchConfig | None = None, smooth: bool = False, source: str = "start"
               ) -> tuple[list[dict[str, Any]], list[str]]:
    """``rows`` with ``east_m``/``north_m`` (m, site frame) and ``floor`` from the map matcher, and its notices.

    ``smooth``: the offline smoother over the whole walk (:func:`pdr.mapmatch.particles.smooth_walk`), else the
    online filter's estimate at each step. The start is checked against the walkable area even without steps.
    """
    steps = steps_from_rows(rows)
    base = steps[0].floor if steps else 0
    steps = [replace(s, floor=floor + s.floor - base) for s in steps]
    if smooth:
        matched, notices = smooth_walk(site, steps, start_en, floor, config, source)
    else:
        matched, notices = MapMatcher(site, start_en, floor, config, source=source).update(steps)
    out = [{**r, "east_m": m.east_m, "north_m": m.north_m, "floor": float(m.floor)}
           for r, m in zip(rows, matched, strict=True)]
    return out, notices
