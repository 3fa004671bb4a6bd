"""Sites in the service: upload, list, get, delete (owner-scoped), bad sites refused naming what is wrong, and a
session naming a site and a start map-matched online as ``pdr track --site S --start E,N --smoother off``."""

from __future__ import annotations

import copy
import json
import math
from typing import Any

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient

from pdr.mapmatch.stage import MapMatchStage
from pdr.phone.configure import pipeline_config, placement_group
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, track_rows
from pdr.recording import Recording
from pdr.sim import parse_scenario, simulate
from pdr.site.plan import SitePlan
from tests.server.conftest import bearer
from tests.server.helpers import multipart, one_second_batches

T0_NS = 1_717_000_000_000_000_000


def _rect(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]


#: A hall 60 m x 20 m with a shop (a hole) on two floors 3.5 m apart (metres, east/north).
HALL: dict[str, Any] = {"name": "hall", "floor_height_m": 3.5, "landmarks": [],
        "floors": [{"floor": f, "altitude_m": 3.5 * f,
                    "walkable": {"type": "Polygon", "coordinates": [_rect(0, 0, 60, 20), _rect(10, 12, 20, 18)]}}
                   for f in (0, 1)]}
ONE_FLOOR = {**HALL, "name": "ground", "floors": HALL["floors"][:1]}


def _upload(client: FlaskClient, token: str, site: dict) -> dict:
    resp = client.post("/api/v1/sites", json=site, headers=bearer(token))
    assert resp.status_code == 201, resp.get_json()
    return resp.get_json()


def test_sites_are_uploaded_listed_read_and_deleted_by_their_owner(client: FlaskClient, tokens: dict) -> None:
    alice, bob = tokens["alice"], tokens["bob"]
    made = _upload(client, alice, HALL)
    assert made["name"] == "hall" and made["landmarks"] == 0 and made["floor_height_m"] == 3.5
    assert [(f["floor"], f["altitude_m"], f["polygons"], f["holes"]) for f in made["floors"]] == [
        (0, 0.0, 1, 1), (1, 3.5, 1, 1)]
    assert made["floors"][0]["bounds_m"] == [0.0, 0.0, 60.0, 20.0]
    body, ctype = multipart({"file": (json.dumps(ONE_FLOOR).encode(), "ground.json"), "name": "ground floor"})
    resp = client.post("/api/v1/sites", data=body, content_type=ctype, headers=bearer(alice))
    assert resp.status_code == 201, resp.get_json()
    second = resp.get_json()
    assert second["name"] == "ground floor" and len(second["floors"]) == 1

    listed = client.get("/api/v1/sites", headers=bearer(alice)).get_json()["sites"]
    assert [s["id"] for s in listed] == [made["id"], second["id"]]
    detail = client.get(f"/api/v1/sites/{made['id']}", headers=bearer(alice)).get_json()
    assert detail["site"] == HALL
    # The plan in the site's metric frame reads back as the same floors.
    plan = SitePlan.from_dict(detail["plan"])
    assert sorted(plan.floors) == [0, 1] and plan.altitude_m(1) == 3.5
    assert plan.floors[0].contains(np.array([[5.0, 5.0], [15.0, 15.0]])).tolist() == [True, False]

    # Another user sees none of them, and cannot delete them.
    assert client.get("/api/v1/sites", headers=bearer(bob)).get_json()["sites"] == []
    assert client.get(f"/api/v1/sites/{made['id']}", headers=bearer(bob)).status_code == 404
    assert client.delete(f"/api/v1/sites/{made['id']}", headers=bearer(bob)).status_code == 404
    assert client.get("/api/v1/sites").status_code == 401
    assert client.delete(f"/api/v1/sites/{made['id']}", headers=bearer(alice)).status_code == 204
    assert client.get(f"/api/v1/sites/{made['id']}", headers=bearer(alice)).status_code == 404
    assert [s["id"] for s in client.get("/api/v1/sites", headers=bearer(alice)).get_json()["sites"]] == [second["id"]]


def _bad(site_change) -> dict:
    site = copy.deepcopy(HALL)
    site_change(site)
    return site


#: A lift on floor 0 of the hall, as a site's landmark.
LIFT = {"id": "lift", "type": "elevator", "east_m": 5.0, "north_m": 5.0, "floor": 0, "heading_deg": [0, 360],
        "radius_m": 5.0}


