"""Every error status has a JSON body ``{"error": {status, code, message, details}}`` and no traceback."""

from __future__ import annotations

import io

import numpy as np
import pytest
from flask import Flask
from flask.testing import FlaskClient

from tests.server.conftest import bearer, make_app
from tests.server.helpers import phone_batch


def assert_error(resp, status: int, match: str = "") -> dict:  # noqa: ANN001
    assert resp.status_code == status, resp.get_data(as_text=True)
    body = resp.get_json()
    err = body["error"]
    assert set(err) == {"status", "code", "message", "details"}
    assert err["status"] == status
    assert match.lower() in err["message"].lower()
    assert "Traceback" not in resp.get_data(as_text=True)
    return err


def _session(client: FlaskClient, token: str) -> str:
    resp = client.post("/api/v1/sessions", json={"session_id": "walk-1"}, headers=bearer(token))
    assert resp.status_code == 201
    return resp.get_json()["id"]


def test_400_malformed_json(client, tokens):
    resp = client.post("/api/v1/sessions", data="{not json", content_type="application/json",
                       headers=bearer(tokens["alice"]))
    assert_error(resp, 400, "not valid JSON")


def test_401_missing_and_wrong_token(client, tokens):
    assert_error(client.get("/api/v1/sessions"), 401, "authentication required")
    assert_error(client.get("/api/v1/sessions", headers=bearer("pdr_wrong")), 401, "invalid")


def test_403_query_token_outside_ingest(client, tokens):
    assert_error(client.get(f"/api/v1/sessions?token={tokens['alice']}"), 403, "ingest endpoints only")


def test_404_unknown_route_and_other_users_session(client, tokens):
    assert_error(client.get("/api/v1/nothing-here"), 404)
    sid = _session(client, tokens["alice"])
    assert_error(client.get(f"/api/v1/sessions/{sid}", headers=bearer(tokens["bob"])), 404, "no session")
    assert_error(client.get(f"/api/v1/sessions/{sid}/track", headers=bearer(tokens["bob"])), 404)
    resp = client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 0.0), headers=bearer(tokens["bob"]))
    assert_error(resp, 404)
    assert client.get("/api/v1/sessions", headers=bearer(tokens["bob"])).get_json()["sessions"] == []


def test_405_wrong_method(client, tokens):
    resp = client.delete("/api/v1/sessions", headers=bearer(tokens["alice"]))
    assert_error(resp, 405)
    assert "GET" in resp.headers["Allow"]


def test_409_same_batch_id_different_content(client, tokens):
    sid = _session(client, tokens["alice"])
    h = bearer(tokens["alice"])
    assert client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 0.0), headers=h).status_code == 201
    again = client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 0.0), headers=h)
    assert again.status_code == 200 and again.get_json()["duplicate"] is True
    assert_error(client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 5.0), headers=h), 409,
                 "different content")


def test_413_body_too_large(tmp_path, tokens):  # noqa: ARG001
    app = make_app(tmp_path / "small", max_upload_mb=0.002, max_batch_mb=0.001)
    try:
        resp = app.test_client().post("/api/v1/sessions", data=b"x" * 5000, content_type="application/json")
        body = assert_error(resp, 413, "too large: the limit of this route is 1048 bytes")
        assert body["details"]["limit_bytes"] == 1048
        resp = app.test_client().post("/api/v1/sessions", data=b"x" * 5000, content_type="multipart/form-data")
        assert_error(resp, 413, "too large: the limit of this route is 2097 bytes")
    finally:
        app.extensions["pdr"].worker.stop()


def test_415_not_json(client, tokens):
    resp = client.post("/api/v1/sessions", data="session_id=x", content_type="text/plain",
                       headers=bearer(tokens["alice"]))
    assert_error(resp, 415, "application/json")


@pytest.mark.parametrize(("raw", "got"), [(b"null", "null"), (b"[1, 2]", "an array"), (b"5", "a number"),
                                          (b'"walk"', "a string"), (b"true", "a boolean")])
