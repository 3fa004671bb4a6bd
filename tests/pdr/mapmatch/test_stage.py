"""The map matcher as a pipeline stage: the same positions as matching the finished causal track, and a session
saved half-way resumes to the same track."""

from __future__ import annotations

import numpy as np
import pytest

from pdr import state_codec
from pdr.io import read_recording
from pdr.mapmatch.rows import match_rows
from pdr.mapmatch.stage import MapMatchStage
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.phone.stage import StepStage
from pdr.site.ms import site_from_ms_floor
from pdr.site.plan import SitePlan
from tests.conftest import data_path

pytestmark = pytest.mark.data


@pytest.fixture(scope="module")
def f3_walk():
    floor = data_path("ms_indoor_location", "site2", "F3")
    rec = read_recording(sorted((floor / "path_data_files").iterdir())[3])
    plan = SitePlan.from_dict(site_from_ms_floor(floor))
    assert rec.truth.positions is not None
    e, n = rec.truth.positions.pos_m[0, :2]
    return rec, plan, (float(e), float(n))


def test_the_stage_matches_each_step_as_the_matcher_on_the_finished_track(f3_walk):
    rec, plan, start = f3_walk
    stage = MapMatchStage(plan, start, 3)
    assert isinstance(stage, StepStage)
    staged = track_rows(PdrPipeline(PipelineConfig(), stages=[stage]).run(rec))
    free = track_rows(PdrPipeline(PipelineConfig(), start_en_m=start).run(rec))
    matched, _ = match_rows(free, plan, start, 3)
    assert len(staged) == len(matched) > 10
    got = np.array([[r["east_m"], r["north_m"]] for r in staged])
    want = np.array([[r["east_m"], r["north_m"]] for r in matched])
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert {r["floor"] for r in staged} == {3.0}
    # The PDR track from the same start drifts off the matched one (the walls did something).
    pdr = np.array([[r["east_m"], r["north_m"]] for r in free])
    assert np.max(np.linalg.norm(got - pdr, axis=1)) > 1.0


def test_a_session_saved_half_way_resumes_to_the_same_matched_track(f3_walk):
    rec, plan, start = f3_walk
    whole = track_rows(PdrPipeline(PipelineConfig(), stages=[MapMatchStage(plan, start, 3)]).run(rec))
    t0, t1 = rec.time_span_s()
    mid = 0.5 * (t0 + t1)
    a = PdrPipeline(PipelineConfig(), stages=[MapMatchStage(plan, start, 3)])
    first = a.update(rec.slice_time(t0, mid))
    state = state_codec.loads(state_codec.dumps(a.state()))
    assert "map_match" in state["stages"]
    b = PdrPipeline.from_state(state, stages=[MapMatchStage(plan, start, 3)])
    rest = b.update(rec.slice_time(mid, t1 + 1)) + b.finish()
    assert track_rows(first + rest) == whole
