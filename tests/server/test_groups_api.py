"""Groups API: cooperative localization with the server as fusion centre (access control, errors, fusion)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient
from sqlalchemy import func, select

from pdr.errors import InputError
from pdr.fusion.measurements import event_to_dict
from pdr.fusion.simulation import SimulationConfig, StepEvent, march_scenario, run_scenario
from pdr.fusion.state import FootKey
from server import auth
from server.api import groups
from server.group_store import group_agents, group_track_points, group_uploads
from tests.server.conftest import bearer


@pytest.fixture
def gapp(app: Flask) -> Flask:
    if "groups" not in app.blueprints:              # until the app factory registers it
        app.register_blueprint(groups.bp)
    return app


@pytest.fixture
def gclient(gapp: Flask) -> FlaskClient:
    return gapp.test_client()


def scenario() -> Any:
    return march_scenario(2, 30, SimulationConfig(), np.random.default_rng(9))


def join_all(client: FlaskClient, token: str, gid: str, sc: Any) -> None:
    for a in sc.agents:
        left = sc.truth[FootKey(a, "left")].pos_n[0]
        right = sc.truth[FootKey(a, "right")].pos_n[0]
        r = client.post(f"/api/v1/groups/{gid}/agents", headers=bearer(token),
                        json={"agent": a, "pos0_n": left.tolist(), "heading0_deg": 90.0,
                              "foot_offsets_n": [[0, 0, 0], (right - left).tolist()]})
        assert r.status_code == 201, r.get_json()


def events_json(sc: Any, agent: str, t0: float, t1: float) -> list[dict[str, Any]]:
    """The agent's events in [t0, t1) as it uploads them (the simulation's feet left/right named as the API's)."""
    from pdr.fusion.measurements import InterAgentRange, StepSummary
    out = []
    for e in sc.events():
        if not t0 <= e.t_s < t1:
            continue
        if isinstance(e, StepEvent) and e.agent == agent:
            out.append(event_to_dict(StepSummary(e.agent, f"{e.foot}_foot", e.increment)))
        elif not isinstance(e, StepEvent) and e.agent_a == agent:
            out.append(event_to_dict(InterAgentRange(e.t_s, e.agent_a, e.agent_b, e.measured_m)))
    return out


def test_group_fuses_uploads_like_the_library(gclient: FlaskClient, tokens: dict[str, str]) -> None:
    """The library's fusion of the same events, with the feet named as sessions name them everywhere in the API:
    step events, the group's configuration, corrections and tracks (left_foot, right_foot)."""
    tok = tokens["alice"]
    r = gclient.post("/api/v1/groups", headers=bearer(tok), json={"name": "team", "contact_timeout_s": 30})
    assert r.status_code == 201
    gid = r.get_json()["id"]
    sc = scenario()
    join_all(gclient, tok, gid, sc)
    for t0 in range(0, 31, 10):
        for a in sc.agents:
            events = events_json(sc, a, t0, t0 + 10)
            r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok),
                             json={"batch_id": f"{a}-{t0}", "agent": a, "events": events})
            assert r.status_code == 201, r.get_json()
            assert r.get_json()["correction"]["agent"] == a
    again = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok),
                         json={"batch_id": "a0-0", "agent": "a0", "events": []})
    assert again.status_code == 200 and again.get_json()["duplicate"]
    assert gclient.post(f"/api/v1/groups/{gid}/flush", headers=bearer(tok)).status_code == 200
    corr = gclient.get(f"/api/v1/groups/{gid}/agents/a1/correction", headers=bearer(tok)).get_json()
    reference = run_scenario(sc)
    np.testing.assert_allclose(corr["mean"], reference.centre.correction("a1").mean, atol=1e-9)
    assert corr["feet"] == ["left_foot", "right_foot"]
    tracks = gclient.get(f"/api/v1/groups/{gid}/tracks", headers=bearer(tok)).get_json()["agents"]
    assert set(tracks) == {"a0", "a1"} and set(tracks["a0"]) == {"left_foot", "right_foot"}
    assert len(tracks["a0"]["left_foot"]) == 31                                 # initial pose + 30 steps
    east = [row[1] for row in tracks["a0"]["left_foot"]]
    assert east[-1] == pytest.approx(30.0, abs=2.0)
    detail = gclient.get(f"/api/v1/groups/{gid}", headers=bearer(tok)).get_json()
    assert detail["pending"] == 0 and detail["fusion_counts"]["ranges"] > 0
    assert detail["config"]["feet"] == ["left_foot", "right_foot"]
    listed = gclient.get("/api/v1/groups", headers=bearer(tok)).get_json()["groups"]
    assert [g["id"] for g in listed] == [gid]