def test_422_a_json_body_that_is_not_an_object_says_an_object_was_expected(client, tokens, raw, got):
    """Every route reading a JSON body: ``null`` was 'request body is not valid JSON' (400; it is valid JSON), an
    array a native batch's 'needs a non-empty string batch_id', Sensor Logger's 'None is not of type'."""
    h = bearer(tokens["alice"])
    sid = _session(client, tokens["alice"])
    gid = client.post("/api/v1/groups", json={"name": "g"}, headers=h).get_json()["id"]
    routes = [("POST", "/api/v1/sessions", "session"), ("POST", f"/api/v1/sessions/{sid}/devices", "device"),
              ("POST", f"/api/v1/sessions/{sid}/batches", "native batch"),
              ("PUT", f"/api/v1/sessions/{sid}/processing", "processing"),
              ("POST", f"/api/v1/sessions/{sid}/steps", "step summaries"), ("POST", "/api/v1/sites", "site"),
              ("POST", "/api/v1/groups", "group"), ("POST", f"/api/v1/groups/{gid}/agents", "agent"),
              ("POST", f"/api/v1/groups/{gid}/uploads", "upload"), ("POST", "/api/v1/classify",
                                                                     "classification request")]
    for method, route, what in routes:
        resp = client.open(route, method=method, data=raw, content_type="application/json", headers=h)
        err = assert_error(resp, 422, f"invalid {what}: the request body must be a JSON object {{...}}, got {got}")
        assert err["details"]["expected"] == "object", route
    resp = client.post(f"/api/v1/ingest/sensor-logger?token={tokens['alice']}", data=raw,
                       content_type="application/json")
    assert resp.status_code == 499
    assert f"Sensor Logger message: the request body must be a JSON object {{...}}, got {got}" in resp.get_data(
        as_text=True)
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["batches"] == {}


@pytest.mark.parametrize(
    ("body", "match", "field", "path"),
    [({"session_id": "bad id with spaces"}, "session_id", "session_id", "session_id"),
     ({"placement": "shoe"}, "placement", "placement", "placement"),
     ({"unexpected": 1}, "unexpected", "unexpected", ""),
     ({"processing": {"start": "x"}}, "processing.start", "processing.start", "processing.start"),
     ({"origin": {"lat_deg": 1}}, "lon_deg", "origin.lon_deg", "origin")],
)
def test_422_schema_violations_name_the_field(client, tokens, body, match, field, path):
    """A schema error names the field in details.field, as every other error does (details.path kept)."""
    err = assert_error(client.post("/api/v1/sessions", json=body, headers=bearer(tokens["alice"])), 422, match)
    assert err["details"]["field"] == field
    assert err["details"]["path"] == path


def test_422_schema_violation_of_processing_options_names_the_field(client, tokens):
    sid = _session(client, tokens["alice"])
    resp = client.put(f"/api/v1/sessions/{sid}/processing", json={"foot": {"zaru": 1}},
                      headers=bearer(tokens["alice"]))
    assert assert_error(resp, 422, "foot.zaru")["details"]["field"] == "foot.zaru"


def test_422_invalid_batch_names_stream_and_sample(client, tokens):
    sid = _session(client, tokens["alice"])
    batch = phone_batch("b1", 0.0)
    t = batch["streams"]["acc"]["t_ns"]
    t[3:6] = [t[2] - 3, t[2] - 2, t[2] - 1]  # a broken clock (a repeated or lone backward sample is dropped)
    resp = client.post(f"/api/v1/sessions/{sid}/batches", json=batch, headers=bearer(tokens["alice"]))
    assert_error(resp, 422, "field 'streams.acc.t_ns[3]': time goes backwards in 3 of 50")
    assert client.get(f"/api/v1/sessions/{sid}", headers=bearer(tokens["alice"])).get_json()["batch_list"] == []


def test_429_after_repeated_failed_authentication(tmp_path):
    app = make_app(tmp_path / "rl", auth_failures_per_minute=3)
    try:
        c = app.test_client()
        for _ in range(3):
            assert c.get("/api/v1/sessions", headers=bearer("pdr_guess")).status_code == 401
        assert_error(c.get("/api/v1/sessions", headers=bearer("pdr_guess")), 429, "too many")
    finally:
        app.extensions["pdr"].worker.stop()


def test_500_is_json_without_traceback(app: Flask):
    @app.get("/api/v1/_boom")
    def boom():  # noqa: ANN202
        raise RuntimeError("secret internals")

    resp = app.test_client().get("/api/v1/_boom")
    err = assert_error(resp, 500, "internal server error")
    assert "secret internals" not in err["message"]


