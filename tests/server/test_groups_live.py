"""Issue 32 item 8 against the real ``pdr serve`` process: a group whose agents take their steps from live
sessions (updated as the sessions' batches arrive, a session's clock put on the group's by the agent's
``clock_offset_s``), ranges fused and stale ones refused with 422, one foot vocabulary (``left_foot``/``right_foot``
in the configuration, step events, corrections and tracks; the old ``left`` refused naming the field), and the
upload's documented schema.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from pdr.io import read_recording
from pdr.io.native import batch_to_json
from pdr.recording import Recording
from server.client import Client, add_user, running_server
from tests.conftest import data_path
from tests.server.helpers import multipart, wait_processed

pytestmark = [pytest.mark.data, pytest.mark.timeout(1500)]

#: Two PyShoe trials whose walks end within 4 s of each other (last final steps at 42.1 s and about 40 s).
TRIAL_A, TRIAL_B = "2017-11-27-11-18-11", "2017-11-27-11-24-07"
#: Agent b's shoe stamps its samples on its own clock, this much ahead of the group's (s; e.g. time since boot).
B_CLOCK_AHEAD_S = 1000.0


def _clock_shifted(rec: Recording, ahead_s: float) -> Recording:
    """``rec`` as a device whose clock is ``ahead_s`` (s) ahead of the recording's."""
    dt_ns = int(round(ahead_s * 1e9))
    streams = {k: dataclasses.replace(st, t_ns=st.t_ns + dt_ns) for k, st in rec.streams.items()}
    return dataclasses.replace(rec, streams=streams, t0_ns=rec.origin_ns + dt_ns)



def _agent(c: Client, gid: str, name: str) -> dict[str, Any]:
    group = c.request("GET", f"/api/v1/groups/{gid}").json()
    return next(a for a in group["agents"] if a["agent"] == name)


def _final_steps(c: Client, sid: str) -> list[float]:
    """Times of the session's final foot steps (the provisional tail is not fed to groups)."""
    points = c.request("GET", f"/api/v1/sessions/{sid}/track?device=left_foot").json()["points"]
    return [p["t_s"] for p in points if not p["provisional"]]


def _left_track(c: Client, gid: str, name: str) -> list[list[float]]:
    tracks = c.request("GET", f"/api/v1/groups/{gid}/tracks?agent={name}").json()["agents"]
    return tracks.get(name, {}).get("left_foot", [])


