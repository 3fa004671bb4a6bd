"""Issue 32 against the real ``pdr serve`` process: a user pairs shoes, uploads a shoe file to a paired foot,
sends step summaries, names sessions by their key, reprocesses, and gives a bad calibration.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest

from pdr.cli import main as pdr_main
from server.client import Client, add_user, running_server
from tests.conftest import data_path
from tests.server.helpers import multipart, wait_processed

pytestmark = [pytest.mark.data, pytest.mark.timeout(600)]

#: A phone walk of 34 s (simulated, hand-held, clock from 0 as the PyShoe files').
PHONE_LOG = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim" / "hand_escalator.zip"



def test_shoes_paired_uploaded_and_summarised_through_the_real_service(tmp_path: Path) -> None:
    log = data_path("pyshoe_vicon", "2017-11-22-11-52-02.mat")
    with running_server(tmp_path / "srv") as (url, env, _):
        c = Client(url, add_user(env, "walker"))
        sid = c.request("POST", "/api/v1/sessions", {"session_id": "hall-walk"}).json()["id"]
        for role in ("left_foot", "right_foot"):
            assert c.request("POST", f"/api/v1/sessions/{sid}/devices", {"role": role}).status == 201
        body, content_type = multipart({"file": (log.read_bytes(), log.name)})
        # Item 4: the file sent to the native batch route is refused with the route that takes it; there the
        # pairing decides the foot (a PyShoe file reads as right_foot).
        r = c.request("POST", f"/api/v1/sessions/{sid}/batches", raw=body, content_type=content_type)
        assert r.status == 415 and f"/sessions/{sid}/devices/ROLE/upload" in r.json()["error"]["message"], r.body
        r = c.request("POST", f"/api/v1/sessions/{sid}/devices/left_foot/upload", raw=body, content_type=content_type)
        assert r.status == 201 and r.json()["device_role"] == "left_foot", r.body[:300]

        # Items 1 and 3: the silent right foot is not fused in; the left foot's track is the session's.
        s = wait_processed(c, sid)
        assert s["status"] == "done" and s["feet"]["live"] == ["left_foot"] and "fused" not in s["tracks"]
        assert s["primary_track"] == "left_foot" and s["distance_m"] == s["tracks"]["left_foot"]["distance_m"]
        # Item 7: the client's key finds the session.
        assert c.request("GET", "/api/v1/sessions/hall-walk").json()["id"] == sid
        # Item 2: every CSV row names its device; ?device=primary is the left foot's track.
        rows = list(csv.DictReader(c.request("GET", f"/api/v1/sessions/{sid}/track?format=csv").body
                                   .decode().splitlines()))
        assert rows and {r["device"] for r in rows} == {"left_foot"}
        primary = c.request("GET", f"/api/v1/sessions/{sid}/track?device=primary").json()["points"]
        assert [p["east_m"] for p in primary] == [float(r["east_m"]) for r in rows]

        # Item 5: summaries of an unpaired foot are refused; pdr foot's payload for the paired one is taken.
        payload = tmp_path / "steps.json"
        assert pdr_main(["foot", str(log), "--method", "stepwise", "--per-step", "--format", "foot-steps",
                         "--role", "right_foot", "--out", str(payload)]) == 0
        other = c.request("POST", "/api/v1/sessions", {"session_id": "summaries"}).json()["id"]
        steps = json.loads(payload.read_text())
        assert c.request("POST", f"/api/v1/sessions/{other}/steps", steps).status == 409
        assert c.request("POST", f"/api/v1/sessions/{other}/devices", {"role": "right_foot"}).status == 201
        assert c.request("POST", f"/api/v1/sessions/{other}/steps", steps).status == 201
        summarised = wait_processed(c, other)
        # The session counts the summaries that close a stride (pdr foot's count), not its resets while the foot stands.
        strides = sum(bool(step.get("stride", True)) for step in steps["steps"])
        assert strides < len(steps["steps"])
        assert summarised["primary_track"] == "right_foot" and summarised["steps"] == strides
        # Summaries and the raw file give the same track (eq. 7 composition of the same increments).
        assert summarised["distance_m"] == pytest.approx(s["distance_m"], abs=1e-6)

        # Item 7: another file under an existing session_id is refused with the session it names.
        body, content_type = multipart({"file": (log.read_bytes(), log.name), "session_id": "hall-walk"})
        r = c.request("POST", "/api/v1/sessions", raw=body, content_type=content_type)
        assert r.status == 409 and r.json()["error"]["details"]["session"] == sid
        # Items 1 and 6: once the right foot sends data too, the fused track is the primary one, and not halved
        # (the same walk on both feet fuses to that walk); with a phone that walked longer than the shoes (a 34 s
        # simulated walk on the same clock), the session lasts from the first to the last step of any of its
        # tracks, not the fused track's span.
        body, content_type = multipart({"file": (log.read_bytes(), log.name)})
        r = c.request("POST", f"/api/v1/sessions/{sid}/devices/right_foot/upload", raw=body, content_type=content_type)
        assert r.status == 201 and r.json()["device_role"] == "right_foot", r.body[:300]
        assert c.request("POST", f"/api/v1/sessions/{sid}/devices", {"role": "phone"}).status == 201
        body, content_type = multipart({"file": (PHONE_LOG.read_bytes(), PHONE_LOG.name)})
        r = c.request("POST", f"/api/v1/sessions/{sid}/devices/phone/upload", raw=body, content_type=content_type)
        assert r.status == 201 and r.json()["device_role"] == "phone", r.body[:300]
        s = wait_processed(c, sid)
        tracks = s["tracks"]
        assert s["feet"] == {"paired": ["left_foot", "right_foot"], "live": ["left_foot", "right_foot"]}
        assert s["primary_track"] == "fused" and s["distance_m"] == tracks["fused"]["distance_m"]
        assert tracks["fused"]["distance_m"] == pytest.approx(tracks["left_foot"]["distance_m"], rel=0.1)
        first = min(t["first_t_s"] for t in tracks.values())
        last = max(t["last_t_s"] for t in tracks.values())
        assert last == tracks["phone"]["last_t_s"] > tracks["fused"]["last_t_s"] + 10.0
        assert s["duration_s"] == pytest.approx(last - first, abs=1e-3)
        # Items 2 and 3: with four tracks, every CSV row names its device; the phone still gives the modes.
        rows = list(csv.DictReader(c.request("GET", f"/api/v1/sessions/{sid}/track?format=csv").body
                                   .decode().splitlines()))
        assert {r["device"] for r in rows} == set(tracks) == {"phone", "left_foot", "right_foot", "fused"}
        fused_rows = c.request("GET", f"/api/v1/sessions/{sid}/track?format=csv&device=primary").body.decode()
        assert {r["device"] for r in csv.DictReader(fused_rows.splitlines())} == {"fused"}
        modes = c.request("GET", f"/api/v1/sessions/{sid}/modes").json()["modes"]
        assert modes and {m["device"] for m in modes} == {"phone"}
        # Item 10: while the session is rebuilt it keeps answering with the results from before.
        assert c.request("POST", f"/api/v1/sessions/{sid}/reprocess").status == 202
        seen, deadline = [], time.monotonic() + 300
        while True:
            now = c.request("GET", f"/api/v1/sessions/{sid}").json()
            seen.append((now["rebuilding"], now["tracks"]))
            if not now["rebuilding"] and now["status"] == "done" and not now["batches"].get("pending"):
                break
            assert time.monotonic() < deadline, now
            time.sleep(0.05)
        assert all(tracks == s["tracks"] for _, tracks in seen), seen
        # Item 9: a calibration that clamps every step is refused, naming the field.
        r = c.request("PUT", f"/api/v1/sessions/{sid}/processing", {"calibration": {"step_length": {"k": -1}}})
        assert r.status == 422 and "step_length.k" in r.json()["error"]["message"]
        c.close()


def test_every_foot_format_uploads_to_its_paired_foot_through_the_real_service(tmp_path: Path) -> None:
    """Item 4 for the other shoe formats: an x-io CSV and a SensorConnect CSV (both read as right_foot: the files
    do not say) each uploaded to a paired left foot, which the pairing makes them."""
    files = {"xio": ("left_foot", data_path("xio_gait_loop", "short_walk.csv")),
             "sensorconnect": ("left_foot", data_path("foot_stride_gcp", "own", "SensorConnectData_31.csv"))}
    with running_server(tmp_path / "srv") as (url, env, _):
        c = Client(url, add_user(env, "walker"))
        sessions = {}
        for fmt, (role, log) in files.items():
            sid = c.request("POST", "/api/v1/sessions", {"session_id": f"walk-{fmt}"}).json()["id"]
            assert c.request("POST", f"/api/v1/sessions/{sid}/devices", {"role": role}).status == 201
            body, content_type = multipart({"file": (log.read_bytes(), log.name)})
            r = c.request("POST", f"/api/v1/sessions/{sid}/devices/{role}/upload", raw=body,
                          content_type=content_type)
            assert r.status == 201 and r.json()["format"] == fmt and r.json()["device_role"] == role, r.body[:300]
            sessions[fmt] = sid
        for fmt, sid in sessions.items():
            s = wait_processed(c, sid)
            assert s["status"] == "done" and s["primary_track"] == files[fmt][0] and s["steps"] > 5, (fmt, s)
        c.close()
