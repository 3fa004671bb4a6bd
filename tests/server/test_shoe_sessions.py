"""Shoe IMUs in a session as a user pairs and sends them (issue 32): live feet, the primary track, device
columns, foot files uploaded to a paired foot, the session's duration.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient

from pdr.cli import main as pdr_main
from tests.conftest import data_path
from tests.server.conftest import bearer
from tests.server.helpers import multipart, phone_batch

FOOT_FILES = {"xio": ("xio_gait_loop", "short_walk.csv"),
              "pyshoe": ("pyshoe_vicon", "2017-11-22-11-52-02.mat"),
              "sensorconnect": ("foot_stride_gcp", "own", "SensorConnectData_31.csv")}


def _session(client: FlaskClient, token: str, name: str, pair: tuple[str, ...]) -> str:
    sid = client.post("/api/v1/sessions", json={"session_id": name}, headers=bearer(token)).get_json()["id"]
    for role in pair:
        assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": role},
                           headers=bearer(token)).status_code == 201
    return sid


def _phone_session(app: Flask, client: FlaskClient, token: str, name: str, batches: int) -> str:
    """A session with ``batches`` one-second phone batches, processed."""
    sid = _session(client, token, name, ())
    for i in range(batches):
        assert client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"p{i}", float(i)),
                           headers=bearer(token)).status_code == 201
    assert app.extensions["pdr"].worker.wait_idle(60)
    return sid


def _upload(client: FlaskClient, token: str, sid: str, role: str, path: Path) -> tuple[int, dict]:
    body, content_type = multipart({"file": (path.read_bytes(), path.name)})
    resp = client.post(f"/api/v1/sessions/{sid}/devices/{role}/upload", headers=bearer(token), data=body,
                       content_type=content_type)
    return resp.status_code, resp.get_json()


def _pdr_foot(log: Path, out: Path) -> list[dict[str, str]]:
    assert pdr_main(["foot", str(log), "--method", "stepwise", "--per-step", "--out", str(out)]) == 0
    with out.open() as fh:
        return list(csv.DictReader(fh))


def _assert_track_is(points: list[dict], ref: list[dict[str, str]]) -> None:
    assert len(points) == len(ref) > 10
    for col in ("t_s", "east_m", "north_m", "up_m", "heading_deg"):   # the CLI writes 9 significant digits
        np.testing.assert_allclose([p[col] for p in points], [float(r[col]) for r in ref], rtol=1e-8, atol=1e-8,
                                   err_msg=col)


@pytest.mark.data
def test_one_live_foot_is_the_primary_track_and_is_not_halved(real_app: Flask, token: str, tmp_path: Path) -> None:
    """Both feet paired, only the left sends (a file whose reader says right_foot): no fused track, the left
    foot's ZUPT track stands for the session, every track form names the device."""
    client = real_app.test_client()
    h = bearer(token)
    log = data_path(*FOOT_FILES["pyshoe"])
    sid = _session(client, token, "one-foot", ("left_foot", "right_foot"))
    status, body = _upload(client, token, sid, "left_foot", log)
    assert status == 201 and body["device_role"] == "left_foot" and body["format"] == "pyshoe"
    assert real_app.extensions["pdr"].worker.wait_idle(300)
    s = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert s["status"] == "done", s
    assert s["feet"] == {"paired": ["left_foot", "right_foot"], "live": ["left_foot"]}
    assert set(s["tracks"]) == {"left_foot"} and s["primary_track"] == "left_foot"
    assert s["distance_m"] == s["tracks"]["left_foot"]["distance_m"] > 5
    points = client.get(f"/api/v1/sessions/{sid}/track?device=left_foot", headers=h).get_json()["points"]
    _assert_track_is(points, _pdr_foot(log, tmp_path / "steps.csv"))

    text = client.get(f"/api/v1/sessions/{sid}/track?format=csv", headers=h).get_data(as_text=True)
    rows = list(csv.DictReader(text.splitlines()))
    assert text.splitlines()[0].endswith(",device") and {r["device"] for r in rows} == {"left_foot"}
    primary = client.get(f"/api/v1/sessions/{sid}/track?device=primary", headers=h).get_json()["points"]
    assert primary == points
    columns = client.get(f"/api/v1/sessions/{sid}/track/columns?device=primary", headers=h).get_json()["columns"]
    assert set(columns["device"]) == {"left_foot"} and columns["east_m"] == [p["east_m"] for p in points]
    status, again = _upload(client, token, sid, "left_foot", log)
    assert status == 200 and again["duplicate"] is True