@pytest.mark.parametrize(("landmark", "field"), [
    ({"floor": "x"}, "floor"), ({"floor": math.nan}, "floor"), ({"floor": None}, "floor"),   # were 500s
    ({"east_m": math.nan}, "east_m"), ({"north_m": math.inf}, "north_m"),                     # were stored
    ({"heading_deg": [math.nan, 90]}, "heading_deg"), ({"radius_m": -1.0}, "radius_m"), ({"radius_m": 0}, "radius_m"),
])
def test_a_landmark_whose_number_is_no_number_is_refused_naming_it_on_both_routes(client: FlaskClient, tokens: dict,
                                                                                   landmark, field) -> None:
    """A landmark's floor that is no number was a 500 (ValueError where the floor plans check the landmarks' floors);
    an east_m or north_m of NaN or Infinity, a NaN heading and a radius of 0 or less were stored, and a session on
    the site got its position fixed at NaN. Each is a 422 naming the landmark and the field now, as a site of POST
    /api/v1/sites and as a session's inline processing.site."""
    auth = bearer(tokens["alice"])
    site = {**HALL, "landmarks": [LIFT | landmark]}
    for resp in (client.post("/api/v1/sites", json=site, headers=auth),
                 client.post("/api/v1/sessions", json={"session_id": "s", "processing": {"site": site}}, headers=auth)):
        error = resp.get_json()["error"]
        assert resp.status_code == 422, error
        assert "landmark 0" in error["message"] and error["details"]["field"] == field, error
    assert client.get("/api/v1/sites", headers=auth).get_json()["sites"] == []
    assert client.get("/api/v1/sessions", headers=auth).get_json()["sessions"] == []
    resp = client.post("/api/v1/sites", json={**HALL, "landmarks": 5}, headers=auth)
    assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "landmarks"
    assert client.post("/api/v1/sites", json={**HALL, "landmarks": [LIFT]}, headers=auth).status_code == 201


@pytest.mark.parametrize(("change", "where", "field"), [
    (lambda s: s["floors"][1]["walkable"]["coordinates"].__setitem__(0, [[0, 0], [10, 10], [10, 0], [0, 10],
                                                                         [0, 0]]),
     "floors[1] walkable polygon 0 ring 0", "coordinates"),
    (lambda s: s["floors"][0]["walkable"].__setitem__("type", "LineString"), "floors[0] walkable", "type"),
    (lambda s: s["floors"][0].__setitem__("frame", "lonlat"), "floors[0]", "origin"),
    (lambda s: s["floors"][0].pop("walkable"), "floors[0]", "walkable"),
    (lambda s: s["floors"][1].__setitem__("floor", 0), "floors[1]", "floor"),
    (lambda s: s.__setitem__("floors", []), "site", "floors"),
    (lambda s: s.__setitem__("landmarks", [{"id": "lift", "type": "elevator", "east_m": 1, "north_m": 1,
                                            "floor": 7, "heading_deg": [0, 360]}]), "landmark 0", "floor"),
    (lambda s: s["floors"][0]["walkable"]["coordinates"][0].pop(), "floors[0] walkable polygon 0 ring 0",
     "coordinates"),
    # Accepted before, then every batch of a session on the site failed (a TypeError in the wall index).
    (lambda s: s["floors"][0]["walkable"]["coordinates"].__setitem__(0, [[0, 0], [1e308, 0], [1e308, 1e308],
                                                                         [0, 0]]),
     "floors[0] walkable polygon 0 ring 0", "coordinates"),
    (lambda s: s["floors"][0]["walkable"]["coordinates"].__setitem__(0, [[0, 0], [5e4, 0], [5e4, 5e4], [0, 0]]),
     "floors[0]", "walkable"),
    (lambda s: s["floors"][0].__setitem__("floor", 10 ** 30), "floors[0]", "floor"),
])
def test_a_bad_site_is_refused_naming_the_floor_polygon_and_field(client: FlaskClient, tokens: dict, change, where,
                                                                   field) -> None:
    resp = client.post("/api/v1/sites", json=_bad(change), headers=bearer(tokens["alice"]))
    error = resp.get_json()["error"]
    assert resp.status_code == 422, error
    assert where in error["message"] and error["details"]["field"] == field, error
    assert client.get("/api/v1/sites", headers=bearer(tokens["alice"])).get_json()["sites"] == []


