"""Sensor Logger HTTP push: sessions from sessionId, duplicates ignored, out of order accepted, 499 for user errors."""

from __future__ import annotations

import uuid
from dataclasses import replace

import numpy as np

from pdr.io import read_recording
from pdr.io.sensor_logger_writer import to_push_messages
from pdr.phone.configure import pipeline_config
from pdr.phone.pipeline import PdrPipeline, track_rows
from pdr.recording import DeviceInfo, Recording, SensorStream
from server import auth
from tests.conftest import data_path
from tests.server.conftest import bearer

URL = "/api/v1/ingest/sensor-logger"


def _messages(n_s: int = 4) -> list[dict]:
    t = 1_700_000_000_000_000_000 + np.arange(n_s * 50, dtype=np.int64) * 20_000_000
    rec = Recording({"acc": SensorStream("acc", t, np.tile([0.0, 0.0, 9.81], (t.size, 1))),
                     "gyro": SensorStream("gyro", t, np.zeros((t.size, 3)))}, DeviceInfo(platform="android"))
    return to_push_messages(rec, session_id="sl-session", device_id="pixel-7", period_s=1.0)


def test_push_messages_with_duplicate_and_reorder(app, client, tokens):
    msgs = _messages()
    order = [msgs[0], msgs[2], msgs[1], msgs[1], msgs[3]]  # message 2 before 1, and 1 sent twice
    answers = [client.post(f"{URL}?token={tokens['alice']}", json=m) for m in order]
    assert [a.status_code for a in answers] == [200] * 5
    assert [a.get_json()["duplicate"] for a in answers] == [False, False, False, True, False]
    app.extensions["pdr"].worker.wait_idle()
    sessions = client.get("/api/v1/sessions", headers=bearer(tokens["alice"])).get_json()["sessions"]
    assert len(sessions) == 1 and sessions[0]["session_id"] == "sl-session" and sessions[0]["source"] == "sensor_logger"
    assert sessions[0]["devices"][0]["device_id"] == "pixel-7"
    track_url = f"/api/v1/sessions/{sessions[0]['id']}/track"
    pts = client.get(track_url, headers=bearer(tokens["alice"])).get_json()["points"]
    assert [p["east_m"] for p in pts] == [1.0, 2.0, 3.0, 4.0]  # processed in time order
    assert pts == sorted(pts, key=lambda p: p["t_s"])


def test_a_session_id_of_200_characters_is_taken_whole_and_the_session_named_within_200(app, client, tokens):
    """A sessionId of 187 to 200 characters (the most it may have) made a session name of up to 214, 'Sensor Logger '
    and the id: stored so in SQLite, a 500 in PostgreSQL, whose sessions.name holds 200 (tests/server/test_postgres.py).
    The session keeps the whole id; its name is cut at 200 characters."""
    key = "s" * 200
    msg = _messages(1)[0] | {"sessionId": key}
    assert client.post(f"{URL}?token={tokens['alice']}", json=msg).status_code == 200
    (session,) = client.get("/api/v1/sessions", headers=bearer(tokens["alice"])).get_json()["sessions"]
    assert session["session_id"] == key
    assert session["name"] == f"Sensor Logger {key}"[:200]


def test_user_visible_errors_are_499_text(client, tokens):
    msg = _messages(1)[0]
    no_token = client.post(URL, json=msg)
    assert no_token.status_code == 499 and no_token.mimetype == "text/plain"
    assert "authentication" in no_token.get_data(as_text=True)
    bad = dict(msg, payload=[{"name": "gyroscope", "time": 1, "values": {"x": "NaN?", "y": 0, "z": 0}}])
    resp = client.post(f"{URL}?token={tokens['alice']}", json=bad)
    assert resp.status_code == 499 and "payload[0].values.x" in resp.get_data(as_text=True)
    missing = client.post(f"{URL}?token={tokens['alice']}", json={"payload": []})
    assert missing.status_code == 499 and "messageId" in missing.get_data(as_text=True)
    garbage = client.post(f"{URL}?token={tokens['alice']}", data=b"\x00\xff", content_type="application/json")
    assert garbage.status_code == 499
    assert client.get("/api/v1/sessions", headers=bearer(tokens["alice"])).get_json()["sessions"] == []