def test_openapi_documents_every_api_route(app: Flask, client):
    doc = client.get("/api/v1/openapi.json").get_json()
    assert doc["openapi"].startswith("3.1")
    documented = {(path, method) for path, ops in doc["paths"].items() for method in ops}
    for rule in app.url_map.iter_rules():
        if not rule.rule.startswith("/api/v1"):
            continue
        path = rule.rule.replace("<", "{").replace(">", "}")
        assert rule.methods is not None
        for method in rule.methods - {"HEAD", "OPTIONS"}:
            assert (path, method.lower()) in documented, f"{method} {path} missing from the OpenAPI document"


def test_openapi_states_the_devices_and_the_largest_after_the_results_take(client, tokens):
    """The document gave ?device= as any string and ?after= without its maximum; both are now stated, and exactly
    what the service takes: every listed device and the maximum are answered 200, a device not listed and one past
    the maximum 400 naming the parameter."""
    sid = _session(client, tokens["alice"])
    h = bearer(tokens["alice"])
    paths = client.get("/api/v1/openapi.json").get_json()["paths"]

    def parameters(route: str) -> dict:
        return {p["name"]: p for p in paths[f"/api/v1/sessions/{{session_id}}/{route}"]["get"]["parameters"]}

    for route in ("track", "track/columns"):
        devices = parameters(route)["device"]["schema"]["enum"]
        assert {"primary", "phone", "left_foot", "right_foot", "fused"} <= set(devices)
        for device in devices:
            assert client.get(f"/api/v1/sessions/{sid}/{route}?device={device}", headers=h).status_code == 200
        resp = client.get(f"/api/v1/sessions/{sid}/{route}?device=toe", headers=h)
        assert assert_error(resp, 400, "unknown device")["details"]["field"] == "device"
    for route in ("track", "track/columns", "steps", "modes", "landmarks", "floors"):
        after = parameters(route)["after"]["schema"]
        assert after["minimum"] == 0 and isinstance(after["maximum"], int)
        for value, status in ((after["minimum"], 200), (after["maximum"], 200), (after["maximum"] + 1, 400),
                              (after["minimum"] - 1, 400)):
            resp = client.get(f"/api/v1/sessions/{sid}/{route}?after={value}", headers=h)
            assert resp.status_code == status, (route, value, resp.get_json())


@pytest.mark.parametrize(("query", "field"), [("format=xml", "format"), ("heading=bogus", "heading")])
def test_400_unknown_track_format_or_heading_names_the_parameter(client, tokens, query, field):
    sid = _session(client, tokens["alice"])
    resp = client.get(f"/api/v1/sessions/{sid}/track?{query}", headers=bearer(tokens["alice"]))
    assert assert_error(resp, 400, f"unknown {field}")["details"]["field"] == field


@pytest.mark.parametrize("route", ["track", "track/columns"])
def test_400_unknown_track_device_names_the_parameter(client, tokens, route):
    sid = _session(client, tokens["alice"])
    h = bearer(tokens["alice"])
    resp = client.get(f"/api/v1/sessions/{sid}/{route}?device=bogus", headers=h)
    assert assert_error(resp, 400, "unknown device 'bogus'")["details"]["field"] == "device"
    for known in ("phone", "left_foot", "fused", "primary", ""):   # a known role without rows is no error
        assert client.get(f"/api/v1/sessions/{sid}/{route}?device={known}", headers=h).status_code == 200


@pytest.mark.parametrize("route", ["sessions", "sites", "groups", "reports", "models"])
@pytest.mark.parametrize("query", ["limit=abc", "limit=5", "offset=-1"])
def test_400_a_list_refuses_query_parameters_it_does_not_take(client, tokens, route, query):
    """The lists take no paging or filter: a parameter is refused naming it, not ignored (all items answered)."""
    h = bearer(tokens["alice"])
    resp = client.get(f"/api/v1/{route}?{query}", headers=h)
    assert assert_error(resp, 400, "unknown query parameter")["details"]["field"] == query.split("=")[0]
    assert client.get(f"/api/v1/{route}", headers=h).status_code == 200


