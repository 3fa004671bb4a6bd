"""The phone pipeline's typed events (pdr.phone.events): row form, round trips and bad rows."""

from __future__ import annotations

import dataclasses
import json

import pytest

from pdr.errors import InputError
from pdr.phone import events as ev

STEP = ev.StepEvent(t_s=12.5, t_start_s=12.0, east_m=3.25, north_m=-1.5, up_m=0.0, floor=1.0, heading_deg=87.5,
                    step_length_m=0.71, turn_deg=2.0, mode="walking", placement="hand", heading_sigma_deg=4.0,
                    pos_sigma_m=0.8, patterns=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], heading_raw_deg=85.0,
                    gyro_heading_deg=None, up_time_s=[0.0, 0.1, 12.0], gyro_bias_dps=None, position_fix=False,
                    landmark_heading=True)
EVENTS: list[ev.PipelineEvent] = [
    STEP,
    ev.FloorChangeEvent(30.0, 2.0, 1.0),
    ev.LandmarkEvent(31.5, "S1", "stairs_up"),
    ev.ElevatorEvent(40.0, 55.0, "up", 8.1, 12.5, site_landmark="E2", floors=2),
    ev.ElevatorEvent(60.0, 70.0, "down", -4.0, None),
    ev.StairFlightEvent(80.0, 95.5, "down", 26, -5.4, floors=2),
    ev.NoticeEvent("no magnetometer: the heading is relative"),
]


@pytest.mark.parametrize("event", EVENTS, ids=lambda e: e.KIND)
def test_row_round_trip_through_json(event: ev.PipelineEvent) -> None:
    row = json.loads(json.dumps(event.to_row()))
    assert row["type"] == event.KIND
    assert ev.event_from_row(row) == event


def test_row_fields_in_declaration_order() -> None:
    row = STEP.to_row()
    assert list(row) == ["type"] + [f.name for f in dataclasses.fields(ev.StepEvent)]
    assert row["heading_deg"] == 87.5 and row["patterns"] == STEP.patterns


def test_elevator_without_a_landmark_has_no_landmark_key() -> None:
    row = ev.ElevatorEvent(60.0, 70.0, "down", -4.0, None).to_row()
    assert "site_landmark" not in row and row["floors"] is None
    assert "site_landmark" in ev.ElevatorEvent(60.0, 70.0, "down", -4.0, None, site_landmark="E1").to_row()


def test_to_rows_keeps_the_order() -> None:
    assert [r["type"] for r in ev.to_rows(EVENTS)] == [e.KIND for e in EVENTS]


def test_events_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        STEP.east_m = 0.0  # type: ignore[misc]


def test_unknown_keys_are_ignored() -> None:
    row = {**ev.LandmarkEvent(1.0, "L", "walking").to_row(), "extra": 5}
    assert ev.event_from_row(row) == ev.LandmarkEvent(1.0, "L", "walking")


@pytest.mark.parametrize(("row", "match"), [
    ({"type": "jump", "t_s": 1.0}, "unknown event type 'jump'"),
    ({"t_s": 1.0}, "unknown event type None"),
    ({"type": "floor_change", "t_s": 1.0, "floor": 2.0}, "bad floor_change event"),
    ({"type": "step", "t_s": 1.0}, "bad step event"),
])
def test_bad_rows_are_refused(row: dict, match: str) -> None:
    with pytest.raises(InputError, match=match):
        ev.event_from_row(row)