def test_a_group_fed_by_live_sessions_through_the_real_service(tmp_path) -> None:
    log_a = data_path("pyshoe_vicon", f"{TRIAL_A}.mat")
    rec_b = read_recording(data_path("pyshoe_vicon", f"{TRIAL_B}.mat"))
    rec_b = _clock_shifted(dataclasses.replace(rec_b, device=dataclasses.replace(rec_b.device, role="left_foot")),
                           B_CLOCK_AHEAD_S)
    half_s = 20.0
    with running_server(tmp_path / "srv") as (url, env, _):
        c = Client(url, add_user(env, "leader"))
        # The upload's event format is part of the documented API (a schema per event type).
        spec = c.request("GET", "/api/v1/openapi.json").json()
        events = spec["components"]["schemas"]["GroupUpload"]["properties"]["events"]["items"]
        assert events["properties"]["type"]["enum"][0] == "step" and len(events["allOf"]) == 5
        assert events["allOf"][0]["then"]["properties"]["foot"]["enum"] == ["left_foot", "right_foot"]

        # Agent a: its shoe file is in its session before it joins; joining feeds the steps taken so far.
        sa = c.request("POST", "/api/v1/sessions", {"session_id": "walker-a"}).json()["id"]
        assert c.request("POST", f"/api/v1/sessions/{sa}/devices", {"role": "left_foot"}).status == 201
        body, content_type = multipart({"file": (log_a.read_bytes(), log_a.name)})
        assert c.request("POST", f"/api/v1/sessions/{sa}/devices/left_foot/upload", raw=body,
                         content_type=content_type).status == 201
        wait_processed(c, sa)
        steps_a = _final_steps(c, sa)
        r = c.request("POST", "/api/v1/groups", {"name": "pair", "config": {"feet": ["left"]}})
        assert r.status == 422 and "now called 'left_foot'" in r.json()["error"]["message"], r.body
        r = c.request("POST", "/api/v1/groups", {"name": "pair", "config": {"feet": ["left_foot"]},
                                                 "contact_timeout_s": 600})
        assert r.status == 201 and r.json()["config"]["feet"] == ["left_foot"], r.body
        gid = r.json()["id"]
        r = c.request("POST", f"/api/v1/groups/{gid}/agents", {"agent": "a", "session_id": sa,
                                                               "pos0_n": [0, 0, 0]})
        assert r.status == 201 and r.json()["correction"]["steps"] == [len(steps_a)], r.body
        assert r.json()["correction"]["feet"] == ["left_foot"]
        assert _agent(c, gid, "a")["latest_s"] == steps_a[-1] == r.json()["correction"]["t_s"][0]

        # Agent b joins before its session has data; its track follows the batches as they are processed, its
        # shoe's clock put on the group's.
        sb = c.request("POST", "/api/v1/sessions", {"session_id": "walker-b"}).json()["id"]
        assert c.request("POST", f"/api/v1/sessions/{sb}/devices", {"role": "left_foot"}).status == 201
        assert c.request("POST", f"/api/v1/groups/{gid}/agents", {"agent": "b", "session_id": sb, "pos0_n": [0, 10, 0],
                                                                  "clock_offset_s": -B_CLOCK_AHEAD_S}).status == 201
        assert _left_track(c, gid, "b") == [[0.0, 0.0, 10.0, 0.0, 90.0]]          # its initial pose only
        for i, (t0, t1) in enumerate(((0.0, half_s), (half_s, float(rec_b.duration_s) + 1.0))):
            batch = batch_to_json(rec_b.slice_time(t0, t1), batch_id=f"b-{i}")
            assert c.request("POST", f"/api/v1/sessions/{sb}/batches", batch).status == 201
            wait_processed(c, sb)
            track = _left_track(c, gid, "b")
            fed = _agent(c, gid, "b")["latest_s"]
            assert track[-1][0] == fed and len(track) > 5
            if i == 0:
                assert fed < half_s                                          # the first half only
                first_half = len(track)
            else:
                assert len(track) > first_half
        assert _agent(c, gid, "b")["clock_offset_s"] == -B_CLOCK_AHEAD_S and _agent(c, gid, "a")["clock_offset_s"] == 0
        # Every final step of the session is in the group, at its time on the group's clock, no more (the
        # provisional tail is not).
        session_steps = _final_steps(c, sb)
        assert session_steps[0] > B_CLOCK_AHEAD_S
        assert [row[0] for row in _left_track(c, gid, "b")[1:]] == pytest.approx(
            [t - B_CLOCK_AHEAD_S for t in session_steps], abs=1e-6)

        # Steps of an agent fed from a session are refused; its ranges are taken.
        step = {"type": "step", "agent": "a", "foot": "left_foot", "t_s": 50.0, "dp": [1, 0, 0], "dpsi": 0,
                "cov": np.eye(4).tolist()}
        r = c.request("POST", f"/api/v1/groups/{gid}/uploads", {"batch_id": "s", "agent": "a", "events": [step]})
        assert r.status == 409 and "takes its steps from session" in r.json()["error"]["message"]
        # A range older than the fusion horizon (a's state is at 42.1 s, ranges live 2 s): 422, nothing kept.
        old = {"type": "range", "agent_a": "a", "agent_b": "b", "t_s": 5.0, "range_m": 10.0}
        r = c.request("POST", f"/api/v1/groups/{gid}/uploads", {"batch_id": "r1", "agent": "a", "events": [old]})
        err = r.json()["error"]
        assert r.status == 422 and err["code"] == "stale_range" and err["details"]["events"] == [0], r.body
        assert "older than the fusion horizon of agent 'a'" in err["message"]
        fresh = dict(old, t_s=_agent(c, gid, "b")["latest_s"] + 1.0)
        r = c.request("POST", f"/api/v1/groups/{gid}/uploads", {"batch_id": "r1", "agent": "a", "events": [fresh]})
        assert r.status == 201 and r.json()["accepted"] == 1 and not r.json()["duplicate"], r.body
        flushed = c.request("POST", f"/api/v1/groups/{gid}/flush").json()
        assert flushed["stale_ranges"] == 0 and flushed["pending"] == 0
        assert c.request("GET", f"/api/v1/groups/{gid}").json()["fusion_counts"]["ranges"] == 1

        # One foot vocabulary: an agent of its own uploads steps naming the foot as sessions do.
        assert c.request("POST", f"/api/v1/groups/{gid}/agents", {"agent": "c", "pos0_n": [0, 20, 0]}).status == 201
        step = dict(step, agent="c", foot="left_foot", t_s=1.0)
        r = c.request("POST", f"/api/v1/groups/{gid}/uploads", {"batch_id": "c1", "agent": "c", "events": [step]})
        assert r.status == 201 and r.json()["accepted"] == 1
        r = c.request("POST", f"/api/v1/groups/{gid}/uploads",
                      {"batch_id": "c2", "agent": "c", "events": [dict(step, foot="left", t_s=2.0)]})
        assert r.status == 422 and r.json()["error"]["details"]["path"] == "events[0].foot", r.body
        tracks = c.request("GET", f"/api/v1/groups/{gid}/tracks").json()["agents"]
        assert {foot for feet in tracks.values() for foot in feet} == {"left_foot"}
        c.close()
