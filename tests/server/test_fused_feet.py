"""Both shoes of one walker through the service: the fused dual-foot track (device role ``fused``)."""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
from flask import Flask
from flask.testing import FlaskClient

from pdr.foot.dual import DualFootFusion
from pdr.frames import yaw_to_heading_deg
from pdr.io.native import batch_to_json
from pdr.recording import GroundTruth, Recording
from pdr.sim import parse_scenario, simulate
from server.foot_steps import increment_from_json, mode_of
from tests.server.conftest import bearer

T0_NS = 1_700_000_000_000_000_000
SEGMENTS = [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 16, "speed_mps": 1.4},
            {"type": "turn", "angle_deg": 90, "duration_s": 2, "speed_mps": 1.0},
            {"type": "walk", "duration_s": 8, "speed_mps": 1.4}, {"type": "stand", "duration_s": 2}]


@cache
def _shoe(side: str, seed: int) -> Recording:
    # One walk (the path does not depend on the seed); each shoe its own sensor errors (its own seed).
    return simulate(parse_scenario({"name": "walker", "placement": "foot", "side": side, "start_time_ns": T0_NS,
                                    "rates_hz": {"acc": 200, "gyro": 200}, "sensors": {"grade": "consumer"},
                                    "segments": SEGMENTS}), seed)


def _batches(rec: Recording, prefix: str) -> list[dict]:
    """Native 1 s batches of samples only (what a shoe unit sends: no truth)."""
    t0, t1 = rec.time_span_s()
    return [batch_to_json(replace(rec.slice_time(float(a), float(a) + 1.0), truth=GroundTruth()),
                          session_id=f"walk-{prefix}", batch_id=f"{prefix}{i:03d}")
            for i, a in enumerate(np.arange(t0, t1, 1.0))]


def _walk_session(app: Flask, client: FlaskClient, token: str, name: str, order: list[tuple[str, int]],
                  batches: dict[str, list[dict]]) -> str:
    sid = client.post("/api/v1/sessions", json={"session_id": f"walk-{name}"}, headers=bearer(token)).get_json()["id"]
    for side, i in order:
        body = {**batches[side][i], "session_id": f"walk-{name}"}
        resp = client.post(f"/api/v1/sessions/{sid}/batches", json=body, headers=bearer(token))
        assert resp.status_code == 201, resp.get_json()
    assert app.extensions["pdr"].worker.wait_idle(300)
    return sid


def _track(client: FlaskClient, token: str, sid: str, device: str) -> list[dict]:
    return client.get(f"/api/v1/sessions/{sid}/track?device={device}", headers=bearer(token)).get_json()["points"]


def _footprint_error(points: list[dict], recs: dict[str, Recording], step_t: dict[str, np.ndarray]) -> float:
    """Mean horizontal distance (m) of track points from the truth: each foot at its latest reset (its current
    footprint), the fused points from the midpoint of the two; positions from each foot's start.
    """
    t = np.array([p["t_s"] for p in points])
    est = np.array([[p["east_m"], p["north_m"]] for p in points])
    truths = []
    for side, rec in recs.items():
        pos = rec.truth.positions
        assert pos is not None
        k = np.searchsorted(step_t[side], t, side="right") - 1          # latest reset of this foot at t
        t_fp = np.where(k >= 0, step_t[side][np.maximum(k, 0)], pos.t_s[0] + T0_NS / 1e9) - T0_NS / 1e9
        truths.append(np.stack([np.interp(t_fp, pos.t_s, pos.pos_m[:, i]) - pos.pos_m[0, i] for i in range(2)], 1))
    return float(np.mean(np.linalg.norm(est - np.mean(truths, axis=0), axis=1)))