def test_a_site_upload_that_is_not_a_site_gets_a_4xx(client: FlaskClient, tokens: dict) -> None:
    auth = bearer(tokens["alice"])
    body, ctype = multipart({"file": (b"{not json", "site.json")})
    resp = client.post("/api/v1/sites", data=body, content_type=ctype, headers=auth)
    assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "file"
    body, ctype = multipart({"name": "x"})
    assert client.post("/api/v1/sites", data=body, content_type=ctype, headers=auth).status_code == 400
    assert client.post("/api/v1/sites", data="[1]", content_type="text/plain", headers=auth).status_code == 415
    resp = client.post("/api/v1/sites", json=[1, 2], headers=auth)
    assert resp.status_code == 422 and "site" in resp.get_json()["error"]["message"]


@pytest.mark.parametrize("name", [{"a": 1}, ["hall"], 5, True, None])
def test_a_site_whose_name_is_not_text_is_refused_naming_it_on_both_routes(client: FlaskClient, tokens: dict,
                                                                            name: Any) -> None:
    """A site whose "name" was an object, a list or a number was stored under its Python text ("{'a': 1}",
    "['hall']", "5"): a 422 naming the field on the JSON and the multipart route. So is a landmark's id that is neither
    text nor a whole number."""
    auth = bearer(tokens["alice"])
    resp = client.post("/api/v1/sites", json={**ONE_FLOOR, "name": name}, headers=auth)
    assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "name", resp.get_data()[:300]
    body, ctype = multipart({"file": (json.dumps({**ONE_FLOOR, "name": name}).encode(), "ground.json")})
    resp = client.post("/api/v1/sites", data=body, content_type=ctype, headers=auth)
    assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "name", resp.get_data()[:300]
    assert client.get("/api/v1/sites", headers=auth).get_json()["sites"] == []
    resp = client.post("/api/v1/sites", json={**ONE_FLOOR, "landmarks": [LIFT | {"id": name}]}, headers=auth)
    if isinstance(name, int) and not isinstance(name, bool):   # a landmark's id may be a whole number
        assert resp.status_code == 201, resp.get_data()[:300]
    else:
        assert resp.status_code == 422, resp.get_data()[:300]
        assert resp.get_json()["error"]["details"]["field"] == "id"
        assert "landmark 0" in resp.get_json()["error"]["message"]


@pytest.mark.parametrize(("fields", "field"), [({"name": "hall\x00"}, "name"), ({}, "file")])
def test_a_site_file_whose_name_holds_a_nul_character_is_refused_naming_the_field(client: FlaskClient, tokens: dict,
                                                                                  fields: dict, field: str) -> None:
    """A multipart site upload named (its 'name' field, else its file name) 'hall\\x00' was stored so in SQLite and a
    500 in PostgreSQL, which refuses a NUL in text (tests/server/test_postgres.py): a 422 naming the field."""
    auth = bearer(tokens["alice"])
    body, ctype = multipart({"file": (json.dumps(ONE_FLOOR).encode(), "ground\x00.json"), **fields})
    resp = client.post("/api/v1/sites", data=body, content_type=ctype, headers=auth)
    assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == field, resp.get_data()[:300]
    assert "NUL" in resp.get_json()["error"]["message"]
    assert client.get("/api/v1/sites", headers=auth).get_json()["sites"] == []


@pytest.mark.parametrize("site", [{"floors": "x"}, {"floors": {"floor": 0}}, {"landmarks": [], "floors": "x"},
                                  {"floors": []}, {"name": "hall", "floors": [], "landmarks": []}])
def test_an_inline_site_with_bad_floors_is_refused_as_post_sites_refuses_it(client: FlaskClient, tokens: dict,
                                                                            site: dict) -> None:
    """A session's inline processing.site gets the message and field POST /api/v1/sites gives the same body (not
    a complaint about a 'landmarks' list). An empty floors list was accepted inline (a site of no floor and no
    landmark, stored and used) while /sites refused it."""
    auth = bearer(tokens["alice"])
    uploaded = client.post("/api/v1/sites", json=site, headers=auth)
    assert uploaded.status_code == 422
    expected = uploaded.get_json()["error"]
    assert expected["details"]["field"] == "floors"
    sid = client.post("/api/v1/sessions", json={"session_id": "ok"}, headers=auth).get_json()["id"]
    for resp in (client.post("/api/v1/sessions", json={"session_id": "s", "processing": {"site": site}}, headers=auth),
                 client.put(f"/api/v1/sessions/{sid}/processing", json={"site": site}, headers=auth)):
        error = resp.get_json()["error"]
        assert resp.status_code == 422, error
        assert error["details"]["field"] == "floors", error
        assert error["message"] == expected["message"].replace("site, ", "processing.site, ", 1), error