def test_a_group_is_deleted_by_its_owner_with_all_it_holds(gclient: FlaskClient, tokens: dict[str, str],
                                                            gapp: Flask) -> None:
    alice, bob = bearer(tokens["alice"]), bearer(tokens["bob"])
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "team"}).get_json()["id"]
    keep = gclient.post("/api/v1/groups", headers=alice, json={"name": "other"}).get_json()["id"]
    sc = scenario()
    join_all(gclient, tokens["alice"], gid, sc)
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "a0-0", "agent": "a0", "events": events_json(sc, "a0", 0, 10)})
    assert r.status_code == 201
    def rows(table: Any) -> int:
        with gapp.extensions["pdr"].store.engine.connect() as conn:
            count = select(func.count()).select_from(table).where(table.c.group_id == gid)
            return int(conn.execute(count).scalar_one())

    assert rows(group_agents) == 2 and rows(group_uploads) == 1 and rows(group_track_points) > 0
    assert gclient.delete(f"/api/v1/groups/{gid}", headers=bob).status_code == 404       # not bob's to delete
    with gapp.extensions["pdr"].store.engine.begin() as conn:
        read_only = auth.issue_token(conn, auth.user_id(conn, "alice"), scope="read")
    assert gclient.delete(f"/api/v1/groups/{gid}", headers=bearer(read_only)).status_code == 403
    assert gclient.delete(f"/api/v1/groups/{gid}", headers=alice).status_code == 204
    assert gclient.get(f"/api/v1/groups/{gid}", headers=alice).status_code == 404
    assert gclient.delete(f"/api/v1/groups/{gid}", headers=alice).status_code == 404
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "a0-1", "agent": "a0", "events": events_json(sc, "a0", 10, 20)})
    assert r.status_code == 404
    assert [g["id"] for g in gclient.get("/api/v1/groups", headers=alice).get_json()["groups"]] == [keep]
    assert rows(group_agents) == rows(group_uploads) == rows(group_track_points) == 0


def test_an_upload_or_member_stored_after_its_group_was_deleted_is_a_404(gclient: FlaskClient, tokens: dict[str, str],
                                                                gapp: Flask) -> None:
    # The upload route checks the group first, then stores the upload: a deletion in between left an insert
    # that its foreign key refuses, which was retried without end.
    from server.errors import APIError
    from server.group_store import GroupStore

    alice = bearer(tokens["alice"])
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "team"}).get_json()["id"]
    repo = GroupStore(gapp.extensions["pdr"].store.engine)
    assert repo.add_upload(gid, "a0", "b0", b"{}")[1]
    assert gclient.delete(f"/api/v1/groups/{gid}", headers=alice).status_code == 204
    with pytest.raises(APIError) as err:
        repo.add_upload(gid, "a0", "b1", b"{}")
    assert err.value.status == 404
    with pytest.raises(APIError) as err:
        repo.add_agent(gid, "a1", None)
    assert err.value.status == 404