def test_both_shoes_give_one_fused_track_whatever_the_upload_order(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    recs = {"left": _shoe("left", 1), "right": _shoe("right", 2)}
    batches = {side: _batches(rec, side[0].upper()) for side, rec in recs.items()}
    n = min(len(b) for b in batches.values())
    interleaved = [(side, i) for i in range(n) for side in ("left", "right")]
    shuffled = [interleaved[i] for i in np.random.default_rng(5).permutation(len(interleaved))]
    sessions = {name: _walk_session(real_app, client, token, name, order, batches)
                for name, order in (("interleaved", interleaved), ("shuffled", shuffled))}

    fused = {name: _track(client, token, sid, "fused") for name, sid in sessions.items()}
    assert fused["interleaved"] == fused["shuffled"]
    sid = sessions["shuffled"]
    feet = {side: _track(client, token, sid, f"{side}_foot") for side in recs}
    points = fused["shuffled"]
    assert len(points) == len(feet["left"]) + len(feet["right"]) > 30
    assert [p["t_s"] for p in points] == sorted(p["t_s"] for p in feet["left"] + feet["right"])
    # A fused update has the mode of the foot row it fuses: 'standing' for a reset while that foot stands (each
    # foot's first reset, at the start of its first swing), not a step of the session (it was 'walking' and counted).
    foot_mode = {p["t_s"]: p["mode"] for side in recs for p in feet[side]}
    assert [p["mode"] for p in points] == [foot_mode[p["t_s"]] for p in points]
    assert {p["mode"] for p in points} == {"walking", "standing"} and {p["floor"] for p in points} == {None}
    # The walker moves about one step length per fused update (half a stride).
    lengths = np.array([p["step_length_m"] for p in points[2:]])
    assert 0.4 < np.median(lengths) < 1.0
    # The session summary stands for the fused track.
    listed = client.get("/api/v1/sessions", headers=bearer(token)).get_json()["sessions"]
    mine = next(s for s in listed if s["id"] == sid)
    assert mine["steps"] == sum(p["mode"] == "walking" for p in points) and mine["primary_track"] == "fused"
    assert mine["feet"] == {"paired": ["left_foot", "right_foot"], "live": ["left_foot", "right_foot"]}

    # The stored rows are the library's DualFootFusion over the feet's stored step increments, exactly.
    steps = client.get(f"/api/v1/sessions/{sid}/steps", headers=bearer(token)).get_json()["steps"]
    fusion = DualFootFusion()
    ref = []
    for side in ("left", "right"):
        ref += fusion.add_steps(side, [increment_from_json(s["t_s"], s, s["label"]) for s in steps
                                       if s["device"] == f"{side}_foot"])
    ref += fusion.finish()
    assert [p["t_s"] for p in points] == [u.t_s for u in ref]
    assert [p["mode"] for p in points] == [mode_of(u.stride) for u in ref]
    np.testing.assert_array_equal([[p["east_m"], p["north_m"], p["up_m"]] for p in points],
                                  [u.midpoint_n for u in ref])
    np.testing.assert_allclose([p["heading_deg"] for p in points], yaw_to_heading_deg([u.body_yaw for u in ref]),
                               rtol=0, atol=1e-9)

    # Against the simulator's truth: the fused walker is closer than the worse shoe alone, and than the two
    # shoes' mean (the constraint averages their independent heading drifts).
    step_t = {side: np.array([p["t_s"] for p in feet[side]]) for side in recs}
    alone = [_footprint_error(feet[side], {side: recs[side]}, step_t) for side in recs]
    both = _footprint_error(points, recs, step_t)
    assert both < max(alone) and both < float(np.mean(alone)), (both, alone)

    # Reprocessing from the raw batches reproduces the fused track.
    assert client.post(f"/api/v1/sessions/{sid}/reprocess", headers=bearer(token)).status_code == 202
    assert real_app.extensions["pdr"].worker.wait_idle(300)
    assert _track(client, token, sid, "fused") == points


def test_a_single_shoe_has_no_fused_track(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    batches = {"left": _batches(_shoe("left", 1), "L")}
    sid = _walk_session(real_app, client, token, "one", [("left", i) for i in range(12)], batches)
    assert _track(client, token, sid, "left_foot") and not _track(client, token, sid, "fused")
