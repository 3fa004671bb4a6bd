"""Shoe IMUs through the service with the real processors: raw foot batches and step-wise summaries."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient

from pdr.cli import main as pdr_main
from pdr.foot.navigate import navigate
from pdr.foot.stepwise import dead_reckon
from pdr.foot.summaries import steps_to_json
from pdr.frames import yaw_to_heading_deg
from pdr.io.native import batch_to_json
from tests.conftest import data_path
from tests.pdr.foot.test_online import gait_recording
from tests.server.conftest import bearer
from tests.server.helpers import one_second_batches


def _session(client: FlaskClient, token: str, name: str, pair: tuple[str, ...] = ()) -> str:
    sid = client.post("/api/v1/sessions", json={"session_id": name}, headers=bearer(token)).get_json()["id"]
    for role in pair:
        assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": role},
                           headers=bearer(token)).status_code == 201
    return sid


def _upload(app: Flask, client: FlaskClient, token: str, sid: str, batches: list[dict]) -> None:
    order = list(range(len(batches)))
    order[3], order[4] = order[4], order[3]     # one arrives late: the session is rebuilt in time order
    order.insert(8, 8)                          # one is sent twice
    for i in order:
        resp = client.post(f"/api/v1/sessions/{sid}/batches", json=batches[i], headers=bearer(token))
        assert resp.status_code in (200, 201), resp.get_json()
    assert app.extensions["pdr"].worker.wait_idle(120)


def _track(client: FlaskClient, token: str, sid: str, device: str) -> list[dict]:
    return client.get(f"/api/v1/sessions/{sid}/track?device={device}", headers=bearer(token)).get_json()["points"]


def test_raw_foot_batches_give_the_stepwise_track(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    rec = gait_recording()
    sid = _session(client, token, "shoe")
    _upload(real_app, client, token, sid, one_second_batches(rec, "foot"))
    points = _track(client, token, sid, "left_foot")

    imu, track = navigate(rec, "stepwise")
    idx = np.array([s.index for s in track.steps])
    assert len(points) == idx.size > 5
    np.testing.assert_allclose([p["t_s"] for p in points], track.t_s[idx] + imu.clock_offset_s, rtol=0, atol=1e-9)
    got = np.array([[p["east_m"], p["north_m"], p["up_m"]] for p in points])
    np.testing.assert_allclose(got, track.pos_n[idx], rtol=0, atol=1e-9)
    np.testing.assert_allclose([p["heading_deg"] for p in points], yaw_to_heading_deg(track.yaw[idx]), atol=1e-7)
    np.testing.assert_allclose([p["step_length_m"] for p in points],
                               [np.hypot(s.dp[0], s.dp[1]) for s in track.steps], atol=1e-12)
    # The first reset (the start of the first swing) closes no stride: mode standing, no length, not a step of the
    # session; every later one closes a stride; the walk's 12th stride ends the recording, no reset closes it: the
    # end does (the provisional tail's last row, at the last sample; it was not counted).
    assert [p["mode"] for p in points] == ["standing"] + ["walking"] * (len(points) - 1)
    assert points[0]["step_length_m"] < 0.01 and {p["floor"] for p in points} == {None}
    session = client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
    assert session["steps"] == len(points) - 1 == 12
    steps = client.get(f"/api/v1/sessions/{sid}/steps", headers=bearer(token)).get_json()["steps"]
    assert len(steps) == len(points) and steps[0]["device"] == "left_foot"

    # Reprocessing from the raw batches reproduces the track.
    assert client.post(f"/api/v1/sessions/{sid}/reprocess", headers=bearer(token)).status_code == 202
    assert real_app.extensions["pdr"].worker.wait_idle(120)
    assert _track(client, token, sid, "left_foot") == points


def test_step_summaries_endpoint_is_idempotent_and_dead_reckons(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    h = bearer(token)
    _, track = navigate(gait_recording(), "stepwise")
    steps = list(track.steps)
    sid = _session(client, token, "shoe-summaries")
    first, second = steps_to_json(steps[:5], "right_foot", "s1"), steps_to_json(steps[5:], "right_foot", "s2")
    url = f"/api/v1/sessions/{sid}/steps"
    unpaired = client.post(url, json=second, headers=h)      # summaries do not pair a foot by themselves
    assert unpaired.status_code == 409 and "pair it first" in unpaired.get_json()["error"]["message"]
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["devices"] == []
    client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "right_foot"}, headers=h)
    assert client.post(url, json=second, headers=h).status_code == 201
    assert client.post(url, json=first, headers=h).status_code == 201          # late: rebuilt in time order
    dup = client.post(url, json=first, headers=h)
    assert dup.status_code == 200 and dup.get_json()["duplicate"] is True
    assert real_app.extensions["pdr"].worker.wait_idle(60)
    points = _track(client, token, sid, "right_foot")
    ref = dead_reckon(steps)
    np.testing.assert_allclose([p["t_s"] for p in points], ref.t_s[1:])
    np.testing.assert_allclose([[p["east_m"], p["north_m"], p["up_m"]] for p in points], ref.pos_n[1:], atol=1e-12)
    np.testing.assert_allclose([p["heading_deg"] for p in points], yaw_to_heading_deg(ref.heading[1:]), atol=1e-9)
    # The same positions as the raw-IMU navigation that produced the summaries (eq. 7 both ways).
    idx = np.array([s.index for s in steps])
    np.testing.assert_allclose([[p["east_m"], p["north_m"]] for p in points], track.pos_n[idx, :2], atol=1e-9)

    changed = json.loads(json.dumps(first))
    changed["steps"][0]["dpsi"] += 0.1
    assert client.post(url, json=changed, headers=h).status_code == 409
    assert client.post(url, json=first).status_code == 401
    bad_cov = json.loads(json.dumps(first))
    bad_cov["batch_id"] = "bad"
    bad_cov["steps"][1]["cov"][0][0] = -1.0
    resp = client.post(url, json=bad_cov, headers=h)
    assert resp.status_code == 422 and "steps[1]" in resp.get_json()["error"]["message"]
    missing = {**first, "batch_id": "bad2", "steps": [{"t_s": 1.0, "dp": [0, 0, 0]}]}
    resp = client.post(url, json=missing, headers=h)
    assert resp.status_code == 422 and "dpsi" in resp.get_json()["error"]["message"]
    assert client.post(url, data="x", headers=h).status_code == 415


def test_step_summaries_say_which_resets_are_no_stride_and_the_session_does_not_count_them(
        real_app: Flask, token: str) -> None:
    """A shoe unit's summaries carry ``stride``: the resets while the foot stands (false) are composed (their turn
    on the spot moves the heading) but are 'standing' rows, not steps of the session. Before, every summary was a
    step: a unit standing for a minute added 30 steps."""
    client = real_app.test_client()
    h = bearer(token)
    imu, track = navigate(gait_recording(), "stepwise")
    assert not all(track.step_strides) and any(track.step_strides)
    sid = _session(client, token, "shoe-strides", ("left_foot",))
    payload = steps_to_json(list(track.steps), "left_foot", "u1")
    assert [s["stride"] for s in payload["steps"]] == list(track.step_strides)
    assert client.post(f"/api/v1/sessions/{sid}/steps", json=payload, headers=h).status_code == 201
    assert real_app.extensions["pdr"].worker.wait_idle(60)
    points = _track(client, token, sid, "left_foot")
    assert [p["mode"] for p in points] == ["walking" if f else "standing" for f in track.step_strides]
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["steps"] == sum(track.step_strides)
    # Without the flag (older units), every summary is a stride, as before.
    sid2 = _session(client, token, "shoe-no-flags", ("left_foot",))
    plain = steps_to_json(list(track.steps), "left_foot", "u2")
    for step in plain["steps"]:
        del step["stride"]
    assert client.post(f"/api/v1/sessions/{sid2}/steps", json=plain, headers=h).status_code == 201
    assert real_app.extensions["pdr"].worker.wait_idle(60)
    assert client.get(f"/api/v1/sessions/{sid2}", headers=h).get_json()["steps"] == len(track.steps)
    bad = {**payload, "batch_id": "u3", "steps": [{**payload["steps"][0], "stride": "yes"}]}
    resp = client.post(f"/api/v1/sessions/{sid}/steps", json=bad, headers=h)
    assert resp.status_code == 422 and "steps[0].stride" in json.dumps(resp.get_json())


def test_raw_batches_after_summaries_fail_visibly(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    rec = gait_recording(role="right_foot")
    _, track = navigate(rec, "stepwise")
    sid = _session(client, token, "mixed", pair=("right_foot",))
    client.post(f"/api/v1/sessions/{sid}/steps", json=steps_to_json(list(track.steps[:3]), "right_foot", "s1"),
                headers=bearer(token))
    real_app.extensions["pdr"].worker.wait_idle(60)
    late = batch_to_json(rec.slice_time(12.0, 13.0), session_id="mixed", batch_id="raw")
    client.post(f"/api/v1/sessions/{sid}/batches", json=late, headers=bearer(token))
    real_app.extensions["pdr"].worker.wait_idle(60)
    detail = client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
    assert detail["status"] == "failed"
    assert "cannot be mixed" in json.dumps(detail)


@pytest.mark.data
def test_real_foot_log_in_one_second_batches_equals_pdr_foot(real_app: Flask, token: str, tmp_path: Path) -> None:
    from pdr.io import read_recording

    log = data_path("pyshoe_vicon", "2018-02-09-11-16-53.mat")
    rec = read_recording(log)
    client = real_app.test_client()
    sid = _session(client, token, "vicon")
    _upload(real_app, client, token, sid, one_second_batches(rec, "foot"))
    points = _track(client, token, sid, rec.device.role)

    out = tmp_path / "steps.csv"
    assert pdr_main(["foot", str(log), "--method", "stepwise", "--per-step", "--out", str(out)]) == 0
    with out.open() as fh:
        ref = list(csv.DictReader(fh))
    assert len(points) == len(ref) > 50
    # The CLI writes 9 significant digits.
    for col in ("t_s", "east_m", "north_m", "up_m", "heading_deg"):
        np.testing.assert_allclose([p[col] for p in points], [float(r[col]) for r in ref], rtol=1e-8, atol=1e-8,
                                   err_msg=col)
    np.testing.assert_allclose([p["step_length_m"] for p in points],
                               [np.hypot(float(r["dp_x_m"]), float(r["dp_y_m"])) for r in ref], rtol=1e-8, atol=1e-8)
    # The resets while the foot stands: 'standing' rows here, stride 0 there (the CSV did not mark them).
    assert [p["mode"] for p in points] == ["walking" if r["stride"] == "1" else "standing" for r in ref]
    assert "standing" in {p["mode"] for p in points}