def test_access_control_and_errors(gclient: FlaskClient, tokens: dict[str, str]) -> None:
    alice, bob = bearer(tokens["alice"]), bearer(tokens["bob"])
    assert gclient.get("/api/v1/groups").status_code == 401
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "a"}).get_json()["id"]
    assert gclient.get(f"/api/v1/groups/{gid}", headers=bob).status_code == 404
    assert gclient.post(f"/api/v1/groups/{gid}/agents", headers=bob,
                        json={"agent": "x", "pos0_n": [0, 0, 0]}).status_code == 404
    assert gclient.get("/api/v1/groups", headers=bob).get_json() == {"groups": []}
    r = gclient.post("/api/v1/groups", headers=alice, json={"name": "a", "colour": 1})
    assert r.status_code == 422 and r.get_json()["error"]["code"] == "invalid_input"
    r = gclient.post("/api/v1/groups", headers=alice, json={"config": {"feet": []}})
    assert r.status_code == 422 and "feet" in r.get_json()["error"]["message"]
    # One foot vocabulary: the fusion library's old names are refused, naming the field and the new name.
    r = gclient.post("/api/v1/groups", headers=alice, json={"config": {"feet": ["left_foot", "right"]}})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["path"] == "config.feet[1]"
    assert "now called 'right_foot'" in r.get_json()["error"]["message"]
    r = gclient.post("/api/v1/groups", headers=alice, json={"config": {"feet": ["hand"]}})
    assert r.status_code == 422 and "config.feet[0]" in r.get_json()["error"]["message"]
    for config, path in (({"ranging": {"sigma_m": 0}}, "config.ranging.sigma_m"),
                         ({"lattice_points": 2.5}, "config.lattice_points"), ({"colour": 1}, "config"),
                         # accepted (201) before: 1001 took 19 GB at the group's first range, 100 000 and 1e160 m
                         # failed it (500) and every later update of the group
                         ({"lattice_points": 1001}, "config.lattice_points"),
                         ({"separation": {"gamma_xy": 1e160}}, "config.separation.gamma_xy")):
        r = gclient.post("/api/v1/groups", headers=alice, json={"config": config})
        assert r.status_code == 422 and r.get_json()["error"]["details"]["path"] == path, r.get_json()
    spec = gclient.get("/api/v1/openapi.json").get_json()["components"]["schemas"]["CreateGroup"]
    assert spec["properties"]["config"]["properties"]["ranging"]["properties"]["sigma_m"]["exclusiveMinimum"] == 0
    one = gclient.post("/api/v1/groups", headers=alice, json={"config": {"feet": ["right_foot"]}}).get_json()
    assert one["config"]["feet"] == ["right_foot"]
    assert gclient.post(f"/api/v1/groups/{one['id']}/agents", headers=alice,
                        json={"agent": "x", "pos0_n": [0, 0, 0]}).status_code == 201
    step = {"type": "step", "agent": "x", "foot": "left_foot", "t_s": 1, "dp": [1, 0, 0], "dpsi": 0,
            "cov": np.eye(4).tolist()}
    r = gclient.post(f"/api/v1/groups/{one['id']}/uploads", headers=alice,
                     json={"batch_id": "b", "agent": "x", "events": [step]})
    assert r.status_code == 422 and "one of this group's feet, right_foot" in r.get_json()["error"]["message"]
    assert gclient.post("/api/v1/groups", headers=alice, data="x").status_code == 415
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice, json={"agent": "x", "pos0_n": [0, 0]})
    assert r.status_code == 422
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                     json={"agent": "x", "pos0_n": [0, 0, 0], "session_id": "nope"})
    assert r.status_code == 404
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                     json={"agent": "x", "pos0_n": [0, 0, 0], "clock_offset_s": 5.0})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "clock_offset_s"
    sid = gclient.post("/api/v1/sessions", headers=alice, json={"session_id": "walk"}).get_json()["id"]
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice, data='{"agent": "x", "pos0_n": [0, 0, 0], '
                     f'"session_id": "{sid}", "clock_offset_s": Infinity}}', content_type="application/json")
    assert r.status_code == 422 and "finite" in r.get_json()["error"]["message"]
    # a foot 1e308 m from its agent joined (201), and the group's next fused update failed it for good (500)
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                     json={"agent": "x", "pos0_n": [0, 0, 0], "foot_offsets_n": [[0, 0, 0], [1e308, 0, 0]]})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["path"] == "foot_offsets_n[1][0]", r.get_json()
    assert gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                        json={"agent": "x", "pos0_n": [0, 0, 0]}).status_code == 201
    assert gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                        json={"agent": "x", "pos0_n": [0, 0, 0]}).status_code == 409
    bad = [({"batch_id": "b", "agent": "y", "events": []}, "has not joined"),
           ({"batch_id": "b", "agent": "x", "events": [{"type": "range", "agent_a": "x", "agent_b": "z",
                                                         "t_s": 1, "range_m": 2}]}, "events[0]: agent 'z'"),
           ({"batch_id": "b", "agent": "x", "events": [{"type": "step", "agent": "x", "foot": "left_foot",
                                                         "t_s": 1, "dp": [1, 0], "dpsi": 0, "cov": []}]}, "events[0]"),
           ({"batch_id": "b", "agent": "x", "events": [{"type": "step", "agent": "x", "foot": "hand", "t_s": 1,
                                                         "dp": [1, 0, 0], "dpsi": 0,
                                                         "cov": np.eye(4).tolist()}]}, "events[0].foot: 'hand'"),
           ({"batch_id": "b", "agent": "x", "events": [{"type": "step", "agent": "x", "foot": "left", "t_s": 1,
                                                         "dp": [1, 0, 0], "dpsi": 0, "cov": np.eye(4).tolist()}]},
            "events[0].foot: the foot 'left' is now called 'left_foot'"),
           ({"batch_id": "b", "agent": "x", "events": [{"type": "range", "agent_a": "x", "agent_b": "x",
                                                         "t_s": 1}]}, "events[0]: 'range_m' is a required"),
           ({"batch_id": "b", "agent": "x", "events": [{"type": "walk", "t_s": 1}]}, "events[0].type")]
    for body, message in bad:
        r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice, json=body)
        assert r.status_code == 422 and message in r.get_json()["error"]["message"], r.get_json()
    assert gclient.get(f"/api/v1/groups/{gid}/agents/zz/correction", headers=alice).status_code == 404
    assert gclient.get(f"/api/v1/groups/{gid}/tracks?since_s=abc", headers=alice).status_code == 422
    assert gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bob,
                        json={"batch_id": "b", "agent": "x", "events": []}).status_code == 404