@pytest.mark.parametrize("route", ["modes", "landmarks", "floors", "track", "steps"])
def test_400_an_after_beyond_any_seq_names_the_parameter_not_500(client, tokens, route):
    sid = _session(client, tokens["alice"])
    h = bearer(tokens["alice"])
    for bad in ("99999999999999999999999", str(2**31)):
        resp = client.get(f"/api/v1/sessions/{sid}/{route}?after={bad}", headers=h)
        assert assert_error(resp, 400, "'after' must be at most")["details"]["field"] == "after"
    assert client.get(f"/api/v1/sessions/{sid}/{route}?after={2**31 - 1}", headers=h).status_code == 200


@pytest.mark.parametrize(("route", "query"), [("track", "since_s=10"), ("track", "sinse=10"), ("track", "limit=5"),
                                              ("track/columns", "since_s=10"), ("steps", "device=phone"),
                                              ("modes", "heading=smoothed"), ("landmarks", "from=3"),
                                              ("floors", "since_s=10")])
def test_400_a_result_refuses_a_query_parameter_it_does_not_take(client, tokens, route, query):
    """A misspelt or foreign parameter (the groups' since_s) was ignored: the poller got every row, as if it had
    asked for them all. Now it is refused naming it and the parameters the route takes."""
    sid = _session(client, tokens["alice"])
    h = bearer(tokens["alice"])
    name = query.split("=")[0]
    error = assert_error(client.get(f"/api/v1/sessions/{sid}/{route}?{query}", headers=h), 400,
                         f"unknown query parameter '{name}': this route takes ")
    assert error["details"]["field"] == name and "since" in error["message"]
    assert client.get(f"/api/v1/sessions/{sid}/{route}?since=10&after=0", headers=h).status_code == 200


def test_a_group_track_refuses_a_query_parameter_it_does_not_take(client, tokens):
    h = bearer(tokens["alice"])
    gid = client.post("/api/v1/groups", headers=h, json={"name": "t"}).get_json()["id"]
    error = assert_error(client.get(f"/api/v1/groups/{gid}/tracks?since=1.5", headers=h), 400,
                         "unknown query parameter 'since': this route takes agent, since_s")
    assert error["details"]["field"] == "since"
    assert client.get(f"/api/v1/groups/{gid}/tracks?since_s=1.5&agent=a&agent=b", headers=h).status_code == 200


def test_a_non_finite_group_since_s_is_refused_naming_it(client, tokens):
    h = bearer(tokens["alice"])
    gid = client.post("/api/v1/groups", headers=h, json={"name": "t"}).get_json()["id"]
    for bad in ("nan", "inf", "-inf", "1e999", "abc"):
        resp = client.get(f"/api/v1/groups/{gid}/tracks?since_s={bad}", headers=h)
        assert assert_error(resp, 422, "'since_s' must be")["details"]["field"] == "since_s"
    assert client.get(f"/api/v1/groups/{gid}/tracks?since_s=1.5", headers=h).status_code == 200


def test_422_an_upload_of_no_known_format_names_the_form_field_format(client, tokens):
    """The reader's hint is the command line's ('pass --format'); the API's answer names its form field."""
    h = bearer(tokens["alice"])
    sid = _session(client, tokens["alice"])
    client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "left_foot"}, headers=h)
    for route in ("/api/v1/sessions", f"/api/v1/sessions/{sid}/devices/left_foot/upload"):
        data = {"file": (io.BytesIO(b"hello\n1,2,3\n"), "walk.txt")}
        err = assert_error(client.post(route, data=data, headers=h, content_type="multipart/form-data"), 422,
                           "not a supported log format")
        assert "--format" not in err["message"] and "field 'format' to force one" in err["message"], err
        assert err["code"] == "unknown_format" and err["details"]["field"] == "file"


@pytest.mark.parametrize(("change", "field"), [({"t_s": 1e300}, "steps[0].t_s"), ({"t_s": -1e300}, "steps[0].t_s"),
                                               ({"t_s": 1e11}, "steps[0].t_s"), ({"index": 10**30}, "steps[0].index")])
