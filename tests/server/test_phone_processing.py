"""The real phone processor in the service: PDR track plus motion modes from the shipped classifier."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from tests.conftest import data_path
from tests.server.conftest import bearer, make_app
from tests.server.helpers import multipart

pytestmark = [pytest.mark.data, pytest.mark.timeout(300)]


@pytest.fixture
def real_app(tmp_path):
    from server import auth

    app = make_app(tmp_path, processor_factory=None)
    with app.extensions["pdr"].store.engine.begin() as conn:
        token = auth.add_user(conn, "walker")
    yield app, token
    app.extensions["pdr"].worker.stop()


def _upload(app, token: str, path, placement: str | None = None) -> dict:  # noqa: ANN001
    c = app.test_client()
    form: dict = {"file": (path.read_bytes(), path.name)}
    if placement:
        form["placement"] = placement
    body, content_type = multipart(form)
    resp = c.post("/api/v1/sessions", data=body, headers=bearer(token), content_type=content_type)
    assert resp.status_code == 201, resp.get_json()
    sid = resp.get_json()["id"]
    assert app.extensions["pdr"].worker.wait_idle(240)
    return c.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()


def test_pocket_walk_gets_a_track_and_walking_modes(real_app):
    app, token = real_app
    walk = data_path("mobifall_v2_pocket", "sub2", "ADL", "WAL")
    session = _upload(app, token, next(walk.glob("WAL_acc_*")), placement="trouser_pocket")
    assert session["status"] == "done", session
    assert session["steps"] > 300  # five minutes of walking
    modes = app.test_client().get(f"/api/v1/sessions/{session['id']}/modes", headers=bearer(token)).get_json()
    labels = Counter(m["label"] for m in modes["modes"])
    assert labels.most_common(1)[0][0] == "walking", labels
    assert labels["walking"] / sum(labels.values()) > 0.8


def test_hand_held_walk_uses_step_modes_and_says_so(real_app):
    app, token = real_app
    log = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt")
    session = _upload(app, token, log)
    assert session["status"] == "done" and session["steps"] > 100
    assert any("no mode classifier is installed for a phone carried in the hand" in w for w in session["warnings"])


def test_smoothed_track_equals_pdr_tracks_default(real_app):
    # ?heading=smoothed is pdr track's default output: the causal steps (stored as streamed) with the offline
    # heading smoother run over the inputs kept in the step events.
    from pdr.cli.track import run_pipeline
    from pdr.io import read_recording
    from pdr.phone.heading_smoother import smooth_track
    from pdr.phone.pipeline import PipelineConfig

    app, token = real_app
    log = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial22_repetition01.txt")
    session = _upload(app, token, log, placement="hand")
    c = app.test_client()
    url = f"/api/v1/sessions/{session['id']}/track"
    causal = c.get(url, headers=bearer(token)).get_json()
    smoothed = c.get(url + "?heading=smoothed", headers=bearer(token)).get_json()
    assert causal["heading"] == "causal" and smoothed["heading"] == "smoothed"
    assert smoothed["smoothed_devices"] == ["phone"] and "smoothed_devices" not in causal
    rows, _ = run_pipeline(read_recording(log), PipelineConfig(placement="hand"))
    ours, _ = smooth_track(rows)
    assert smoothed["count"] == causal["count"] == len(ours) > 100
    for key in ("east_m", "north_m", "heading_deg"):
        np.testing.assert_allclose([p[key] for p in smoothed["points"]], [r[key] for r in ours], atol=1e-9)
    # The stored steps are the pipeline's step events, numbered per device (GET /steps).
    steps = c.get(f"/api/v1/sessions/{session['id']}/steps", headers=bearer(token)).get_json()["steps"]
    assert [s["step_index"] for s in steps] == list(range(len(rows)))
    assert [s["placement"] for s in steps] == [r["placement"] for r in rows]
    for key in ("t_start_s", "heading_raw_deg", "gyro_heading_deg", "turn_deg", "pos_sigma_m"):
        np.testing.assert_array_equal([s[key] for s in steps], [r[key] for r in rows])
    moved = np.hypot(*(np.array([[p["east_m"], p["north_m"]] for p in smoothed["points"]])
                       - np.array([[p["east_m"], p["north_m"]] for p in causal["points"]])).T)
    assert moved.max() > 1.0                                       # the smoother changed the track
    # since: the rows after it of the whole smoothed track.
    t_mid = smoothed["points"][50]["t_s"]
    later = c.get(url + f"?heading=smoothed&since={t_mid}", headers=bearer(token)).get_json()
    assert later["points"] == smoothed["points"][51:]
    bad = c.get(url + "?heading=magic", headers=bearer(token))
    assert bad.status_code == 400 and "heading" in bad.get_json()["error"]["message"]
    # The columnar form (the web page's) gives the same smoothed rows, with since.
    columns = c.get(url + f"/columns?heading=smoothed&since={t_mid}", headers=bearer(token)).get_json()
    assert columns["heading"] == "smoothed" and columns["count"] == len(later["points"])
    assert columns["smoothed_devices"] == ["phone"] and columns["heading_notes"] == smoothed["heading_notes"]
    for key in ("t_s", "east_m", "north_m", "heading_deg"):
        assert columns["columns"][key] == [p[key] for p in later["points"]]
    assert columns["columns"]["device"] == [p["device"] for p in later["points"]]
    assert c.get(url + "/columns", headers=bearer(token)).get_json()["heading"] == "causal"
    assert c.get(url + "/columns?heading=magic", headers=bearer(token)).status_code == 400


def _modes(app, token: str, session: dict) -> list[dict]:  # noqa: ANN001
    return app.test_client().get(f"/api/v1/sessions/{session['id']}/modes", headers=bearer(token)).get_json()["modes"]


def _covered(modes: list[dict], label_prefix: str, t0: float, t1: float) -> float:
    """Fraction of [t0, t1] (s) covered by mode entries whose label starts with ``label_prefix``."""
    cover = sum(max(0.0, min(t1, m["t_end_s"]) - max(t0, m["t_s"])) for m in modes
                if m["label"].startswith(label_prefix) and m["t_end_s"] is not None)
    return cover / (t1 - t0)


@pytest.mark.slow
def test_hand_held_stop_is_its_own_standing_entry(real_app):
    # IPIN trial 03 repetition 01: the walker passes landmark 7 at 117.8 s and again, at the same place,
    # at 153.6 s with no step in between: a ~36 s stop in the middle of a 207 s walk.
    app, token = real_app
    session = _upload(app, token, data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial03_repetition01.txt"))
    modes = _modes(app, token, session)
    assert _covered(modes, "standing", 117.8, 153.6) > 0.7, modes
    labels = [m["label"] for m in modes]
    i = labels.index("standing", 1)
    assert "walking" in labels[i + 1:], labels  # the walk resumes after the stop
    assert not any(m["label"].startswith(("car_", "vehicle")) for m in modes)


@pytest.mark.slow
def test_elevator_rides_appear_in_modes_with_their_floor_change(real_app):
    # IPIN trial 53: four elevator rides, each between two landmarks at the same place on different floors.
    app, token = real_app
    log = data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial53_repetition01.mat")
    session = _upload(app, token, log, placement="hand")
    modes = _modes(app, token, session)
    from classifiers.timeline_eval import truth_stops
    from pdr.io import read_recording

    rides = [r for r in truth_stops(read_recording(log)) if r[2].startswith("elevator")]
    assert len(rides) == 4
    for t0, t1, direction in rides:
        found = [m for m in modes if m["label"] == direction and m["t_s"] < t1 and m["t_end_s"] > t0]
        # Two floors each (0 <-> -2), the first one too: the floor height is only learnt from it once the rider
        # walks out, and the 5.8 m ride reads as one floor of the default 4 m before.
        assert found and found[0]["floors"] == 2, (t0, t1, direction, modes)
    assert not any(m["label"].startswith("stairs") for m in modes), modes  # the walk has no stairs


def test_pocket_office_walk_has_no_car_labels_when_standing(real_app):
    # The simulated pocket office walk stands still between its legs: once labelled car_step_in (issue 30).
    from pathlib import Path

    app, token = real_app
    log = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim" / "pocket_office.zip"
    session = _upload(app, token, log, placement="trouser_pocket")
    assert session["status"] == "done", session
    labels = Counter(m["label"] for m in _modes(app, token, session))
    assert not [k for k in labels if k.startswith(("car_", "vehicle"))], labels
    assert labels["stationary"] + labels["standing"] > 0, labels


def test_the_no_classifier_notice_says_whether_the_placement_was_given_or_detected():
    """A session without a placement once read "placement: null" beside "this one is carried in the hand"."""
    from server.phone_processor import PhoneProcessor
    from server.processing import SessionContext

    for placement, auto in (("hand", False), (None, True)):
        proc = PhoneProcessor(SessionContext("s", "phone", placement, {}), None)
        assert proc.pipeline.auto_placement is auto
        proc.pipeline.placement = "hand"  # as the online detector sets it
        _, notice = proc._classify(None)  # type: ignore[arg-type]  # turned off before reading the batch
        if auto:
            assert "detected as carried in the hand (the session names no placement)" in notice
        else:
            assert "for a phone carried in the hand" in notice and "detected" not in notice


def test_a_session_created_with_an_origin_checks_the_magnetometer_against_the_earths_field_there(real_app):
    """A session whose creator says where it is (``origin``) gets the earth's magnetic dip there (World Magnetic
    Model) for its phone pipeline's magnetometer gate, though its batches carry no location; the first batch's
    warnings say so. A session without an origin does not."""
    from pdr.io.native import batch_to_json
    from pdr.sim import load_scenario, simulate
    from tests.conftest import REPO_ROOT

    app, token = real_app
    c = app.test_client()
    walk = simulate(load_scenario(REPO_ROOT / "mobile_logs" / "sim" / "hand_escalator.json"), 1).slice_time(0.0, 30.0)
    warnings = {}
    for name, extra in (("geo", {"origin": {"lat_deg": 49.4614, "lon_deg": 11.1115}}), ("plain", {})):
        sid = c.post("/api/v1/sessions", json={"session_id": name, **extra}, headers=bearer(token)).get_json()["id"]
        r = c.post(f"/api/v1/sessions/{sid}/batches", json=batch_to_json(walk, session_id=name, batch_id="b0"),
                   headers=bearer(token))
        assert r.status_code in (200, 201, 202), r.get_json()
        assert app.extensions["pdr"].worker.wait_idle(120)
        warnings[name] = c.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()["warnings"]
    assert any("earth's field at the recording's location (dip 65." in w for w in warnings["geo"]), warnings["geo"]
    assert not any("earth's field" in w for w in warnings["plain"]), warnings["plain"]


def test_an_undated_location_fix_leaves_the_earths_field_to_the_session_origin_and_says_so(real_app):
    """A first batch whose ``meta.location`` has no ``unix_time_s`` (accepted: it geo-references) gives no earth's
    field, and it kept the session's origin from giving it: the magnetometer went unchecked without a word. Now the
    origin gives it and a warning says why; without an origin a warning says the field is not known."""
    from pdr.io.native import batch_to_json
    from pdr.sim import load_scenario, simulate
    from server.phone_processor import UNDATED_FIX_ORIGIN, UNDATED_FIX_UNUSED
    from tests.conftest import REPO_ROOT

    app, token = real_app
    c = app.test_client()
    walk = simulate(load_scenario(REPO_ROOT / "mobile_logs" / "sim" / "hand_escalator.json"), 1).slice_time(0.0, 30.0)
    body = batch_to_json(walk, batch_id="b0")
    body["meta"] = {**body.get("meta", {}), "location": {"lat_deg": 49.46, "lon_deg": 11.11}}
    warnings = {}
    for name, extra in (("geo-undated", {"origin": {"lat_deg": 49.4614, "lon_deg": 11.1115}}),
                        ("plain-undated", {})):
        sid = c.post("/api/v1/sessions", json={"session_id": name, **extra}, headers=bearer(token)).get_json()["id"]
        r = c.post(f"/api/v1/sessions/{sid}/batches", json={**body, "session_id": name}, headers=bearer(token))
        assert r.status_code == 201, r.get_json()
        assert app.extensions["pdr"].worker.wait_idle(120)
        warnings[name] = c.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()["warnings"]
    geo, plain = warnings["geo-undated"], warnings["plain-undated"]
    assert any("earth's field at the recording's location (dip 65." in w for w in geo), geo
    assert UNDATED_FIX_ORIGIN in geo and UNDATED_FIX_UNUSED not in geo
    assert UNDATED_FIX_UNUSED in plain and not any("dip" in w for w in plain), plain


def test_a_gyroscope_that_starts_a_batch_late_still_gets_the_mode_classifier(real_app):
    # A pocket phone whose first 2 s batch has no gyroscope (it starts with the second): the shipped pocket model
    # needs the gyroscope. Before, the first batch turned the classifier off for the whole session ("the mode
    # classifier cannot use this data") and the gyroscope was never used by the track either.
    from dataclasses import replace

    from pdr import state_codec
    from pdr.io.native import batch_to_json
    from pdr.io.registry import read_recording
    from pdr.recording import GroundTruth
    from tests.pdr.phone.test_live_streams import _lagged

    app, token = real_app
    c = app.test_client()
    rec = read_recording(data_path("sensor_logger_walks", "inpocket-27-steps-Matan"))
    sid = c.post("/api/v1/sessions", json={"session_id": "late-gyro", "placement": "trouser_pocket"},
                 headers=bearer(token)).get_json()["id"]
    for i, part in enumerate(_lagged(rec, 2.0, ("gyro",))):
        body = batch_to_json(replace(part, truth=GroundTruth()), session_id="late-gyro", batch_id=f"b{i:03d}")
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=body, headers=bearer(token)).status_code == 201
        assert app.extensions["pdr"].worker.wait_idle(120)
    session = c.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
    assert session["status"] == "done" and session["steps"] == 28, session
    assert not any("cannot use this data" in w for w in session["warnings"]), session["warnings"]
    assert any(w.startswith("gyroscope data starts at t=") for w in session["warnings"])
    state, _ = app.extensions["pdr"].store.load_state(sid, "phone")
    assert state_codec.loads(state)["classifier_status"] == "active"