def test_stale_ranges_are_refused_and_nothing_of_the_upload_is_kept(gclient: FlaskClient,
                                                                   tokens: dict[str, str]) -> None:
    """Issue 32: a0 uploads its whole 30 s walk with its ranges to a1, which has not reported: the group does
    not wait for a1 (contact timeout 10 s), so those ranges could never be fused: 422 naming them and why."""
    tok = tokens["alice"]
    gid = gclient.post("/api/v1/groups", headers=bearer(tok), json={"name": "t"}).get_json()["id"]
    sc = scenario()
    join_all(gclient, tok, gid, sc)
    events = events_json(sc, "a0", 0, 31)
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok),
                     json={"batch_id": "walk", "agent": "a0", "events": events})
    err = r.get_json()["error"]
    ranges = [i for i, e in enumerate(events) if e["type"] == "range"]
    assert r.status_code == 422 and err["code"] == "stale_range", err
    refused = err["details"]["events"]
    assert set(refused) <= set(ranges) and len(err["details"]["reasons"]) == len(refused)
    assert "agent 'a1' has reported only up to 0 s and is out of contact" in err["message"]
    steps = [e for e in events if e["type"] == "step"]
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok),
                     json={"batch_id": "walk", "agent": "a0", "events": steps})
    assert r.status_code == 201 and r.get_json()["accepted"] == len(steps)       # the refused one was not kept


def test_a_step_beyond_any_stride_is_refused_and_cannot_break_the_group(gclient: FlaskClient,
                                                                       tokens: dict[str, str]) -> None:
    """A step of dp 1e200 m or variance 1e308 (finite, so it passed) was accepted (201) and buffered; fusing it
    overflowed the fusion: the flush and every later upload of any agent answered 500, and the group never
    recovered. Now the upload is a 422 naming dp or cov, and the group goes on."""
    tok = tokens["alice"]
    gid = gclient.post("/api/v1/groups", headers=bearer(tok), json={"name": "t"}).get_json()["id"]
    for agent, east in (("a", 0.0), ("b", 5.0)):
        assert gclient.post(f"/api/v1/groups/{gid}/agents", headers=bearer(tok),
                            json={"agent": agent, "pos0_n": [east, 0.0, 0.0]}).status_code == 201
    cov = (np.eye(4) * 1e-4).tolist()

    def step(agent: str, foot: str, t_s: float, east_m: float = 0.7) -> dict[str, Any]:
        return {"type": "step", "t_s": t_s, "agent": agent, "foot": foot, "dp": [east_m, 0.0, 0.0], "dpsi": 0.0,
                "cov": cov}

    def upload(batch_id: str, agent: str, events: list[dict[str, Any]]) -> Any:
        return gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok),
                            json={"batch_id": batch_id, "agent": agent, "events": events})

    assert upload("u0", "a", [step("a", "left_foot", 1.0), step("a", "right_foot", 1.0)]).status_code == 201
    r = upload("u1", "a", [step("a", "left_foot", 2.0, east_m=1e200)])
    assert r.status_code == 422, r.get_json()
    assert r.get_json()["error"]["details"] == {"source": "events[0]", "field": "dp"}
    assert "at most 100 m" in r.get_json()["error"]["message"]
    # a variance of 1e308 (finite: it passed) broke the group the same way
    r = upload("u1", "a", [step("a", "left_foot", 2.0) | {"cov": (np.eye(4) * 1e308).tolist()}])
    assert r.status_code == 422, r.get_json()
    assert r.get_json()["error"]["details"] == {"source": "events[0]", "field": "cov"}
    r = upload("u1", "a", [step("a", "left_foot", 2.0) | {"dpsi": 1e308}])      # the same with a turn of 1e308 rad
    assert r.status_code == 422, r.get_json()
    assert r.get_json()["error"]["details"] == {"source": "events[0]", "field": "dpsi"}
    assert upload("u1", "a", [step("a", "left_foot", 2.0)]).status_code == 201     # nothing of the refused one kept
    assert upload("u2", "b", [step("b", "left_foot", 2.0)]).status_code == 201
    assert gclient.post(f"/api/v1/groups/{gid}/flush", headers=bearer(tok)).status_code == 200
    track = gclient.get(f"/api/v1/groups/{gid}/tracks", headers=bearer(tok)).get_json()["agents"]["a"]["left_foot"]
    assert [row[:2] for row in track] == [[0.0, 0.0], [1.0, 0.7], [2.0, 1.4]]