@pytest.mark.data
@pytest.mark.parametrize("fmt", ["xio", "sensorconnect"])
def test_each_foot_format_uploads_to_the_paired_foot(real_app: Flask, token: str, tmp_path: Path, fmt: str) -> None:
    client = real_app.test_client()
    log = data_path(*FOOT_FILES[fmt])
    sid = _session(client, token, f"upload-{fmt}", ("right_foot",))
    status, body = _upload(client, token, sid, "right_foot", log)
    assert status == 201 and body["format"] == fmt, body
    assert real_app.extensions["pdr"].worker.wait_idle(300)
    s = client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
    assert s["status"] == "done" and s["primary_track"] == "right_foot", s
    points = client.get(f"/api/v1/sessions/{sid}/track?device=primary", headers=bearer(token)).get_json()["points"]
    _assert_track_is(points, _pdr_foot(log, tmp_path / "steps.csv"))


@pytest.mark.data
def test_upload_to_a_device_refuses_what_the_pairing_does_not_allow(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    sid = _session(client, token, "refusals", ("left_foot",))
    foot_log = data_path(*FOOT_FILES["xio"])
    status, body = _upload(client, token, sid, "right_foot", foot_log)
    assert status == 409 and "pair it first" in body["error"]["message"]
    status, body = _upload(client, token, sid, "toe", foot_log)
    assert status == 422 and body["error"]["details"]["field"] == "role"
    phone_log = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt")
    status, body = _upload(client, token, sid, "left_foot", phone_log)
    assert status == 422 and "phone's log" in body["error"]["message"]
    assert client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()["batches"] == {}


@pytest.mark.parametrize("route", ["batches", "devices", "steps"])
def test_a_log_file_sent_where_json_is_expected_names_the_upload_route(client: FlaskClient, tokens: dict[str, str],
                                                                       route: str) -> None:
    """Issue 32 item 4: a shoe file posted to a JSON route is refused 415 with the route that takes it."""
    sid = _session(client, tokens["alice"], "files", ("left_foot",))
    body, content_type = multipart({"file": (b"MATLAB 5.0 MAT-file", "walk.mat")})
    r = client.post(f"/api/v1/sessions/{sid}/{route}", headers=bearer(tokens["alice"]), data=body,
                    content_type=content_type)
    err = r.get_json()["error"]
    assert r.status_code == 415 and f"/api/v1/sessions/{sid}/devices/ROLE/upload" in err["message"], err
    assert err["details"]["field"] == "file"


def test_duration_spans_every_device_and_the_foot_is_primary(app: Flask, client: FlaskClient,
                                                             tokens: dict[str, str]) -> None:
    """A 10 s phone walk with a 3 s shoe: the session lasts 10 s; its steps and distance are the shoe's."""
    h = bearer(tokens["alice"])
    sid = _session(client, tokens["alice"], "mixed", ("left_foot",))
    for i in range(10):
        assert client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"p{i}", float(i)),
                           headers=h).status_code == 201
    for i in range(3):
        body = phone_batch(f"f{i}", 4.0 + i, role="left_foot")
        body["device"]["placement"] = "foot"
        assert client.post(f"/api/v1/sessions/{sid}/batches", json=body, headers=h).status_code == 201
    assert app.extensions["pdr"].worker.wait_idle(60)
    s = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert s["primary_track"] == "left_foot" and s["steps"] == 3
    assert s["duration_s"] == pytest.approx(9.0, abs=0.05)      # counting processor: a row at each batch's end
    assert s["feet"] == {"paired": ["left_foot"], "live": ["left_foot"]}


def test_a_foot_batch_to_a_session_with_a_phone_needs_the_foot_paired(app: Flask, client: FlaskClient,
                                                                       tokens: dict[str, str]) -> None:
    """A raw left_foot batch sent to a phone's session was stored with 201 and paired the foot quietly, and the
    foot's track replaced the phone's as the session's primary one. Now: 409 naming device.role and the pairing
    route, nothing stored; once the foot is paired the same batch is taken. A shoe streaming alone (no phone in the
    session) still pairs its foot by its batches (server.feet.pairs_itself)."""
    h = bearer(tokens["alice"])
    sid = _phone_session(app, client, tokens["alice"], "phone-walk", 3)
    before = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    foot = phone_batch("f0", 1.0, role="left_foot")
    r = client.post(f"/api/v1/sessions/{sid}/batches", json=foot, headers=h)
    assert r.status_code == 409, r.get_json()
    err = r.get_json()["error"]
    assert err["details"]["field"] == "device.role", err
    assert f"POST /api/v1/sessions/{sid}/devices" in err["message"] and "batch not stored" in err["message"]
    after = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert (after["feet"], after["primary_track"], after["batches"]) == (before["feet"], "phone", before["batches"])
    assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "left_foot"}, headers=h).status_code == 201
    assert client.post(f"/api/v1/sessions/{sid}/batches", json=foot, headers=h).status_code == 201
    shoe = _session(client, tokens["alice"], "shoe-alone", ())
    assert client.post(f"/api/v1/sessions/{shoe}/batches", json=foot, headers=h).status_code == 201
    assert app.extensions["pdr"].worker.wait_idle(60)
    assert client.get(f"/api/v1/sessions/{shoe}", headers=h).get_json()["feet"]["paired"] == ["left_foot"]