def test_session_options_naming_a_site_are_checked_before_anything_is_stored(client: FlaskClient,
                                                                             tokens: dict) -> None:
    alice, bob = tokens["alice"], tokens["bob"]
    hall = _upload(client, alice, HALL)["id"]
    ground = _upload(client, alice, ONE_FLOOR)["id"]
    bobs = _upload(client, bob, HALL)["id"]
    for processing, field, text in (
            ({"site_id": "nope"}, "processing.site_id", "no site 'nope'"),
            ({"site_id": bobs}, "processing.site_id", "no site"),                       # not alice's
            ({"site_id": hall, "start": [5, 5]}, "processing.start", "has floors [0, 1]"),
            ({"site_id": hall, "start": [15, 15, 0]}, "processing.start", "outside floor 0's walkable area"),
            ({"site_id": hall, "start": [5, 5, 4]}, "processing.start", "no floor plan for floor 4"),
            ({"site_id": hall, "start": [5, 5, 0.5]}, "processing.start", "integer floor"),
            ({"start": [5, 5]}, "processing.start", "needs 'site_id'"),
            ({"site_id": hall, "site": {"landmarks": []}}, "processing.site_id", "not both")):
        resp = client.post("/api/v1/sessions", json={"session_id": "s", "processing": processing},
                           headers=bearer(alice))
        error = resp.get_json()["error"]
        assert resp.status_code == 422 and error["details"]["field"] == field and text in error["message"], error
    assert client.get("/api/v1/sessions", headers=bearer(alice)).get_json()["sessions"] == []
    resp = client.post("/api/v1/sessions", json={"session_id": "s", "processing": {"site_id": ground,
                                                                                  "start": [5, 5]}},
                       headers=bearer(alice))
    assert resp.status_code == 201 and resp.get_json()["processing"] == {"site_id": ground, "start": [5.0, 5.0]}
    sid = resp.get_json()["id"]
    plan = client.get(f"/api/v1/sessions/{sid}/site", headers=bearer(alice)).get_json()
    assert plan["site_id"] == ground and plan["start"] == {"east_m": 5.0, "north_m": 5.0, "floor": None}
    assert [f["floor"] for f in plan["floors"]] == [0]
    assert client.get(f"/api/v1/sessions/{sid}/site", headers=bearer(bob)).status_code == 404
    # Replacing the options checks them the same way; clearing them drops the session's site.
    resp = client.put(f"/api/v1/sessions/{sid}/processing", json={"site_id": hall, "start": [15, 15, 1]},
                      headers=bearer(alice))
    assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "processing.start"
    assert client.put(f"/api/v1/sessions/{sid}/processing", json={}, headers=bearer(alice)).status_code == 202
    assert client.get(f"/api/v1/sessions/{sid}/site", headers=bearer(alice)).status_code == 404


def _walk() -> Recording:
    """A hand-held walk east along the hall from (5, 6) m with a left turn and a stop."""
    return simulate(parse_scenario({"placement": "hand", "start_time_ns": T0_NS,
                                    "start": {"position_m": [5.0, 6.0, 0.0], "heading_deg": 90.0},
                                    "segments": [{"type": "stand", "duration_s": 3},
                                                 {"type": "walk", "duration_s": 14},
                                                 {"type": "turn", "angle_deg": 90, "duration_s": 2},
                                                 {"type": "walk", "duration_s": 4}]}), seed=4)


def _session(app: Flask, client: FlaskClient, token: str, processing: dict, rec: Recording, key: str) -> str:
    resp = client.post("/api/v1/sessions", json={"session_id": key, "placement": "hand", "processing": processing},
                       headers=bearer(token))
    assert resp.status_code == 201, resp.get_json()
    sid = resp.get_json()["id"]
    for batch in one_second_batches(rec, key):
        r = client.post(f"/api/v1/sessions/{sid}/batches", json=batch, headers=bearer(token))
        assert r.status_code in (200, 201), r.get_json()
    assert app.extensions["pdr"].worker.wait_idle(240)
    return str(sid)