def test_an_upload_whose_fusion_fails_is_not_kept_and_its_retry_is_applied(gclient: FlaskClient,
                                                                          tokens: dict[str, str],
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A fault of ours while an upload is fused (not an input error): the upload was stored but never applied, and its
    retry was answered 'duplicate', so its events were lost for good. Now nothing of it is kept, and the retry is
    applied."""
    from pdr.fusion.group import Group
    tok = tokens["alice"]
    gid = gclient.post("/api/v1/groups", headers=bearer(tok), json={"name": "t"}).get_json()["id"]
    sc = scenario()
    join_all(gclient, tok, gid, sc)
    steps = [e for e in events_json(sc, "a0", 0, 5) if e["type"] == "step"]
    body = {"batch_id": "b1", "agent": "a0", "events": steps}
    process = Group.process

    def broken(self: Group) -> Any:
        raise RuntimeError("a fault while fusing")

    monkeypatch.setattr(Group, "process", broken)
    try:
        failed = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok), json=body).status_code
    except RuntimeError:            # the test app propagates the exception instead of answering 500
        failed = 500
    assert failed == 500
    monkeypatch.setattr(Group, "process", process)
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=bearer(tok), json=body)
    assert r.status_code == 201, r.get_json()
    assert r.get_json()["duplicate"] is False and r.get_json()["accepted"] == len(steps) > 0


def test_an_absurd_covariance_or_standard_deviation_is_a_422_naming_the_field(gclient: FlaskClient,
                                                                              tokens: dict[str, str]) -> None:
    """An agent joined with cov0 1e300 (finite, so it passed; steps' covariances were bounded, cov0 was not) was
    201, and after its first ranges the group's covariances went negative and its track 1e15 m away; a range
    variance or a measurement's sigma_m of 1e300 were taken too. Each is a 422 naming the field, nothing of it is
    kept, and the group goes on."""
    alice = bearer(tokens["alice"])
    for config, path in (({"kalman_range_variance_m2": 1e300}, "config.kalman_range_variance_m2"),
                         ({"ranging": {"sigma_m": 1e300}}, "config.ranging.sigma_m")):
        r = gclient.post("/api/v1/groups", headers=alice, json={"config": config})
        assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == path, r.get_json()
    assert gclient.get("/api/v1/groups", headers=alice).get_json() == {"groups": []}
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "t"}).get_json()["id"]
    for cov0, field in (((np.eye(4) * 1e300).tolist(), "cov0[0][0]"), ((np.eye(4) * -1e5).tolist(), "cov0[0][0]"),
                        ([[1, 0, 0, 0], [0, 1, 0, 2e4], [0, 0, 1, 0], [0, 2e4, 0, 1]], "cov0[1][3]")):
        r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                         json={"agent": "a", "pos0_n": [0, 0, 0], "cov0": cov0})
        assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == field, r.get_json()
        assert f"{field}:" in r.get_json()["error"]["message"]
    assert gclient.get(f"/api/v1/groups/{gid}", headers=alice).get_json()["agents"] == []
    for agent, east in (("a", 0.0), ("b", 5.0)):
        r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                         json={"agent": agent, "pos0_n": [east, 0, 0], "cov0": (np.eye(4) * 1e4).tolist()})
        assert r.status_code == 201, r.get_json()
    fix = {"type": "position_fix", "t_s": 1.0, "agent": "a", "pos_n": [0, 0], "gamma_m": 0.0, "sigma_m": 1e300}
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "u0", "agent": "a", "events": [fix]})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "events[0].sigma_m", r.get_json()
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "u0", "agent": "a", "events": [fix | {"sigma_m": 3.0}]})
    assert r.status_code == 201 and not r.get_json()["duplicate"], r.get_json()
    spec = gclient.get("/api/v1/openapi.json").get_json()["components"]["schemas"]["JoinGroup"]
    assert spec["properties"]["cov0"]["items"]["items"]["maximum"] == 1e4


def test_a_time_a_day_ahead_of_the_group_is_a_422_naming_it_and_the_group_goes_on(gclient: FlaskClient,
                                                                                   tokens: dict[str, str]) -> None:
    """A step event (or a joining agent) with t_s 1e300 was accepted and carried the group's newest time with it:
    every agent was then out of contact and every later range older than the fusion horizon, so one upload disabled
    the group. A time beyond any clock in seconds, or more than a day ahead of the group's newest event, is a 422
    naming it, nothing of it is kept, and the group goes on. Agents joined without a time (at 0 s) take events on
    the clients' own clock (Unix time here) from the first on."""
    alice = bearer(tokens["alice"])
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "t"}).get_json()["id"]
    for agent, east in (("a", 0.0), ("b", 5.0)):
        r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice, json={"agent": agent, "pos0_n": [east, 0, 0]})
        assert r.status_code == 201, r.get_json()
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice, json={"agent": "c", "pos0_n": [0, 0, 0],
                                                                          "t_s": 1e300})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "t_s", r.get_json()
    unix = 1.7e9
    step = {"type": "step", "t_s": 1e300, "agent": "a", "foot": "left_foot", "dp": [0.7, 0, 0], "dpsi": 0.0,
            "cov": (np.eye(4) * 1e-4).tolist()}
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "u0", "agent": "a", "events": [step]})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "events[0].t_s", r.get_json()
    rng = {"type": "range", "agent_a": "a", "agent_b": "b", "range_m": 5.0}
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "u0", "agent": "a", "events": [step | {"t_s": unix}, rng | {"t_s": unix}]})
    assert r.status_code == 201, r.get_json()
    for t_s in (unix + 2 * 86400, 1e10):               # two days on; a clock in another unit
        r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                         json={"batch_id": "u1", "agent": "a", "events": [step | {"t_s": t_s}]})
        assert r.status_code == 422, r.get_json()
        error = r.get_json()["error"]
        assert error["details"]["field"] == "t_s" and "days ahead" in error["message"], error
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice, json={"agent": "c", "pos0_n": [0, 0, 0],
                                                                          "t_s": unix + 2 * 86400})
    assert r.status_code == 422 and "days ahead" in r.get_json()["error"]["message"], r.get_json()
    assert [a["agent"] for a in gclient.get(f"/api/v1/groups/{gid}", headers=alice).get_json()["agents"]] == ["a", "b"]
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "u1", "agent": "a", "events": [step | {"t_s": unix + 1.0}]})
    assert r.status_code == 201, r.get_json()