def test_session_id_is_a_key_of_one_session(app: Flask, client: FlaskClient, tokens: dict[str, str]) -> None:
    """A second file under an existing session_id is refused (409, naming the session); the same file again is a
    no-op; GET /sessions/{session_id} finds the session by the client's key too."""
    h = bearer(tokens["alice"])
    created = client.post("/api/v1/sessions", json={"session_id": "walk-7"}, headers=h)
    assert created.status_code == 201
    sid = created.get_json()["id"]
    body, content_type = multipart({"file": (json.dumps(phone_batch("b0", 0.0)).encode(), "walk.json"),
                                    "session_id": "walk-7"})
    resp = client.post("/api/v1/sessions", data=body, content_type=content_type, headers=h)
    assert resp.status_code == 409 and resp.get_json()["error"]["details"]["session"] == sid
    body, content_type = multipart({"file": (json.dumps(phone_batch("b1", 0.0)).encode(), "other.json"),
                                    "session_id": "walk-8"})
    first = client.post("/api/v1/sessions", data=body, content_type=content_type, headers=h)
    again = client.post("/api/v1/sessions", data=body, content_type=content_type, headers=h)
    assert (first.status_code, again.status_code) == (201, 200)
    assert again.get_json()["id"] == first.get_json()["id"]
    listed = client.get("/api/v1/sessions", headers=h).get_json()["sessions"]
    assert sorted(s["session_id"] for s in listed) == ["walk-7", "walk-8"]
    assert client.get("/api/v1/sessions/walk-7", headers=h).get_json()["id"] == sid
    assert client.get("/api/v1/sessions/walk-7", headers=bearer(tokens["bob"])).status_code == 404


@pytest.mark.data
def test_pdr_foot_writes_step_summaries_the_service_takes(real_app: Flask, token: str, tmp_path: Path) -> None:
    """``pdr foot LOG --per-step --format foot-steps``: the low-rate payload of a shoe unit (seed 001), with each
    step's covariance; posted to the session's paired foot it gives the per-step track of ``pdr foot``."""
    log = data_path(*FOOT_FILES["pyshoe"])
    payload_path = tmp_path / "steps.json"
    assert pdr_main(["foot", str(log), "--method", "stepwise", "--per-step", "--format", "foot-steps",
                     "--role", "left_foot", "--out", str(payload_path)]) == 0
    payload = json.loads(payload_path.read_text())
    assert payload["format"] == "pdr-foot-steps/1" and payload["device"]["role"] == "left_foot"
    covs = np.array([s["cov"] for s in payload["steps"]])
    assert np.all(np.linalg.eigvalsh(covs) > 0)                          # real covariances, not placeholders
    client = real_app.test_client()
    sid = _session(client, token, "summaries", ("left_foot",))
    resp = client.post(f"/api/v1/sessions/{sid}/steps", json=payload, headers=bearer(token))
    assert resp.status_code == 201, resp.get_json()
    assert real_app.extensions["pdr"].worker.wait_idle(120)
    points = client.get(f"/api/v1/sessions/{sid}/track?device=primary", headers=bearer(token)).get_json()["points"]
    assert {p["device"] for p in points} == {"left_foot"}
    _assert_track_is(points, _pdr_foot(log, tmp_path / "steps.csv"))


def test_a_rebuild_keeps_serving_the_previous_results(app: Flask, client: FlaskClient, tokens: dict[str, str]) -> None:
    """Between the start of a rebuild (reprocess, new options, a late batch) and its end the session answers with
    the results from before it and says ``rebuilding``; a second start keeps those, the end drops them."""
    h = bearer(tokens["alice"])
    sid = _phone_session(app, client, tokens["alice"], "rebuilt", 5)

    def results() -> tuple[dict, list, list, dict]:
        s = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
        track = client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
        steps = client.get(f"/api/v1/sessions/{sid}/steps", headers=h).get_json()["steps"]
        columns = client.get(f"/api/v1/sessions/{sid}/track/columns", headers=h).get_json()["columns"]
        return s, track, steps, columns

    before = results()
    assert before[0]["rebuilding"] is False and len(before[1]) == 5
    processing = app.extensions["pdr"].processing
    processing.clear(sid)                    # what POST .../reprocess does before the worker runs the rebuild
    during = results()
    assert during[0]["rebuilding"] is True and during[0]["tracks"] == before[0]["tracks"]
    assert during[1:] == before[1:]
    processing.clear(sid)
    assert results()[1:] == before[1:]
    processing.process_session(sid)
    after = results()
    assert after[0]["rebuilding"] is False and after[0]["status"] == "done" and after[1:] == before[1:]
    assert processing.store.rebuilding(sid) is False