def test_422_a_step_summary_time_or_index_beyond_int64_names_the_field(client, tokens, change, field):
    """A shoe unit's step at t_s 1e300 s or with index 1e30 was a 500 (OverflowError turning t_s into int64 ns, or
    storing the index as int64); nothing is stored now, and the next good summaries are taken."""
    h = bearer(tokens["alice"])
    sid = _session(client, tokens["alice"])
    assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "left_foot"}, headers=h).status_code == 201
    step = {"t_s": 1.0, "dp": [0.7, 0.0, 0.0], "dpsi": 0.0, "cov": (np.eye(4) * 1e-4).tolist(), "index": 100}
    payload = {"format": "pdr-foot-steps/1", "batch_id": "b1", "device": {"role": "left_foot"},
               "steps": [step | change]}
    err = assert_error(client.post(f"/api/v1/sessions/{sid}/steps", json=payload, headers=h), 422)
    assert err["details"]["field"] == field
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["batch_list"] == []
    resp = client.post(f"/api/v1/sessions/{sid}/steps", json=payload | {"steps": [step]}, headers=h)
    assert resp.status_code == 201, resp.get_json()


@pytest.mark.parametrize("route", ["sessions/{}", "sessions/{}/track", "groups/{}", "reports/{}", "models/{}",
                                   "sites/{}", "reports/{}/files/x"])
def test_404_of_a_very_long_id_quotes_a_short_prefix_of_it(client, tokens, route):
    """A 50 000-character id was echoed whole in the 404's message (a body 1000 times the usual)."""
    long_id = "a" * 50_000
    err = assert_error(client.get(f"/api/v1/{route.format(long_id)}", headers=bearer(tokens["alice"])), 404,
                       f"'{'a' * 64}'")
    assert len(err["message"]) < 200, len(err["message"])


@pytest.mark.parametrize(("method", "route", "field"), [
    ("GET", "sessions/a%00b", "session_id"), ("DELETE", "sessions/a%00b", "session_id"),
    ("GET", "sessions/a%00b/track", "session_id"), ("POST", "sessions/a%00b/reprocess", "session_id"),
    ("GET", "groups/a%00b", "group_id"), ("DELETE", "groups/a%00b", "group_id"), ("GET", "sites/a%00b", "site_id"),
    ("DELETE", "sites/a%00b", "site_id"), ("GET", "reports/a%00b", "report_id"),
    ("GET", "reports/x/files/a%00b", "name"), ("GET", "groups/{group}/tracks?agent=a%00b", "agent"),
    ("GET", "sessions?x%00=1", "x?")])
def test_400_a_nul_character_in_the_url_names_the_parameter(client, tokens, method, route, field):
    """A NUL character (%00) in a path segment or query parameter was a 500 on PostgreSQL, which refuses it in the text
    the id was compared with (GET /api/v1/sessions/a%00b, a group's tracks of agent a%00b): a 400 naming it, on every
    database (tests/server/test_postgres.py)."""
    h = bearer(tokens["alice"])
    group = client.post("/api/v1/groups", json={"name": "g"}, headers=h).get_json()["id"]
    err = assert_error(client.open(f"/api/v1/{route.format(group=group)}", method=method, headers=h), 400, "NUL")
    assert err["details"]["field"] == field


@pytest.mark.parametrize(("change", "field"), [({"name": "Evening walk"}, "name"), ({"placement": "hand"}, "placement"),
                                               ({"origin": {"lat_deg": 49.0, "lon_deg": 11.0}}, "origin"),
                                               ({"processing": {"foot": {"zaru": False}}}, "processing")])
def test_409_a_session_created_again_with_another_field_names_it_and_changes_nothing(client, tokens, change, field):
    """A create under an existing session_id with another name was answered 200 and the name ignored (a new origin
    moved the session's track): now a 409 naming the field; the same request again, or with fewer fields, is 200."""
    h = bearer(tokens["alice"])
    first = {"session_id": "walk-1", "name": "Morning walk", "placement": "trouser_pocket",
             "origin": {"lat_deg": 49.45, "lon_deg": 11.08}, "processing": {"foot": {"zaru": True}}}
    created = client.post("/api/v1/sessions", json=first, headers=h)
    assert created.status_code == 201
    err = assert_error(client.post("/api/v1/sessions", json=first | change, headers=h), 409, f"whose {field} is")
    assert err["details"] == {"field": field, "session": created.get_json()["id"]}
    again = client.post("/api/v1/sessions", json=first, headers=h)
    assert again.status_code == 200 and again.get_json()["id"] == created.get_json()["id"]
    assert {k: again.get_json()[k] for k in ("name", "placement", "origin", "processing")} == {
        k: first[k] for k in ("name", "placement", "origin", "processing")}
    assert client.post("/api/v1/sessions", json={"session_id": "walk-1"}, headers=h).status_code == 200
