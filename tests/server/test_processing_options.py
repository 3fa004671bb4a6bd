"""Per-session processing options (site, step-length calibration, foot ZARU) from the API to the processors."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient

from pdr.errors import InputError
from pdr.foot.navigate import navigate
from pdr.foot.zupt import ZuptConfig
from pdr.io.native import batch_to_json
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, PipelineConfig
from pdr.phone.step_length import StepLengthModel
from pdr.recording import DeviceInfo, Recording, SensorStream
from pdr.sim import parse_scenario, simulate
from server import auth
from server.processing_options import ProcessingOptions
from tests.pdr.foot.gait import simulate_gait
from tests.server.conftest import bearer
from tests.server.helpers import multipart, one_second_batches

T0_NS = 1_717_000_000_000_000_000
SITE = {"name": "hall", "floor_height_m": 3.5, "declination_deg": 12.0,
        "landmarks": [{"id": "door", "type": "stairs", "east_m": 40.0, "north_m": 0.0, "floor": 0,
                       "heading_deg": [80, 100]}]}
MODEL = StepLengthModel()
CALIBRATION = {"step_length": replace(MODEL, k=1.2 * MODEL.k, b=1.2 * MODEL.b).to_dict()}


def test_options_are_checked_and_round_trip() -> None:
    opts = ProcessingOptions.from_json({"site": SITE, "calibration": CALIBRATION, "foot": {"zaru": True}})
    assert opts.site == Site.from_dict(SITE) and opts.foot_zaru and not opts.foot_interval_samples
    assert opts.zupt_config() == ZuptConfig(zaru=True)
    interval = ProcessingOptions.from_json({"foot": {"imu_samples": "interval"}})
    assert interval.zupt_config() == ZuptConfig(interval_samples=True)
    assert interval.to_json() == {"foot": {"imu_samples": "interval"}}
    assert ProcessingOptions.from_json({"foot": {"imu_samples": "instant"}}) == ProcessingOptions()
    assert opts.step_length == StepLengthModel.from_dict(CALIBRATION["step_length"])
    assert ProcessingOptions.from_json(opts.to_json()) == opts
    assert ProcessingOptions.from_json(None) == ProcessingOptions() and ProcessingOptions().to_json() == {}
    for bad, where in (({"site": {"name": "x"}}, "landmarks"), ({"calibration": {"k": 1}}, "step_length"),
                       ({"foot": {"zaru": "yes"}}, "processing.foot"), ({"map": {}}, "unknown option"),
                       ({"foot": {"imu_samples": "mean"}}, "processing.foot"),
                       ({"calibration": {"step_length": {"k": "big"}}}, "step-length")):
        with pytest.raises(InputError, match=where):
            ProcessingOptions.from_json(bad)
    with pytest.raises(InputError, match="not JSON"):
        ProcessingOptions.from_text("{site")


def _session_track(app: Flask, client: FlaskClient, token: str, body: dict, rec: Recording, device: str) -> tuple[
        dict, list[dict]]:
    resp = client.post("/api/v1/sessions", json=body, headers=bearer(token))
    assert resp.status_code == 201, resp.get_json()
    sid = resp.get_json()["id"]
    for batch in one_second_batches(rec, body["session_id"]):
        r = client.post(f"/api/v1/sessions/{sid}/batches", json=batch, headers=bearer(token))
        assert r.status_code in (200, 201), r.get_json()
    assert app.extensions["pdr"].worker.wait_idle(240)
    session = client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
    points = client.get(f"/api/v1/sessions/{sid}/track?device={device}", headers=bearer(token)).get_json()["points"]
    return session, points


def test_bad_options_are_refused_and_nothing_is_created(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    resp = client.post("/api/v1/sessions", json={"session_id": "s", "processing": {"site": {"landmarks": [{}]}}},
                       headers=bearer(token))
    assert resp.status_code == 422 and "processing.site landmark 0" in resp.get_json()["error"]["message"]
    resp = client.post("/api/v1/sessions", json={"session_id": "s", "processing": {"foot": {"zupt": True}}},
                       headers=bearer(token))
    assert resp.status_code == 422 and "processing.foot" in resp.get_json()["error"]["message"]
    resp = client.post("/api/v1/sessions", json={"session_id": "s", "processing": {"site": {
        "landmarks": [], "grid_deg": 400}}}, headers=bearer(token))
    assert resp.status_code == 422 and "grid_deg" in resp.get_json()["error"]["message"]
    for bad, field in (({"k": -1}, "k"), ({"k": 0}, "k"), ({"min_m": 1.5}, "min_m"), ({"stairs_m": 0}, "stairs_m")):
        resp = client.post("/api/v1/sessions", json={"session_id": "s", "processing": {
            "calibration": {"step_length": bad}}}, headers=bearer(token))
        error = resp.get_json()["error"]
        assert resp.status_code == 422 and f"processing.calibration.step_length.{field}" in error["message"], error
    assert client.get("/api/v1/sessions", headers=bearer(token)).get_json()["sessions"] == []
    sid = client.post("/api/v1/sessions", json={"session_id": "later"}, headers=bearer(token)).get_json()["id"]
    resp = client.put(f"/api/v1/sessions/{sid}/processing", json={"calibration": {"step_length": {"k": -1}}},
                      headers=bearer(token))
    assert resp.status_code == 422 and "step_length.k" in resp.get_json()["error"]["message"]


@pytest.mark.timeout(300)
def test_phone_session_uses_its_site_and_calibration(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    rec = simulate(parse_scenario({"placement": "hand", "start_time_ns": T0_NS,
                                   "segments": [{"type": "stand", "duration_s": 3},
                                                {"type": "walk", "duration_s": 20}]}), seed=2)
    processing = {"site": SITE, "calibration": CALIBRATION}
    session, points = _session_track(real_app, client, token, {"session_id": "cal", "placement": "hand",
                                                               "processing": processing}, rec, "phone")
    assert session["processing"] == ProcessingOptions.from_json(processing).to_json()
    # The same as the offline pipeline given the same site and calibration (pdr track --site --calibration).
    cfg = PipelineConfig(placement="hand", step_length=StepLengthModel.from_dict(CALIBRATION["step_length"]))
    steps = [e for e in PdrPipeline(cfg, Site.from_dict(SITE)).run(rec) if e["type"] == "step"]
    assert len(points) == len(steps) > 15
    for key in ("east_m", "north_m", "heading_deg", "step_length_m"):
        np.testing.assert_allclose([p[key] for p in points], [e[key] for e in steps], atol=1e-6, err_msg=key)
    # Against a session without options: 1.2 times the step length, the heading turned by the declination.
    _, plain = _session_track(real_app, client, token, {"session_id": "plain", "placement": "hand"}, rec, "phone")
    ratio = np.array([p["step_length_m"] for p in points]) / np.array([p["step_length_m"] for p in plain])
    np.testing.assert_allclose(ratio, 1.2, rtol=1e-9)
    turn = (np.array([p["heading_deg"] for p in points]) - [p["heading_deg"] for p in plain] + 180) % 360 - 180
    assert abs(float(np.median(turn)) - 12.0) < 2.0


def _stop_and_go_recording() -> Recording:
    # A shoe IMU walk with 3 s rests and a gyroscope bias of 0.3 deg/s per axis: the update has something to learn.
    g = simulate_gait(n_strides=8, stride_m=1.2, stance_s=3.0, sigma_acc=0.02, sigma_gyro=0.002, seed=5)
    t_ns = T0_NS + np.round(g.t_s * 1e9).astype(np.int64)
    gyro = g.gyro_b + np.radians(0.3) * np.array([1.0, -1.0, 1.0])
    return Recording({"acc": SensorStream("acc", t_ns, g.acc_b), "gyro": SensorStream("gyro", t_ns, gyro)},
                     DeviceInfo(platform="imu", role="left_foot", placement="foot"), t0_ns=T0_NS)


@pytest.mark.timeout(300)
def test_foot_session_with_zaru_gives_the_zaru_track(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    rec = _stop_and_go_recording()
    session, points = _session_track(real_app, client, token, {"session_id": "shoe", "processing": {
        "foot": {"zaru": True}}}, rec, "left_foot")
    assert session["processing"] == {"foot": {"zaru": True}}
    imu, track = navigate(rec, "stepwise", zupt=ZuptConfig(zaru=True))
    _, plain = navigate(rec, "stepwise")
    idx = np.array([s.index for s in track.steps])
    assert len(points) == idx.size > 5
    got = np.array([[p["east_m"], p["north_m"]] for p in points])
    np.testing.assert_allclose(got, track.pos_n[idx, :2], rtol=0, atol=1e-9)
    assert np.abs(got - plain.pos_n[idx, :2]).max() > 0.05


def test_uploaded_file_takes_its_options_from_a_form_field(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    walk = [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 8}]
    rec = simulate(parse_scenario({"placement": "hand", "start_time_ns": T0_NS, "segments": walk}), seed=3)
    payload = json.dumps(batch_to_json(rec, session_id="up", batch_id="all")).encode()
    body, ctype = multipart({"file": (payload, "walk.json"), "processing": "{\"calibration\": {\"k\": 1}}"})
    resp = client.post("/api/v1/sessions", data=body, headers=bearer(token), content_type=ctype)
    assert resp.status_code == 422 and "processing.calibration" in resp.get_json()["error"]["message"]
    assert client.get("/api/v1/sessions", headers=bearer(token)).get_json()["sessions"] == []
    body, ctype = multipart({"file": (payload, "walk.json"), "processing": json.dumps({"calibration": CALIBRATION})})
    resp = client.post("/api/v1/sessions", data=body, headers=bearer(token), content_type=ctype)
    assert resp.status_code == 201, resp.get_json()
    assert resp.get_json()["processing"] == {"calibration": CALIBRATION}


@pytest.mark.timeout(300)
def test_options_set_after_the_walk_rebuild_the_session(real_app: Flask, token: str) -> None:
    # The walker calibrates after recording: PUT .../processing replaces the options and rebuilds the results.
    client = real_app.test_client()
    walk = [{"type": "stand", "duration_s": 3}, {"type": "walk", "duration_s": 15}]
    rec = simulate(parse_scenario({"placement": "hand", "start_time_ns": T0_NS, "segments": walk}), seed=5)
    session, before = _session_track(real_app, client, token, {"session_id": "later", "placement": "hand"}, rec,
                                     "phone")
    assert session["processing"] == {}
    sid = session["id"]
    bad = client.put(f"/api/v1/sessions/{sid}/processing", json={"calibration": {"k": 1}}, headers=bearer(token))
    assert bad.status_code == 422 and "processing.calibration" in bad.get_json()["error"]["message"]
    resp = client.put(f"/api/v1/sessions/{sid}/processing", json={"calibration": CALIBRATION}, headers=bearer(token))
    assert resp.status_code == 202 and resp.get_json()["processing"] == {"calibration": CALIBRATION}
    assert real_app.extensions["pdr"].worker.wait_idle(240)
    after = client.get(f"/api/v1/sessions/{sid}/track?device=phone", headers=bearer(token)).get_json()["points"]
    assert len(after) == len(before) > 10
    ratio = np.array([p["step_length_m"] for p in after]) / np.array([p["step_length_m"] for p in before])
    np.testing.assert_allclose(ratio, 1.2, rtol=1e-9)
    assert client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()["processing"] == {
        "calibration": CALIBRATION}
    # Clearing the options restores the plain track; another user's session is not reachable.
    assert client.put(f"/api/v1/sessions/{sid}/processing", json={}, headers=bearer(token)).status_code == 202
    assert real_app.extensions["pdr"].worker.wait_idle(240)
    again = client.get(f"/api/v1/sessions/{sid}/track?device=phone", headers=bearer(token)).get_json()["points"]
    assert again == before
    with real_app.extensions["pdr"].store.engine.begin() as conn:
        other = auth.add_user(conn, "someone")
    assert client.put(f"/api/v1/sessions/{sid}/processing", json={}, headers=bearer(other)).status_code == 404