def test_empty_payload_is_accepted_without_a_session(client, tokens):
    resp = client.post(f"{URL}?token={tokens['alice']}",
                       json={"messageId": 1, "sessionId": "s", "deviceId": "d", "payload": []})
    assert resp.status_code == 200 and resp.get_json()["stored"] is False


def _ipin_walk_start() -> Recording:
    """The first 20 s of a real hand-held IPIN log, whose reader knows the placement (``hand``), without the log's
    GNSS fix, which its push messages do not carry (:func:`~pdr.io.sensor_logger_writer.to_push_messages`)."""
    rec = read_recording(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt"))
    return replace(rec, meta={k: v for k, v in rec.meta.items() if k != "location"}).slice_time(0.0, 20.0)


def _pushed_track(app, client, token: str, rec: Recording, query: str) -> tuple[dict, list[dict]]:
    for m in to_push_messages(rec, session_id="ipin", device_id="phone"):
        r = client.post(f"{URL}?token={token}{query}", json=m)
        assert r.status_code == 200, r.get_data(as_text=True)
    app.extensions["pdr"].worker.wait_idle()
    session = client.get("/api/v1/sessions", headers=bearer(token)).get_json()["sessions"][0]
    pts = client.get(f"/api/v1/sessions/{session['id']}/track", headers=bearer(token)).get_json()["points"]
    return session, pts


def test_push_url_placement_gives_the_track_of_the_log_with_that_placement(real_app, token):
    """Push messages carry no placement: the URL's ``?placement=`` reaches the phone pipeline as a log reader's
    does, so the streamed track is ``pdr track``'s on the log; without it, the pipeline's own detection's."""
    rec = _ipin_walk_start()
    assert rec.device.placement == "hand"
    client = real_app.test_client()
    session, pts = _pushed_track(real_app, client, token, rec, "&placement=hand")
    assert session["placement"] == "hand" and session["devices"][0]["placement"] == "hand"
    offline = track_rows(PdrPipeline(pipeline_config()).run(rec))
    assert len(offline) > 10 and len(pts) == len(offline)
    assert [(p["east_m"], p["north_m"]) for p in pts] == [(r["east_m"], r["north_m"]) for r in offline]

    with real_app.extensions["pdr"].store.engine.begin() as conn:
        other = auth.add_user(conn, "other")
    _, detected = _pushed_track(real_app, client, other, rec, "")
    unknown = replace(rec, device=replace(rec.device, placement=None))
    assert [(p["east_m"], p["north_m"]) for p in detected] == [
        (r["east_m"], r["north_m"]) for r in track_rows(PdrPipeline(pipeline_config()).run(unknown))]
    assert detected[0]["east_m"] != pts[0]["east_m"]  # the regression's cause: the placement was lost on the way


def test_unknown_or_changed_push_placement_is_a_user_error(client, tokens):
    msgs = _messages(2)
    bad = client.post(f"{URL}?token={tokens['alice']}&placement=pocket", json=msgs[0])
    assert bad.status_code == 499 and "placement" in bad.get_data(as_text=True)
    assert client.post(f"{URL}?token={tokens['alice']}&placement=hand", json=msgs[0]).status_code == 200
    changed = client.post(f"{URL}?token={tokens['alice']}&placement=bag", json=msgs[1])
    assert changed.status_code == 499 and "differs from the session's" in changed.get_data(as_text=True)


def test_string_times_and_location_geo_reference_the_session(client, tokens):
    """``time`` as a string of digits is accepted; ``location`` readings give the session its origin, so its
    GeoJSON is in lon/lat (RFC 7946)."""
    msgs = _messages(3)
    for m in msgs:
        for e in m["payload"]:
            e["time"] = str(e["time"])
    msgs[0]["payload"].append({"name": "location", "time": msgs[0]["payload"][0]["time"],
                               "values": {"latitude": 49.4611, "longitude": 11.111, "altitude": 300.0,
                                          "horizontalAccuracy": 4.5}})
    for m in msgs:
        r = client.post(f"{URL}?token={tokens['alice']}", json=m)
        assert r.status_code == 200, r.get_data(as_text=True)
    session = client.get("/api/v1/sessions", headers=bearer(tokens["alice"])).get_json()["sessions"][0]
    assert session["origin"] == {"lat_deg": 49.4611, "lon_deg": 11.111}


def test_push_url_platform_reads_raw_ios_data(client, tokens):
    """Raw iOS data without orientation (Core Motion's -specific force, here a phone lying face-up reading
    -1 g on z) was read as Android; ``?platform=ios&standardised=0`` says how to read it."""
    t = 1_700_000_000_000_000_000 + np.arange(100, dtype=np.int64) * 20_000_000
    msg = {"messageId": 1, "sessionId": "ios", "deviceId": "iphone",
           "payload": [{"name": "accelerometer", "time": int(k), "values": {"x": 0.0, "y": 0.0, "z": 0.0}}
                       for k in t] + [{"name": "gravity", "time": int(k), "values": {"x": 0.0, "y": 0.0, "z": -9.81}}
                                      for k in t]}
    from pdr.io.sensor_logger import parse_push_message

    assert parse_push_message(msg).values("acc")[0, 2] < 0  # inferred: Android assumed, gravity upside down
    r = client.post(f"{URL}?token={tokens['alice']}&platform=ios&standardised=0", json=msg)
    assert r.status_code == 200, r.get_data(as_text=True)
    assert parse_push_message(msg, platform="ios", standardised=False).values("acc")[0, 2] > 9.0
    for bad in ("platform=windows", "standardised=maybe"):
        r = client.post(f"{URL}?token={tokens['alice']}&{bad}", json=dict(msg, messageId=2))
        assert r.status_code == 499 and r.mimetype == "text/plain" and bad.split("=")[0] in r.get_data(as_text=True)


def test_oversized_message_is_499_with_a_text_body(client, tokens):
    """Over the route's limit (PDR_MAX_BATCH_MB, 8 MB by default) the app shows only a 499's text."""
    msg = _messages(1)[0]
    msg["padding"] = "x" * (9 * 1024**2)
    r = client.post(f"{URL}?token={tokens['alice']}", json=msg)
    assert r.status_code == 499 and r.mimetype == "text/plain"
    assert "message too large" in r.get_data(as_text=True)


def test_a_json_create_and_a_push_racing_with_one_key_make_one_session(app, client, tokens, monkeypatch):
    """The push stores its session between the JSON create's look-up of the key and its insert (as two requests at
    once do): the create then finds the push's session (200) instead of making a second one under the same key.
    """
    from types import SimpleNamespace

    from server import store as store_module

    h = bearer(tokens["alice"])
    pushes: list[int] = []

    def uuid4_after_a_push() -> uuid.UUID:           # the create's new session id, drawn after its look-up
        if not pushes:
            pushes.append(0)
            pushes[0] = client.post(f"{URL}?token={tokens['alice']}", json=_messages(1)[0]).status_code
        return uuid.uuid4()

    monkeypatch.setattr(store_module, "uuid", SimpleNamespace(uuid4=uuid4_after_a_push))
    resp = client.post("/api/v1/sessions", json={"session_id": "sl-session"}, headers=h)
    monkeypatch.undo()
    assert pushes == [200]
    assert resp.status_code == 200, resp.get_data()[:300]
    sessions = client.get("/api/v1/sessions", headers=h).get_json()["sessions"]
    assert [(s["id"], s["source"]) for s in sessions] == [(resp.get_json()["id"], "sensor_logger")]
    assert sessions[0]["batches"] in ({"pending": 1}, {"processing": 1}, {"done": 1})