def test_an_absurd_position_distance_or_pressure_is_a_422_naming_the_field_and_the_group_goes_on(
        gclient: FlaskClient, tokens: dict[str, str]) -> None:
    """An anchor or a position fix 1e300 m away was accepted (201) and the group's every later flush was a 500 (the
    fusion overflowed); a range, a height or a pressure of 1e300 was taken too. Each is a 422 naming the field
    (positions and distances within pdr.fusion.measurements.MAX_COORDINATE_M, pressures within the air's), nothing
    of it is kept, and the group's flush still works."""
    alice = bearer(tokens["alice"])
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "t"}).get_json()["id"]
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice, json={"agent": "a", "pos0_n": [1e300, 0, 0]})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "pos0_n[0]", r.get_json()
    for agent, east in (("a", 0.0), ("b", 5.0)):
        assert gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                            json={"agent": agent, "pos0_n": [east, 0, 0]}).status_code == 201
    model = {"gamma_m": 0.0, "sigma_m": 1.0}
    bad = [({"type": "range", "agent_a": "a", "agent_b": "b", "range_m": 1e300}, "events[0].range_m"),
           ({"type": "anchor_range", "agent": "a", "anchor_n": [1e300, 0, 0], "range_m": 5.0}, "events[0].anchor_n[0]"),
           ({"type": "position_fix", "agent": "a", "pos_n": [0, -1e300], **model}, "events[0].pos_n[1]"),
           ({"type": "height_difference", "agent_a": "a", "agent_b": "b", "dh_m": 1e300, **model}, "events[0].dh_m"),
           ({"type": "height_difference", "agent_a": "a", "pressure_hpa": -5.0, "reference_pressure_hpa": 1013.0,
             **model}, "events[0].pressure_hpa")]
    for i, (event, field) in enumerate(bad):
        r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                         json={"batch_id": f"u{i}", "agent": "a", "events": [event | {"t_s": 1.0}]})
        assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == field, (field, r.get_json())
        assert gclient.post(f"/api/v1/groups/{gid}/flush", headers=alice).status_code == 200
    fix = {"type": "position_fix", "t_s": 1.0, "agent": "a", "pos_n": [0.0, 0.0], **model}
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice,
                     json={"batch_id": "ok", "agent": "a", "events": [fix]})
    assert r.status_code == 201 and gclient.post(f"/api/v1/groups/{gid}/flush", headers=alice).status_code == 200


