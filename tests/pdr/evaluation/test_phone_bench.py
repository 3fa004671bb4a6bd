"""`pdr bench phone --site`: the pipeline timed with the map-matching stage on a corridor its steps fit."""

from __future__ import annotations

import numpy as np

from pdr.evaluation.phone_bench import bench_map_stage, corridor_site, simulated_recording
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows


def test_the_map_stage_is_timed_on_every_step_and_matches_throughout() -> None:
    rec = simulated_recording(120.0)
    free = track_rows(PdrPipeline(PipelineConfig()).run(rec))
    plan, start = corridor_site(free)
    res = bench_map_stage(rec, plan, start, 0)
    assert res["stage_steps"] == res["steps"] == len(free) > 100
    assert res["map_notices"] == 0 and res["stage_wall_s"] > 0 and res["stage_steps_per_s"] > 0
    matched = track_rows(res["_events"])
    xy = np.array([[r["east_m"], r["north_m"]] for r in matched])
    assert plan.floors[0].contains(xy).all()
