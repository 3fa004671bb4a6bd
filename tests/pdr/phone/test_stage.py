"""The stage protocol: a plugged-in step stage sees every step, may correct the track, and its state is saved and
restored with the pipeline's; the typed events and their rows."""

from dataclasses import fields, replace
from typing import Any

import numpy as np
import pytest

from pdr import state_codec
from pdr.errors import InputError
from pdr.phone.events import (
    ElevatorEvent,
    FloorChangeEvent,
    LandmarkEvent,
    NoticeEvent,
    PipelineEvent,
    StepEvent,
    event_from_row,
)
from pdr.phone.history import SampleHistory
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.phone.stage import StepObserver, StepStage
from pdr.phone.track import TrackState
from pdr.sim import load_scenario, simulate
from tests.conftest import REPO_ROOT

SIM = REPO_ROOT / "mobile_logs" / "sim"


class CorridorSnap:
    """A map-matcher-like stage: every position is projected onto the north-south corridor ``east = x`` (the track is
    fixed there), and each step whose position it moved by more than ``notice_m`` adds a notice.
    """

    name = "corridor"

    def __init__(self, x: float, notice_m: float = 5.0) -> None:
        self.x, self.notice_m = x, notice_m
        self.moved_m = 0.0

    def step(self, event: StepEvent, track: TrackState) -> tuple[StepEvent, list[PipelineEvent]]:
        d = abs(track.east_m - self.x)
        self.moved_m += d
        track.fix(self.x, track.north_m, 0.25)
        more: list[PipelineEvent] = [NoticeEvent(f"snapped by {d:.1f} m")] if d > self.notice_m else []
        return replace(event, east_m=track.east_m, pos_sigma_m=float(np.sqrt(np.trace(track.P)))), more

    def state(self) -> dict[str, Any]:
        return {"moved_m": self.moved_m}

    def from_state(self, d: dict[str, Any]) -> "CorridorSnap":
        o = CorridorSnap(self.x, self.notice_m)
        o.moved_m = float(d["moved_m"])
        return o


@pytest.fixture(scope="module")
def hand_walk():
    return simulate(load_scenario(SIM / "hand_escalator.json"), 1)


def test_a_plugged_in_stage_corrects_every_step_and_resumes_from_a_saved_state(hand_walk):
    assert isinstance(CorridorSnap(0.0), StepStage)
    free = track_rows(PdrPipeline(PipelineConfig()).run(hand_walk))
    assert max(abs(r["east_m"]) for r in free) > 1.0          # the walk leaves the corridor without the stage
    p = PdrPipeline(PipelineConfig(), stages=[CorridorSnap(0.0)])
    rows = track_rows(p.run(hand_walk))
    assert len(rows) == len(free) and all(r["east_m"] == 0.0 for r in rows)
    # Same headings and lengths: the stage runs after the heading and length stages.
    assert [r["heading_deg"] for r in rows] == [r["heading_deg"] for r in free]
    assert [r["step_length_m"] for r in rows] == [r["step_length_m"] for r in free]
    # Save half-way, resume with a fresh stage: the same track and the stage's own state carried over.
    t0, t1 = hand_walk.time_span_s()
    mid = 0.5 * (t0 + t1)
    a = PdrPipeline(PipelineConfig(), stages=[CorridorSnap(0.0)])
    first = a.update(hand_walk.slice_time(t0, mid))
    state = state_codec.loads(state_codec.dumps(a.state()))
    assert state["stages"]["corridor"]["moved_m"] > 0.0
    b = PdrPipeline.from_state(state, stages=[CorridorSnap(0.0)])
    assert b.stages[0].moved_m == a.stages[0].moved_m  # type: ignore[attr-defined]
    rest = b.update(hand_walk.slice_time(mid, t1 + 1)) + b.finish()
    assert track_rows(first + rest) == rows


class StepTimes:
    """A step observer: the start and end time (s) of every confirmed step, from the history it is shown."""

    def __init__(self) -> None:
        self.spans: list[tuple[float, float]] = []

    def confirmed(self, s: int, e: int, history: SampleHistory) -> None:
        t = history.t[history.sl(s, e)]
        self.spans.append((float(t[0]), float(t[-1])))


def test_an_observer_sees_every_confirmed_step_and_changes_nothing(hand_walk):
    watch = StepTimes()
    assert isinstance(watch, StepObserver)
    free = PdrPipeline(PipelineConfig()).run(hand_walk)
    watched = PdrPipeline(PipelineConfig(), observers=[watch]).run(hand_walk)
    assert watched == free
    # Every step the pipeline emits was shown to the observer, with the step's own samples.
    assert [r["t_start_s"] for r in track_rows(free)] == [a for a, _ in watch.spans]
    assert all(b > a for a, b in watch.spans)


def test_a_state_without_plugged_in_stages_has_no_stages_key(hand_walk):
    assert "stages" not in PdrPipeline(PipelineConfig()).state()


def test_event_rows_round_trip_and_keep_their_fields():
    ev: list[PipelineEvent] = [
        FloorChangeEvent(1.5, 1.0, 0.0), LandmarkEvent(2.0, "S1", "stairs_up"), NoticeEvent("no barometer"),
        ElevatorEvent(3.0, 9.0, "up", 4.1, None), ElevatorEvent(3.0, 9.0, "down", -4.0, 12.5, "E1")]
    rows = [e.to_row() for e in ev]
    assert rows[0] == {"type": "floor_change", "t_s": 1.5, "floor": 1.0, "from_floor": 0.0, "height_assumed": False}
    assert "site_landmark" not in rows[3] and rows[4]["site_landmark"] == "E1"
    assert [event_from_row(r) for r in rows] == ev
    with pytest.raises(InputError, match="unknown event type"):
        event_from_row({"type": "teleport"})
    with pytest.raises(InputError, match="bad landmark event"):
        event_from_row({"type": "landmark", "t_s": 1.0})


def test_step_rows_have_the_fields_of_the_step_event_in_order(hand_walk):
    rows = track_rows(PdrPipeline(PipelineConfig()).run(hand_walk))
    assert list(rows[0]) == ["type", *(f.name for f in fields(StepEvent))]
    assert event_from_row(rows[0]).to_row() == rows[0]