def test_an_upload_of_more_events_than_a_request_fuses_is_a_422_naming_the_limit(gclient: FlaskClient,
                                                                                  tokens: dict[str, str]) -> None:
    """An upload is fused within its request (about 0.6 ms an event): 100 000 events held a request thread for about
    a minute. More than groups.MAX_UPLOAD_EVENTS is a 422 naming ``events``, and the backlog goes in several
    uploads."""
    alice = bearer(tokens["alice"])
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "t"}).get_json()["id"]
    assert gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                        json={"agent": "a", "pos0_n": [0, 0, 0]}).status_code == 201
    fix = {"type": "position_fix", "agent": "a", "pos_n": [0, 0], "gamma_m": 0, "sigma_m": 1}
    events = [fix | {"t_s": i * 0.01} for i in range(groups.MAX_UPLOAD_EVENTS + 1)]
    r = gclient.post(f"/api/v1/groups/{gid}/uploads", headers=alice, json={"batch_id": "big", "agent": "a",
                                                                          "events": events})
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "events", r.get_json()
    assert gclient.get(f"/api/v1/groups/{gid}", headers=alice).get_json()["pending"] == 0
    spec = gclient.get("/api/v1/openapi.json").get_json()["components"]["schemas"]["GroupUpload"]
    assert spec["properties"]["events"]["maxItems"] == groups.MAX_UPLOAD_EVENTS


def test_a_session_whose_steps_a_group_refuses_still_joins_and_says_why(gclient: FlaskClient, tokens: dict[str, str],
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """An agent joined with a session takes the steps the session has already taken. If the group refuses them (a
    shoe clock days off the group's, without the right clock_offset_s), the join stands (201), as the processing
    pass after it does, and the session's warnings say why; before the day-ahead rule no step was refused there."""
    alice = bearer(tokens["alice"])
    gid = gclient.post("/api/v1/groups", headers=alice, json={"name": "t"}).get_json()["id"]
    sid = gclient.post("/api/v1/sessions", headers=alice, json={"session_id": "walk"}).get_json()["id"]

    def refusing(store: Any, session_id: str) -> dict[str, int]:
        raise InputError("time 9e+05 s is 10.4 days ahead of the group's newest (0 s)", field="t_s")

    monkeypatch.setattr(groups, "feed_groups", refusing)
    r = gclient.post(f"/api/v1/groups/{gid}/agents", headers=alice,
                     json={"agent": "x", "pos0_n": [0, 0, 0], "session_id": sid})
    assert r.status_code == 201, r.get_json()
    warnings = gclient.get(f"/api/v1/sessions/{sid}", headers=alice).get_json()["warnings"]
    assert any(w.startswith("group feed:") and "days ahead" in w for w in warnings), warnings
