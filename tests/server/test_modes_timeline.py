"""The modes timeline the phone processor builds: stop entries placed among the step-mode entries."""

from __future__ import annotations

from pathlib import Path

import pytest

from classifiers.timeline import ModeEntry, StepModes
from pdr.phone.events import StairFlightEvent, StepEvent
from server.phone_processor import convert_events


def test_convert_events_places_stops_among_the_steps():
    def step(t0: float) -> StepEvent:
        return StepEvent(t_s=t0 + 0.5, t_start_s=t0, east_m=0.0, north_m=0.0, up_m=0.0, floor=0.0, heading_deg=0.0,
                         step_length_m=0.7, turn_deg=0.0, mode="walking", placement="hand", heading_sigma_deg=5.0,
                         pos_sigma_m=0.1, patterns=[], heading_raw_deg=0.0, gyro_heading_deg=None, up_time_s=None,
                         gyro_bias_dps=None, position_fix=False, landmark_heading=False)

    events = [step(t) for t in (0.0, 0.5, 1.0)] + [step(t) for t in (10.0, 10.5)]
    stop = ModeEntry(1.5, 10.0, "standing", {"duration_s": 8.5})
    modes = StepModes()
    out = convert_events(events, modes, stops=[stop])
    rows = [(r.t_s, r.t_end_s, r.label) for r in out.events if r.kind == "mode"]
    assert rows == [(0.0, None, "walking"), (1.5, 10.0, "standing"), (10.0, None, "walking")]
    assert modes.last == "walking" and out.track == events      # the steps are stored as they are
    # The classifier's timeline (pocket phones) takes no step-mode entries.
    assert not [r for r in convert_events(events, StepModes(), step_modes=False).events if r.kind == "mode"]


def test_a_stair_flight_is_a_landmark_with_its_floors():
    flight = StairFlightEvent(t_start_s=18.1, t_end_s=29.6, direction="up", steps=19, altitude_change_m=2.7,
                              floors=1)
    rows = convert_events([flight]).events
    assert [(r.kind, r.t_s, r.t_end_s, r.label) for r in rows] == [("landmark", 18.1, 29.6, "stair_flight")]
    assert rows[0].data == {"t_start_s": 18.1, "t_end_s": 29.6, "direction": "up", "steps": 19,
                            "altitude_change_m": 2.7, "floors": 1}
    # Without a barometer the flight has no floor count, and says nothing of one.
    no_baro = StairFlightEvent(t_start_s=18.1, t_end_s=29.6, direction="up", steps=19,
                               altitude_change_m=0.0)
    data = convert_events([no_baro]).events[0].data
    assert data is not None and "floors" not in data


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_escalator_ride_appears_in_modes_with_its_floor_change(tmp_path):
    # The simulated hand-held escalator walk: one floor down on an escalator, walking before and after.
    from server import auth
    from tests.server.conftest import bearer, make_app
    from tests.server.helpers import multipart

    app = make_app(tmp_path, processor_factory=None)
    try:
        with app.extensions["pdr"].store.engine.begin() as conn:
            token = auth.add_user(conn, "walker")
        log = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim" / "hand_escalator.zip"
        body, ctype = multipart({"file": (log.read_bytes(), log.name), "placement": "hand"})
        c = app.test_client()
        resp = c.post("/api/v1/sessions", data=body, headers=bearer(token), content_type=ctype)
        assert resp.status_code == 201, resp.get_json()
        assert app.extensions["pdr"].worker.wait_idle(240)
        modes = c.get(f"/api/v1/sessions/{resp.get_json()['id']}/modes", headers=bearer(token)).get_json()["modes"]
    finally:
        app.extensions["pdr"].worker.stop()
    rides = [m for m in modes if m["label"].startswith(("elevator", "escalator"))]
    assert [m["label"] for m in rides] == ["escalator_down"], modes
    assert rides[0]["floors"] == 1 and rides[0]["t_s"] < 26.0 and rides[0]["t_end_s"] > 14.0
    assert not any(m["label"].startswith("stairs") for m in modes), modes  # walking off is not stairs


@pytest.mark.timeout(300)
def test_a_stop_streamed_in_batches_is_on_the_log_clock_whatever_their_t0_ns(tmp_path):
    # A phone at rest streamed as native batches on Unix-time timestamps, each batch without t0_ns (so its axis
    # starts at its own first sample) and one with a t0_ns of its own choosing: the standing entry of /modes was
    # on the first batch's axis (t_s 0, or none at all), not the log clock of the track and of every other entry;
    # a batch with t0_ns -5 made the stop detector allocate 25 GiB (the batch failed, MemoryError).
    from server import auth
    from tests.server.conftest import bearer, make_app
    from tests.server.helpers import phone_batch

    app = make_app(tmp_path, processor_factory=None)
    try:
        with app.extensions["pdr"].store.engine.begin() as conn:
            h = bearer(auth.add_user(conn, "walker"))
        c = app.test_client()
        sid = c.post("/api/v1/sessions", json={"session_id": "rest"}, headers=h).get_json()["id"]
        for i in range(6):
            batch = phone_batch(f"b{i}", float(i))
            del batch["t0_ns"]
            if i == 3:
                batch["t0_ns"] = 1_600_000_000_000_000_000
            assert c.post(f"/api/v1/sessions/{sid}/batches", json=batch, headers=h).status_code == 201
        assert app.extensions["pdr"].worker.wait_idle(240)
        detail = c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
        modes = c.get(f"/api/v1/sessions/{sid}/modes", headers=h).get_json()["modes"]
    finally:
        app.extensions["pdr"].worker.stop()
    assert [b["status"] for b in detail["batch_list"]] == ["done"] * 6, detail["batch_list"]
    t0 = 1_700_000_000.0  # the first sample, s on the log clock (phone_batch's timestamps)
    standing = [m for m in modes if m["label"] == "standing"]
    assert len(standing) == 1, modes
    assert t0 <= standing[0]["t_s"] < t0 + 1.0 and t0 + 5.0 <= standing[0]["t_end_s"] <= t0 + 6.0, modes