@pytest.mark.timeout(300)
def test_a_session_naming_a_site_and_start_is_map_matched_online(real_app: Flask, token: str) -> None:
    client = real_app.test_client()
    site_id = _upload(client, token, HALL)["id"]
    rec = _walk()
    sid = _session(real_app, client, token, {"site_id": site_id, "start": [5.0, 6.0, 0]}, rec, "matched")
    points = client.get(f"/api/v1/sessions/{sid}/track?device=phone", headers=bearer(token)).get_json()["points"]
    # As `pdr track --site hall.json --start 5,6,0 --smoother off`: the pipeline with the site's floors and the
    # map-matching stage, run offline over the whole recording.
    plan = SitePlan.from_dict(HALL)
    cfg = pipeline_config(placement_group("hand"))
    want = track_rows(PdrPipeline(cfg, Site.from_dict(HALL), stages=[MapMatchStage(plan, (5.0, 6.0), 0)]).run(rec))
    assert len(points) == len(want) > 15
    for key in ("east_m", "north_m", "floor", "heading_deg", "step_length_m"):
        np.testing.assert_allclose([p[key] for p in points], [r[key] for r in want], atol=1e-6, err_msg=key)
    xy = np.array([[p["east_m"], p["north_m"]] for p in points])
    assert plan.floors[0].contains(xy).all()                     # the site's frame, inside the hall
    assert np.linalg.norm(xy[0] - [5.0, 6.0]) < 2.0 and xy[:, 0].max() > 20.0
    session = client.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
    assert session["processing"] == {"site_id": site_id, "start": [5.0, 6.0, 0]}
    # The smoothed track would re-integrate headings off the plan: it is the matched track, with the reason.
    smoothed = client.get(f"/api/v1/sessions/{sid}/track?device=phone&heading=smoothed", headers=bearer(token))
    assert smoothed.get_json()["points"] == points and smoothed.get_json()["smoothed_devices"] == []
    assert "map-matched online" in smoothed.get_json()["heading_notes"][0]
    # The session keeps its copy of the site: deleting the site changes nothing, even on a rebuild.
    assert client.delete(f"/api/v1/sites/{site_id}", headers=bearer(token)).status_code == 204
    assert client.post(f"/api/v1/sessions/{sid}/reprocess", headers=bearer(token)).status_code == 202
    assert real_app.extensions["pdr"].worker.wait_idle(240)
    again = client.get(f"/api/v1/sessions/{sid}/track?device=phone", headers=bearer(token)).get_json()["points"]
    assert again == points
    assert client.get(f"/api/v1/sessions/{sid}/site", headers=bearer(token)).get_json()["site_id"] == site_id


@pytest.mark.timeout(400)
def test_the_real_service_process_map_matches_a_session_on_an_uploaded_site(tmp_path) -> None:
    """`pdr serve` as deployed: upload the site, name it with a start, stream the walk, read the matched track."""
    import time

    from server.client import Client, add_user, running_server

    rec = _walk()
    with running_server(tmp_path) as (url, env, _):
        c = Client(url, add_user(env, "walker"), timeout_s=120.0)
        bad = c.request("POST", "/api/v1/sites", _bad(lambda s: s["floors"][0].pop("walkable")))
        assert bad.status == 422 and bad.json()["error"]["details"]["field"] == "walkable"
        site_id = c.request("POST", "/api/v1/sites", HALL).json()["id"]
        made = c.request("POST", "/api/v1/sessions", {"session_id": "live", "placement": "hand", "processing": {
            "site_id": site_id, "start": [5.0, 6.0, 0]}})
        assert made.status == 201, made.body
        sid = made.json()["id"]
        for batch in one_second_batches(rec, "live"):
            assert c.request("POST", f"/api/v1/sessions/{sid}/batches", batch).status == 201
        deadline = time.monotonic() + 300
        while True:
            detail = c.request("GET", f"/api/v1/sessions/{sid}").json()
            if detail["status"] == "done" and not detail["batches"].get("pending"):
                break
            assert time.monotonic() < deadline, detail["batches"]
            time.sleep(0.5)
        points = c.request("GET", f"/api/v1/sessions/{sid}/track?device=phone").json()["points"]
        floors = c.request("GET", f"/api/v1/sessions/{sid}/site").json()
        c.close()
    plan = SitePlan.from_dict(HALL)
    cfg = pipeline_config(placement_group("hand"))
    want = track_rows(PdrPipeline(cfg, Site.from_dict(HALL), stages=[MapMatchStage(plan, (5.0, 6.0), 0)]).run(rec))
    assert len(points) == len(want) > 15
    np.testing.assert_allclose([[p["east_m"], p["north_m"]] for p in points],
                               [[r["east_m"], r["north_m"]] for r in want], atol=1e-6)
    assert [f["floor"] for f in floors["floors"]] == [0, 1] and floors["start"]["floor"] == 0
