"""Hostile input to the API: every case gets a 4xx with a clear message, and the session stays intact.

Named cases (malformed JSON, deep nesting, huge bodies, NaN/Infinity, int64 overflow, timestamps days
away, wrong units, a batch labelled for another session, SQL and path injection in names), hypothesis
fuzzing of the native batch and Sensor Logger endpoints, and schemathesis against the OpenAPI document.
"""

from __future__ import annotations

import copy
import io
import json
import math
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sqlalchemy import inspect as sa_inspect

from server import auth
from tests.server.conftest import bearer, make_app
from tests.server.helpers import multipart, phone_batch


@pytest.fixture
def env(tmp_path: Any) -> Any:
    app = make_app(tmp_path, max_upload_mb=1, max_batch_mb=1)
    with app.extensions["pdr"].store.engine.begin() as conn:
        h = bearer(auth.add_user(conn, "mallory"))
    c = app.test_client()
    sid = c.post("/api/v1/sessions", json={"session_id": "victim"}, headers=h).get_json()["id"]
    for i in range(3):
        r = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
        assert r.status_code == 201
    app.extensions["pdr"].worker.wait_idle()
    yield app, c, h, sid
    app.extensions["pdr"].worker.stop()


def _snapshot(app: Any, c: Any, h: dict[str, str], sid: str) -> Any:
    app.extensions["pdr"].worker.wait_idle()
    detail = c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    track = c.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
    return [(b["batch_id"], b["status"]) for b in detail["batch_list"]], track


def _post_raw(c: Any, sid: str, h: dict[str, str], body: bytes, content_type: str = "application/json") -> Any:
    return c.post(f"/api/v1/sessions/{sid}/batches", data=body, headers=h, content_type=content_type)


def _batch(**changes: Any) -> dict[str, Any]:
    b = phone_batch("evil", 100.0)
    b.update(changes)
    return b


def _deep(n: int) -> bytes:
    return b'{"batch_id": "deep", "streams": ' + b"[" * n + b"]" * n + b"}"


def _far_future() -> dict[str, Any]:
    b = phone_batch("future", 0.0)
    for s in b["streams"].values():
        s["t_ns"] = [t + 10 * 365 * 86400 * 10**9 for t in s["t_ns"]]
    return b


def _long_span() -> dict[str, Any]:
    b = phone_batch("span", 100.0)
    for s in b["streams"].values():
        s["t_ns"][-1] += 3 * 86400 * 10**9
    return b


def _in_g() -> dict[str, Any]:
    b = phone_batch("in-g", 100.0)
    b["streams"]["acc"]["values"] = [[x / 9.80665 for x in row] for row in b["streams"]["acc"]["values"]]
    return b


def _huge_acc() -> dict[str, Any]:
    """A batch whose accelerometer reads 1e200 m/s^2: finite, but its squares overflow."""
    b = phone_batch("huge-acc", 100.0)
    b["streams"]["acc"]["values"] = [[1e200, 1e200, 1e200] for _ in b["streams"]["acc"]["values"]]
    return b


def _overflow() -> bytes:
    b = phone_batch("overflow", 100.0)
    text = json.dumps(b)
    first = str(b["streams"]["acc"]["t_ns"][0])
    return text.replace(first, "9" * 30, 1).encode()


def _nan() -> bytes:
    b = phone_batch("nan", 100.0)
    b["streams"]["acc"]["values"][3][1] = math.nan
    return json.dumps(b).encode()  # Python writes NaN, which JSON parsers of the service must refuse or catch


def _baro(hpa: float, batch_id: str = "baro") -> dict[str, Any]:
    """A batch whose barometer reads 1013 hPa but ``hpa`` at its sample 3."""
    b = phone_batch(batch_id, 100.0)
    t = b["streams"]["acc"]["t_ns"][:5]
    b["streams"]["baro"] = {"t_ns": t, "values": [[1013.25]] * 3 + [[hpa]] + [[1013.25]]}
    return b


def _baro_pa() -> dict[str, Any]:
    """A batch whose barometer reads in Pa (101 325 at sea level)."""
    b = _baro(1013.25, "baro-pa")
    b["streams"]["baro"]["values"] = [[v[0] * 100.0] for v in b["streams"]["baro"]["values"]]
    return b


CASES: dict[str, tuple[Any, int, str]] = {
    # name: (body bytes or JSON object, expected status, words the message must contain)
    "malformed JSON": (b'{"batch_id": "x", "streams": {', 400, "not valid JSON"),
    "not JSON at all": (b"\x00\x01\x02garbage", 400, "not valid JSON"),
    "JSON array": (b"[1, 2, 3]", 422, "must be a JSON object {...}, got an array"),
    "JSON null": (b"null", 422, "must be a JSON object {...}, got null"),
    "deep nesting": (_deep(100_000), 400, "JSON"),
    "huge array over the upload limit": (b'{"batch_id": "big", "x": [' + b"1," * 700_000 + b"1]}", 413, "too large"),
    "NaN value": (_nan(), 422, "not finite"),
    "Infinity value": (json.dumps(phone_batch("inf", 100.0)).replace("9.81", "Infinity", 1).encode(), 422,
                       "not finite"),
    "timestamp beyond int64": (_overflow(), 422, "int64"),
    # once stored (201), then its processing failed: OverflowError on the time axis (t_ns - t0_ns)
    "t0_ns beyond int64": (_batch(t0_ns=2**64), 422, "t0_ns 18446744073709551616 is outside the int64"),
    "timestamps 10 years after the session": (_far_future(), 422, "days away"),
    "one batch spanning 3 days": (_long_span(), 422, "span"),
    "accelerometer in g": (_in_g(), 422, "looks like g"),
    # the unit check's norm overflowed (a RuntimeWarning, a 500 where warnings are errors; found by the fuzz test)
    "accelerometer at 1e200": (_huge_acc(), 422, "stream 'acc' sample 0 holds a value of magnitude 1e+200"),
    "magnetometer at -1e300": (_batch(streams={"acc": {"t_ns": [1, 2, 3], "values": [[0, 0, 9.8]] * 3},
                                               "mag": {"t_ns": [1, 2, 3], "values": [[-1e300, 0, 0]] * 3}}), 422,
                               "stream 'mag' sample 0 holds a value of magnitude 1e+300"),
    # no air pressure where people walk (300-1100 hPa): each was stored (201) and taken for an altitude
    "barometer at -5 hPa": (_baro(-5.0), 422, "stream 'baro' sample 3: -5 hPa is no air pressure"),
    "barometer at 0 hPa": (_baro(0.0), 422, "stream 'baro' sample 3: 0 hPa is no air pressure"),
    "barometer at 5000 hPa": (_baro(5000.0), 422, "stream 'baro' sample 3: 5000 hPa is no air pressure"),
    "barometer at 1e6 hPa": (_baro(1e6), 422, "stream 'baro' sample 3 holds a value of magnitude 1e+06"),
    # a barometer in Pa was told it was beyond any sensor: the unit is what the client must fix, and is said first
    "barometer in Pa": (_baro_pa(), 422, "stream 'baro' looks like Pa, but batches carry hPa (multiply by 0.01)"),
    # the schema allows empty streams (with a t0_ns): the span of no sample was a 500 (min() of nothing)
    "every stream empty": (_batch(streams={"acc": {"t_ns": [], "values": []}}), 422, "every stream is empty"),
    "unknown stream kind": (_batch(streams={"laser": {"t_ns": [1], "values": [[1.0]]}}), 422, "laser"),
    "wrong column count": (_batch(streams={"acc": {"t_ns": [1, 2], "values": [[1.0, 2.0], [1.0, 2.0]]}}), 422,
                           "acc"),
    # a lone repeated or backward sample is dropped with a warning (pdr.io.time_order); a broken clock is refused
    "timestamps not increasing": (_batch(streams={"acc": {"t_ns": [5, 4, 3], "values": [[0, 0, 9.8]] * 3}}),
                                  422, "time goes backwards in 2 of 3"),
    "SQL injection in batch id": (_batch(batch_id="b'); DROP TABLE batches;--"), 422, "batch_id"),
    "path injection in batch id": (_batch(batch_id="../../../etc/passwd"), 422, "batch_id"),
    "SQL injection in device model": (_batch(device={"platform": "android", "model": "x'; DROP TABLE users;--" * 20,
                                                     "role": "phone"}), 422, "model"),
    "phone role placed on the foot": (_batch(device={"platform": "imu", "model": "shoe", "role": "phone",
                                                     "placement": "foot"}), 422, "role 'phone' with placement 'foot'"),
    "shoe IMU placed in the hand": (_batch(device={"platform": "imu", "model": "shoe", "role": "left_foot",
                                                   "placement": "hand"}), 422, "placement 'hand'"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_hostile_batch_gets_a_clear_4xx_and_leaves_the_session_intact(env, case):
    app, c, h, sid = env
    before = _snapshot(app, c, h, sid)
    body, status, words = CASES[case]
    raw = body if isinstance(body, bytes) else json.dumps(body).encode()
    r = _post_raw(c, sid, h, raw)
    assert r.status_code == status, r.get_data()[:300]
    error = r.get_json()["error"]
    assert error["status"] == status and words.lower() in error["message"].lower(), error
    assert _snapshot(app, c, h, sid) == before
    tables = set(sa_inspect(app.extensions["pdr"].store.engine).get_table_names())
    assert {"users", "batches", "sessions"} <= tables


@pytest.mark.parametrize("hpa", [-5.0, 0.0, 299.0, 1100.5, 5000.0, 1e6])
def test_a_pressure_that_is_no_air_pressure_is_a_422_naming_the_sample_and_keeps_what_was_accepted(env, hpa):
    """A barometer of -5, 0 or 5000 hPa was stored (201); now a 422 naming the stream and sample, and the session's
    accepted batches stay; a barometer within 300-1100 hPa (the Dead Sea to Everest) is stored."""
    app, c, h, sid = env
    before = _snapshot(app, c, h, sid)
    r = c.post(f"/api/v1/sessions/{sid}/batches", json=_baro(hpa), headers=h)
    assert r.status_code == 422, r.get_json()
    assert r.get_json()["error"]["details"] == {"field": "streams.baro.values[3]", "index": 3}
    assert "stream 'baro' sample 3" in r.get_json()["error"]["message"]
    assert _snapshot(app, c, h, sid) == before
    for i, good in enumerate((300.0, 1100.0, 1013.25)):
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=_baro(good, f"good{i}"), headers=h).status_code == 201


#: Location fixes in ``meta.location`` a client got wrong, and the field the 422 names.
BAD_FIXES: dict[str, tuple[Any, str]] = {
    "a place name": ("Nuremberg", "meta.location"),
    "null": (None, "meta.location"),
    "latitude off the globe": ({"lat_deg": 91.0, "lon_deg": 11.1, "unix_time_s": 1.7e9}, "meta.location.lat_deg"),
    "longitude past 180": ({"lat_deg": 49.4, "lon_deg": 191.1, "unix_time_s": 1.7e9}, "meta.location.lon_deg"),
    "latitude as text": ({"lat_deg": "49.4", "lon_deg": 11.1}, "meta.location.lat_deg"),
    "no longitude": ({"lat_deg": 49.4, "unix_time_s": 1.7e9}, "meta.location.lon_deg"),
    "time in ms": ({"lat_deg": 49.4, "lon_deg": 11.1, "unix_time_s": 1.7e12}, "meta.location.unix_time_s"),
    "NaN altitude": ({"lat_deg": 49.4, "lon_deg": 11.1, "unix_time_s": 1.7e9, "alt_m": math.nan},
                     "meta.location.alt_m"),
}


@pytest.mark.parametrize("case", sorted(BAD_FIXES))
def test_a_bad_location_fix_is_a_422_naming_its_field_and_leaves_the_session_intact(env, case):
    """A ``meta.location`` that is not a fix was stored and ignored (201): the magnetometer went unchecked, and the
    session's origin was not used in its place."""
    app, c, h, sid = env
    before = _snapshot(app, c, h, sid)
    fix, field = BAD_FIXES[case]
    r = _post_raw(c, sid, h, json.dumps(_batch(meta={"location": fix})).encode())
    assert r.status_code == 422, r.get_data()[:300]
    error = r.get_json()["error"]
    assert error["details"]["field"] == field and "meta.location" in error["message"], error
    assert _snapshot(app, c, h, sid) == before


def test_a_good_location_fix_is_stored_whole(env):
    """Fixes as clients and readers write them (dated, a Sensor Logger fix with its extra keys, undated: it still
    geo-references) are accepted and kept as sent."""
    from server.processing import decode_batch

    app, c, h, sid = env
    fixes = [{"lat_deg": 49.4614, "lon_deg": 11.1115, "unix_time_s": 1686732686.0, "alt_m": 365.0},
             {"lat_deg": -33.9, "lon_deg": 151.2, "t_ns": 1686732686000000000, "horizontal_accuracy_m": None,
              "unix_time_s": 1686732686.0, "fixes": 3},
             {"lat_deg": 49.46, "lon_deg": 11.11}]
    for i, fix in enumerate(fixes):
        r = c.post(f"/api/v1/sessions/{sid}/batches", json=_batch(batch_id=f"fix{i}", meta={"location": fix}),
                   headers=h)
        assert r.status_code == 201, r.get_json()
    app.extensions["pdr"].worker.wait_idle()
    stored = {b.client_batch_id: decode_batch(b).meta["location"]
              for b in app.extensions["pdr"].store.batches(sid) if b.client_batch_id.startswith("fix")}
    assert stored == {f"fix{i}": fix for i, fix in enumerate(fixes)}


def test_an_uploaded_native_log_with_a_bad_location_fix_is_a_422_and_creates_nothing(env):
    app, c, h, sid = env
    before = c.get("/api/v1/sessions", headers=h).get_json()
    log = json.dumps(_batch(meta={"location": {"lat_deg": 491.0, "lon_deg": 11.1}})).encode()
    r = c.post("/api/v1/sessions", data={"file": (io.BytesIO(log), "walk.json")}, headers=h,
               content_type="multipart/form-data")
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "meta.location.lat_deg", r.get_json()
    assert c.get("/api/v1/sessions", headers=h).get_json() == before


def test_a_log_file_with_no_air_pressure_is_a_422_naming_the_sample_on_both_upload_routes_and_creates_nothing(env):
    """A log file whose barometer reads -5 hPa at one sample was taken into a new session (201) and its floors with it,
    while the same file added to a session's paired phone was refused: both routes check the units now."""
    app, c, h, sid = env
    c.post(f"/api/v1/sessions/{sid}/devices", json={"role": "phone"}, headers=h)
    before = c.get("/api/v1/sessions", headers=h).get_json()
    log = json.dumps(_baro(-5.0)).encode()
    for route in ("/api/v1/sessions", f"/api/v1/sessions/{sid}/devices/phone/upload"):
        r = c.post(route, data={"file": (io.BytesIO(log), "walk.json")}, headers=h, content_type="multipart/form-data")
        assert r.status_code == 422, (route, r.get_data()[:300])
        assert r.get_json()["error"]["details"] == {"field": "streams.baro.values[3]", "index": 3}, route
    after = c.get("/api/v1/sessions", headers=h).get_json()
    assert [(s["id"], s["batches"]) for s in after["sessions"]] == [(s["id"], s["batches"]) for s in before["sessions"]]


def test_an_uploaded_log_without_a_sample_is_a_422_naming_the_file_and_creates_nothing(env):
    """A native log whose streams are all empty (the schema allows it with a ``t0_ns``) was a 500 on both upload
    routes, after the new session was created."""
    app, c, h, sid = env
    before = c.get("/api/v1/sessions", headers=h).get_json()
    log = json.dumps(_batch(streams={"acc": {"t_ns": [], "values": []}})).encode()
    c.post(f"/api/v1/sessions/{sid}/devices", json={"role": "phone"}, headers=h)
    for route in ("/api/v1/sessions", f"/api/v1/sessions/{sid}/devices/phone/upload"):
        r = c.post(route, data={"file": (io.BytesIO(log), "empty.json")}, headers=h,
                   content_type="multipart/form-data")
        assert r.status_code == 422, (route, r.get_data()[:300])
        error = r.get_json()["error"]
        assert error["details"]["field"] == "file" and "every stream is empty" in error["message"], error
    after = c.get("/api/v1/sessions", headers=h).get_json()
    assert [(s["id"], s["batches"]) for s in after["sessions"]] == [(s["id"], s["batches"]) for s in before["sessions"]]


def test_a_gzip_body_is_inflated_and_taken_as_sent_plain_on_every_route_that_reads_a_body(env):
    """Phones and apps gzip their uploads (Content-Encoding: gzip): that was a 415 saying to send it uncompressed.
    Now a gzip body is inflated and taken as the same body sent plain: native batches, JSON bodies, a log file
    upload (multipart) and the Sensor Logger push."""
    import gzip

    app, c, h, sid = env
    gz = {**h, "Content-Encoding": "gzip"}
    batch = json.dumps(phone_batch("zipped", 50.0)).encode()
    r = c.post(f"/api/v1/sessions/{sid}/batches", data=gzip.compress(batch), headers=gz,
               content_type="application/json")
    assert r.status_code == 201 and r.get_json()["batch_id"] == "zipped", r.get_json()
    r = c.post(f"/api/v1/sessions/{sid}/batches", data=batch, headers=h, content_type="application/json")
    assert r.status_code == 200 and r.get_json()["duplicate"], r.get_json()     # the same batch as sent plain
    r = c.post("/api/v1/sessions", data=gzip.compress(b'{"session_id": "zipped-json"}'), headers=gz,
               content_type="application/json")
    assert r.status_code == 201 and r.get_json()["session_id"] == "zipped-json", r.get_json()
    body, ctype = multipart({"file": (json.dumps(phone_batch("filed", 0.0)).encode(), "walk.json"),
                             "session_id": "zipped-file"})
    r = c.post("/api/v1/sessions", data=gzip.compress(body), headers=gz, content_type=ctype)
    assert r.status_code == 201 and r.get_json()["session_id"] == "zipped-file", r.get_json()
    message = {"messageId": 1, "sessionId": "zipped-push", "deviceId": "d", "payload": [
        {"name": "accelerometer", "time": 1_700_000_000_000_000_000, "values": {"x": 0.0, "y": 0.0, "z": 9.8}}]}
    r = c.post(f"/api/v1/ingest/sensor-logger?token={h['Authorization'].split()[-1]}",
               data=gzip.compress(json.dumps(message).encode()), headers={"Content-Encoding": "gzip"},
               content_type="application/json")
    assert r.status_code == 200, r.get_data()[:300]
    sessions = c.get("/api/v1/sessions", headers=h).get_json()["sessions"]
    assert sorted(s["session_id"] for s in sessions) == ["victim", "zipped-file", "zipped-json", "zipped-push"]


def test_a_corrupt_gzip_body_is_a_400_a_gzip_bomb_a_413_another_encoding_a_415_and_nothing_is_stored(env):
    """A body whose Content-Encoding: gzip is a lie (not gzip, or cut short) is a 400 naming the header; one that
    inflates past the route's body limit (a zip bomb: 5 MB of zeros from 5 kB, the limit 1 MB) a 413 quoting the
    limit, as the body sent plain would be; any other encoding still a 415 naming the header."""
    import gzip

    app, c, h, sid = env
    before = _snapshot(app, c, h, sid)
    gz = {**h, "Content-Encoding": "gzip"}
    batch = json.dumps(phone_batch("zipped", 50.0)).encode()
    token = h["Authorization"].split()[-1]
    for data in (batch, gzip.compress(batch)[:300], b"\x1f\x8b\x08\x00" + b"\xff" * 400):
        r = c.post(f"/api/v1/sessions/{sid}/batches", data=data, headers=gz, content_type="application/json")
        assert r.status_code == 400, r.get_data()[:300]
        error = r.get_json()["error"]
        assert error["details"]["field"] == "Content-Encoding" and "'Content-Encoding: gzip'" in error["message"]
        r = c.post(f"/api/v1/ingest/sensor-logger?token={token}", data=data, headers={"Content-Encoding": "gzip"},
                   content_type="application/json")
        assert r.status_code == 499 and "'Content-Encoding: gzip'" in r.get_data(as_text=True)
    bomb = gzip.compress(b'{"batch_id": "bomb", "x": "' + b"0" * (5 * 1024 * 1024) + b'"}')
    assert len(bomb) < 10_000
    for route, ctype in ((f"/api/v1/sessions/{sid}/batches", "application/json"),
                         ("/api/v1/sessions", "multipart/form-data; boundary=x")):
        r = c.post(route, data=bomb, headers=gz, content_type=ctype)
        assert r.status_code == 413, r.get_data()[:300]
        assert r.get_json()["error"]["details"]["limit_bytes"] == 1024 * 1024
    r = c.post(f"/api/v1/ingest/sensor-logger?token={token}", data=bomb, headers={"Content-Encoding": "gzip"},
               content_type="application/json")
    assert r.status_code == 499 and "message too large" in r.get_data(as_text=True)
    for encoding in ("br", "deflate", "gzip, br"):
        r = c.post(f"/api/v1/sessions/{sid}/batches", data=batch, headers={**h, "Content-Encoding": encoding},
                   content_type="application/json")
        assert r.status_code == 415, r.get_data()[:300]
        error = r.get_json()["error"]
        assert error["details"]["field"] == "Content-Encoding" and f"'{encoding}' is not supported" in error["message"]
    assert _snapshot(app, c, h, sid) == before
    assert [s["session_id"] for s in c.get("/api/v1/sessions", headers=h).get_json()["sessions"]] == ["victim"]
    identity = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("plain", 50.0),
                      headers={**h, "Content-Encoding": "identity"})
    assert identity.status_code == 201, identity.get_json()


def test_wrong_content_type_is_415(env):
    app, c, h, sid = env
    r = _post_raw(c, sid, h, json.dumps(phone_batch("x", 50.0)).encode(), content_type="text/plain")
    assert r.status_code == 415 and "application/json" in r.get_json()["error"]["message"]


def test_batch_labelled_for_another_of_the_users_sessions_is_refused(env):
    app, c, h, sid = env
    other = c.post("/api/v1/sessions", json={"session_id": "other-walk"}, headers=h).get_json()["id"]
    before = [_snapshot(app, c, h, s) for s in (sid, other)]
    b = phone_batch("mixed", 50.0)
    b["session_id"] = "other-walk"
    r = c.post(f"/api/v1/sessions/{sid}/batches", json=b, headers=h)
    assert r.status_code == 409 and "other-walk" in r.get_json()["error"]["message"]
    assert [_snapshot(app, c, h, s) for s in (sid, other)] == before


def test_injection_in_names_is_stored_as_inert_text(env):
    app, c, h, sid = env
    name = "walk'); DROP TABLE sessions;-- ../../etc/passwd <script>alert(1)</script>"
    r = c.post("/api/v1/sessions", json={"session_id": "inj-1", "name": name}, headers=h)
    assert r.status_code == 201 and r.get_json()["name"] == name
    assert c.post("/api/v1/sessions", json={"session_id": "x'; DROP TABLE users;--"}, headers=h).status_code == 422
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).status_code == 200


def test_uploaded_file_name_cannot_escape_the_temporary_folder(env, tmp_path):
    app, c, h, sid = env
    target = tmp_path / "escaped.txt"
    data = {"file": (io.BytesIO(b"not a log"), f"../../../../..{target}")}
    r = c.post("/api/v1/sessions", data=data, headers=h, content_type="multipart/form-data")
    assert 400 <= r.status_code < 500 and r.get_json()["error"]["message"]
    assert not target.exists()


def test_unknown_format_or_a_nul_byte_in_the_upload_fields_is_a_422_naming_it(env):
    app, c, h, sid = env
    for fmt, name in (("ipin\x00x", "walk.txt"), ("no_such_format", "walk.txt"), ("ipin", "walk\x00.txt")):
        data = {"file": (io.BytesIO(b"not a log"), name), "format": fmt}
        r = c.post("/api/v1/sessions", data=data, headers=h, content_type="multipart/form-data")
        assert r.status_code == 422, (fmt, name, r.get_json())
        message = r.get_json()["error"]["message"]
        assert ("unknown format" in message) == (fmt != "ipin"), message
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).status_code == 200


def test_sensor_logger_hostile_messages_get_the_apps_499_with_a_message(env):
    app, c, h, _ = env
    good = json.loads(json.dumps({"messageId": 1, "sessionId": "sl", "deviceId": "d", "payload": [
        {"name": "accelerometer", "time": 1_700_000_000_000_000_000 + i * 10_000_000,
         "values": {"x": 0.0, "y": 0.0, "z": 9.81}} for i in range(20)]}))
    for body in (b"{", b"[]", json.dumps({**good, "payload": "x"}).encode(), _deep(50_000),
                 json.dumps({**good, "sessionId": "a'; DROP TABLE sessions;--" * 20}).encode()):
        r = c.post("/api/v1/ingest/sensor-logger", data=body, headers=h, content_type="application/json")
        assert r.status_code == 499 and r.get_data(as_text=True).startswith("pdr: "), (body[:60], r.get_data()[:200])


def test_a_push_without_a_token_tells_the_app_user_to_put_it_in_the_url(env):
    """The Sensor Logger app sets no header, but its user was told to send 'Authorization: Bearer <token>'."""
    app, c, h, _ = env
    message = {"messageId": 1, "sessionId": "sl", "deviceId": "d", "payload": [
        {"name": "accelerometer", "time": 1_700_000_000_000_000_000, "values": {"x": 0.0, "y": 0.0, "z": 9.81}}]}
    r = c.post("/api/v1/ingest/sensor-logger", json=message)
    assert r.status_code == 499 and "?token=<token>" in r.get_data(as_text=True), r.get_data(as_text=True)
    r = c.get("/api/v1/sessions")                                     # no URL token there: no hint of one
    assert r.status_code == 401 and "?token" not in r.get_json()["error"]["message"]


# -- property-based fuzzing of the ingest endpoints ----------------------------------------------------
NASTY: list[Any] = [math.nan, math.inf, -math.inf, 10**30, -(10**30), 2**63, -1, 0, 1e308, "", "x" * 1000,
                    None, True, [], {}, [[[]]], "'; DROP TABLE batches;--", "../../etc/passwd", 1.5]


def _paths(obj: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(obj, list) and obj:
        for i in {0, len(obj) - 1}:
            out += _paths(obj[i], (*prefix, i))
    return out


@st.composite
def mutated_batch(draw: st.DrawFn) -> bytes:
    b = phone_batch(f"f{draw(st.integers(0, 10**6))}", 100.0 + draw(st.integers(0, 100)), duration_s=0.2)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(b)[1:]
        path = draw(st.sampled_from(paths))
        parent = b
        for p in path[:-1]:
            parent = parent[p]
        action = draw(st.sampled_from(["set", "set", "delete", "wrap"]))
        if action == "delete" and isinstance(parent, dict):
            del parent[path[-1]]
        elif action == "wrap":
            parent[path[-1]] = [copy.deepcopy(parent[path[-1]])]
        else:
            parent[path[-1]] = copy.deepcopy(draw(st.sampled_from(NASTY)))
    raw = json.dumps(b).encode()
    if draw(st.booleans()) and draw(st.booleans()):
        raw = raw[:draw(st.integers(0, len(raw)))]
    return raw


def test_fuzzed_native_batches_never_fail_the_server_and_never_touch_other_data(env):
    app, c, h, sid = env
    before = _snapshot(app, c, h, sid)
    fuzzed = c.post("/api/v1/sessions", json={"session_id": "fuzzed"}, headers=h).get_json()["id"]
    accepted: list[str] = []

    @settings(max_examples=120, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    @given(raw=mutated_batch())
    def fuzz(raw: bytes) -> None:
        r = _post_raw(c, fuzzed, h, raw)
        assert r.status_code in (200, 201, 400, 409, 413, 415, 422), (r.status_code, r.get_data()[:300], raw[:300])
        if r.status_code >= 400:
            assert r.get_json()["error"]["message"]
        elif r.status_code == 201:
            accepted.append(r.get_json()["batch_id"])

    fuzz()
    assert _snapshot(app, c, h, sid) == before
    stored = [b for b, _ in _snapshot(app, c, h, fuzzed)[0]]
    assert sorted(stored) == sorted(accepted)


@st.composite
def mutated_message(draw: st.DrawFn) -> bytes:
    msg: dict[str, Any] = {"messageId": draw(st.integers(0, 10**9)), "sessionId": "fz", "deviceId": "d",
                           "payload": [{"name": draw(st.sampled_from(["accelerometer", "gyroscope", "magnetometer",
                                                                       "barometer", "gravity", "orientation", "x"])),
                                        "time": 1_700_000_000_000_000_000 + i * 10_000_000,
                                        "values": {"x": 0.1, "y": 0.2, "z": 9.8}} for i in range(5)]}
    for _ in range(draw(st.integers(0, 3))):
        path = draw(st.sampled_from(_paths(msg)[1:]))
        parent: Any = msg
        for p in path[:-1]:
            parent = parent[p]
        parent[path[-1]] = copy.deepcopy(draw(st.sampled_from(NASTY)))
    return json.dumps(msg).encode()


def test_fuzzed_sensor_logger_messages_get_200_or_499(env):
    app, c, h, _ = env

    @settings(max_examples=80, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    @given(raw=mutated_message())
    def fuzz(raw: bytes) -> None:
        r = c.post("/api/v1/ingest/sensor-logger", data=raw, headers=h, content_type="application/json")
        assert r.status_code in (200, 499), (r.status_code, r.get_data()[:300], raw[:300])

    fuzz()


# -- schemathesis against the published OpenAPI document ------------------------------------------------
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_openapi_operations_never_answer_5xx(tmp_path):
    """Every operation of the OpenAPI document, fuzzed by schemathesis over HTTP against a real ``pdr serve``
    (waitress, the body limits, the access log and the error handlers as deployed): no answer is a 5xx."""
    import schemathesis
    from schemathesis.checks import not_a_server_error
    from schemathesis.core.result import Err

    from server.client import Client, add_user, running_server

    with running_server(tmp_path, {"PDR_MAX_UPLOAD_MB": "1", "PDR_MAX_BATCH_MB": "1"}) as (url, env, _):
        token = add_user(env, "schema")
        h = bearer(token)
        c = Client(url, token)
        sid = c.request("POST", "/api/v1/sessions", {"session_id": "s"}).json()["id"]
        assert c.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch("b0", 0.0)).status == 201
        c.close()
        schema = schemathesis.openapi.from_url(f"{url}/api/v1/openapi.json")
        failures: list[str] = []
        calls = 0
        for result in schema.get_all_operations():
            if isinstance(result, Err):
                raise result.err()
            operation = result.ok()

            @settings(max_examples=15, deadline=None, database=None, suppress_health_check=list(HealthCheck))
            @given(case=operation.as_strategy())
            def run(case: Any) -> None:
                nonlocal calls
                if case.path_parameters and case.path_parameters.get("session_id", sid).strip() == "":
                    case.path_parameters["session_id"] = sid
                if case.method.upper() == "DELETE" and case.path_parameters and (
                        case.path_parameters.get("session_id") == sid):
                    case.path_parameters["session_id"] = "not-" + sid  # keep the seeded session for the others
                response = case.call(base_url=url, headers=h, timeout=60)
                calls += 1
                try:
                    case.validate_response(response, checks=[not_a_server_error])
                except Exception as exc:  # collect every operation's failure, then report them together
                    failures.append(f"{case.method} {case.formatted_path}: {str(exc)[:300]}")

            run()
    assert calls > 100
    assert failures == []


# -- uploaded files that attack the readers themselves --------------------------------------------------
@pytest.mark.data
def test_file_that_crashes_the_mat_reader_is_a_422_and_the_service_survives(env):
    from tests.conftest import data_path

    app, c, h, sid = env
    raw = data_path("pyshoe_vicon", "2017-11-22-11-35-59.mat").read_bytes()
    first = 136 + int.from_bytes(raw[132:136], "little")  # the first variable, whole (imu, 52 KB)
    crashing = raw[:176] + bytes(33) + raw[209:first]  # segfaults scipy.io.loadmat (scipy 1.17) in-process
    r = c.post("/api/v1/sessions", data={"file": (io.BytesIO(crashing), "trial.mat"), "format": "pyshoe"},
               headers=h, content_type="multipart/form-data")
    # pdr.io.matfile refuses it before scipy reads it: the 422 names the damaged element, not a crashed reader
    assert r.status_code == 422, r.get_data()[:300]
    error = r.get_json()["error"]
    assert ("not a readable MATLAB .mat file (damaged: element 1 at byte 128: a data element of unknown type 0"
            in error["message"]), error
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).status_code == 200


@pytest.mark.slow
def test_gzip_bomb_upload_is_a_422_within_the_memory_limit(tmp_path, monkeypatch):
    import zlib

    app = make_app(tmp_path)
    with app.extensions["pdr"].store.engine.begin() as conn:
        h = bearer(auth.add_user(conn, "bomber"))
    c = app.test_client()
    monkeypatch.setenv("PDR_READER_MEMORY_MB", "1024")
    comp = zlib.compressobj(9, zlib.DEFLATED, 31)  # gzip container
    chunk = bytes(2**20)
    bomb = b"".join(comp.compress(chunk) for _ in range(2048)) + comp.flush()  # 2 GB of zeros in ~2 MB
    body, content_type = multipart({"file": (bomb, "walk.txt.gz"), "format": "ms_indoor"})
    r = c.post("/api/v1/sessions", data=body, headers=h, content_type=content_type)
    app.extensions["pdr"].worker.stop()
    assert r.status_code == 422, r.get_data()[:300]
    message = r.get_json()["error"]["message"]
    assert "memory" in message or "limits" in message
    assert c.get("/api/v1/sessions", headers=h).status_code == 200


@pytest.mark.parametrize("placement, role, words", [("foot", "phone", "role 'phone' with placement 'foot'"),
                                                     ("hand", "left_foot", "placement 'hand'")])
def test_uploaded_log_whose_placement_contradicts_its_role_is_a_422_and_creates_nothing(env, tmp_path, placement,
                                                                                       role, words):
    import numpy as np

    from pdr.io import native
    from pdr.recording import DeviceInfo, Recording, SensorStream

    app, c, h, sid = env
    t_ns = 1_700_000_000_000_000_000 + np.arange(200, dtype=np.int64) * 10_000_000
    rec = Recording({"acc": SensorStream("acc", t_ns, np.tile([0.0, 0.0, 9.81], (200, 1))),
                     "gyro": SensorStream("gyro", t_ns, np.zeros((200, 3)))}, DeviceInfo(platform="imu", role=role),
                    t0_ns=int(t_ns[0]))
    log = native.write(rec, tmp_path / "walk.zip")
    before = c.get("/api/v1/sessions", headers=h).get_json()
    r = c.post("/api/v1/sessions", data={"file": (io.BytesIO(log.read_bytes()), "walk.zip"), "placement": placement},
               headers=h, content_type="multipart/form-data")
    assert r.status_code == 422 and words in r.get_json()["error"]["message"], r.get_data()[:300]
    assert c.get("/api/v1/sessions", headers=h).get_json() == before


def test_the_reader_sandbox_child_loads_the_readers_but_not_the_service():
    """The child of server.sandbox starts per uploaded file: it must not import Flask, the database layer or
    the pipelines (that tripled the time to read a small upload)."""
    import subprocess
    import sys

    probe = ("import sys, server.sandbox, pdr.io; print(sorted(m for m in "
             "('flask', 'sqlalchemy', 'server.app', 'pdr.phone.pipeline') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("value", ["NaN", "Infinity", "-Infinity"])
@pytest.mark.parametrize("where", ["origin", "start"])
def test_a_number_that_is_not_finite_is_a_422_naming_its_field(env, value, where):
    """A session's origin of NaN was created (201) and silently dropped (origin null), and a site's --start of NaN
    accepted: JSON bodies may carry NaN and Infinity, which pass every minimum and maximum. Every number of a
    request body is now checked finite (server.schemas.validate)."""
    app, c, h, _ = env
    if where == "origin":
        body, field = f'{{"session_id": "n-{value}", "origin": {{"lat_deg": {value}, "lon_deg": 11.1}}}}', \
            "origin.lat_deg"
    else:
        body, field = f'{{"session_id": "s-{value}", "processing": {{"start": [{value}, 0.0]}}}}', "processing.start[0]"
    r = c.post("/api/v1/sessions", data=body, headers=h, content_type="application/json")
    assert r.status_code == 422, r.get_data()[:300]
    assert r.get_json()["error"]["details"]["field"] == field
    sessions = c.get("/api/v1/sessions", headers=h).get_json()["sessions"]
    assert not [s for s in sessions if s["session_id"].endswith(value)]


#: An integer literal beyond any float64 (1e400) and a lone UTF-16 surrogate: Python's JSON parser takes both.
HUGE_INT = "1" + "0" * 400
LONE_SURROGATE = '"\\ud800x"'


def _with(body: dict[str, Any], path: tuple[Any, ...], literal: str) -> bytes:
    """``body`` as JSON text with the value at ``path`` written as ``literal``."""
    body = copy.deepcopy(body)
    parent: Any = body
    for p in path[:-1]:
        parent = parent[p]
    parent[path[-1]] = "@@HERE@@"
    return json.dumps(body).replace('"@@HERE@@"', literal).encode()


def _steps() -> dict[str, Any]:
    step = {"t_s": 1.0, "dp": [0.7, 0.0, 0.0], "dpsi": 0.0, "cov": [[1e-4 if i == j else 0.0 for j in range(4)]
                                                                     for i in range(4)], "index": 1}
    return {"format": "pdr-foot-steps/1", "batch_id": "st", "device": {"role": "left_foot"}, "steps": [step]}


_SITE = {"name": "hall", "floors": [{"floor": 0, "walkable": {"type": "Polygon", "coordinates": [
    [[0, 0], [60, 0], [60, 20], [0, 20], [0, 0]]]}}]}
_MESSAGE = {"messageId": 1, "sessionId": "sl", "deviceId": "d", "payload": [
    {"name": "accelerometer", "time": 1_700_000_000_000_000_000 + i * 10_000_000,
     "values": {"x": 0.0, "y": 0.0, "z": 9.81}} for i in range(3)]}

#: (route, body, path of the bad value, its field in the answer); ``{sid}`` is the env's session.
UNREPRESENTABLE = [
    ("/api/v1/sessions", {"session_id": "o", "origin": {"lat_deg": 1.0, "lon_deg": 2.0}}, ("origin", "lat_deg"),
     "origin.lat_deg"),
    ("/api/v1/sessions", {"session_id": "n", "name": "x"}, ("name",), "name"),
    ("/api/v1/sessions/{sid}/batches", phone_batch("u", 100.0), ("streams", "acc", "values", 0, 2),
     "streams.acc.values[0][2]"),
    ("/api/v1/sessions/{sid}/batches", phone_batch("u", 100.0), ("session_id",), "session_id"),
    ("/api/v1/sessions/{sid}/steps", _steps(), ("steps", 0, "dp", 0), "steps[0].dp[0]"),
    ("/api/v1/ingest/sensor-logger", _MESSAGE, ("payload", 0, "values", "z"), "payload[0].values.z"),
    ("/api/v1/ingest/sensor-logger", _MESSAGE, ("sessionId",), "sessionId"),
    ("/api/v1/classify", {"batch": phone_batch("c", 0.0, duration_s=3.0)}, ("batch", "streams", "acc", "values", 9, 0),
     "batch.streams.acc.values[9][0]"),
    ("/api/v1/sites", _SITE, ("floors", 0, "walkable", "coordinates", 0, 1, 0),
     "floors[0].walkable.coordinates[0][1][0]"),
    ("/api/v1/sites", _SITE, ("name",), "name"),
    ("/api/v1/groups", {"name": "g", "contact_timeout_s": 60}, ("contact_timeout_s",), "contact_timeout_s"),
    ("/api/v1/groups", {"name": "g"}, ("name",), "name"),
]


@pytest.mark.parametrize(("route", "body", "path", "field"), UNREPRESENTABLE,
                         ids=[f"{r}:{f}" for r, _, _, f in UNREPRESENTABLE])
def test_an_integer_beyond_any_float_or_a_lone_surrogate_is_a_422_naming_its_field_and_stores_nothing(
        env, route, body, path, field):
    """An integer of 401 digits in a number field was a 500 on every JSON route (OverflowError where it was made a
    float: the schema's finite check, numpy, ``float()``), and text with a lone surrogate ("\\ud800") a 500 where it
    was stored (UnicodeEncodeError in the database driver). Both are now a 422 naming the field, before anything is
    stored; the Sensor Logger app gets its 499 naming it."""
    app, c, h, sid = env
    before = _snapshot(app, c, h, sid), c.get("/api/v1/sessions", headers=h).get_json()
    literal = HUGE_INT if path[-1] not in ("name", "session_id", "sessionId") else LONE_SURROGATE
    r = c.post(route.format(sid=sid), data=_with(body, path, literal), headers=h, content_type="application/json")
    if "sensor-logger" in route:
        assert r.status_code == 499 and field in r.get_data(as_text=True), r.get_data()[:300]
    else:
        assert r.status_code == 422, r.get_data()[:300]
        assert r.get_json()["error"]["details"]["field"] == field
    assert (_snapshot(app, c, h, sid), c.get("/api/v1/sessions", headers=h).get_json()) == before
    assert c.get("/api/v1/sites", headers=h).get_json()["sites"] == []
    assert c.get("/api/v1/groups", headers=h).get_json()["groups"] == []


#: A NUL character, which PostgreSQL refuses in text ("\\u0000" in a JSON string).
NUL_TEXT = '"a\\u0000b"'

#: (route, body, path of the text, its field in the answer): text that ends up in a column, on every JSON route.
NUL_FIELDS = [
    ("/api/v1/sessions", {"session_id": "n", "name": "x"}, ("name",), "name"),
    ("/api/v1/sessions", {"session_id": "n", "device": {"model": "x"}}, ("device", "model"), "device.model"),
    ("/api/v1/sessions/{sid}/devices", {"role": "left_foot", "device_id": "x"}, ("device_id",), "device_id"),
    ("/api/v1/sessions/{sid}/batches", phone_batch("u", 100.0), ("device", "device_id"), "device.device_id"),
    ("/api/v1/sessions/{sid}/batches", phone_batch("u", 100.0), ("session_id",), "session_id"),
    ("/api/v1/ingest/sensor-logger", _MESSAGE, ("sessionId",), "sessionId"),
    ("/api/v1/ingest/sensor-logger", _MESSAGE, ("deviceId",), "deviceId"),
    ("/api/v1/ingest/sensor-logger", _MESSAGE, ("messageId",), "messageId"),
    ("/api/v1/sites", _SITE, ("name",), "name"),
    ("/api/v1/groups", {"name": "g"}, ("name",), "name"),
]


@pytest.mark.parametrize(("route", "body", "path", "field"), NUL_FIELDS, ids=[f"{r}:{f}" for r, _, _, f in NUL_FIELDS])
def test_text_with_a_nul_character_is_a_422_naming_its_field_and_stores_nothing(env, route, body, path, field):
    """A NUL character ("\\u0000") in a JSON string was stored as it came in SQLite and was a 500 in PostgreSQL, which
    refuses it in text (a session's name, a device's model or id, a Sensor Logger sessionId, a site's or group's
    name; tests/server/test_postgres.py). It is a 422 naming the field now, before anything is stored, on every
    database; the Sensor Logger app gets its 499 naming it."""
    app, c, h, sid = env
    before = _snapshot(app, c, h, sid), c.get("/api/v1/sessions", headers=h).get_json()
    r = c.post(route.format(sid=sid), data=_with(body, path, NUL_TEXT), headers=h, content_type="application/json")
    if "sensor-logger" in route:
        assert r.status_code == 499 and field in r.get_data(as_text=True), r.get_data()[:300]
        assert "NUL" in r.get_data(as_text=True)
    else:
        assert r.status_code == 422, r.get_data()[:300]
        assert r.get_json()["error"]["details"]["field"] == field and "NUL" in r.get_json()["error"]["message"]
    assert (_snapshot(app, c, h, sid), c.get("/api/v1/sessions", headers=h).get_json()) == before
    assert c.get("/api/v1/sites", headers=h).get_json()["sites"] == []
    assert c.get("/api/v1/groups", headers=h).get_json()["groups"] == []


def test_a_processing_form_field_or_json_key_with_a_nul_character_is_a_422_naming_it(env):
    app, c, h, sid = env
    log = json.dumps(phone_batch("f", 0.0, duration_s=2.0)).encode()
    body, ctype = multipart({"file": (log, "walk.json"), "processing": '{"site_id": "a\\u0000b"}'})
    r = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
    assert r.status_code == 422, r.get_data()[:300]
    assert r.get_json()["error"]["details"]["field"] == "processing.site_id"
    r = c.post("/api/v1/sessions", data=b'{"session_id": "k", "processing": {"site": {"a\\u0000": 1}}}', headers=h,
               content_type="application/json")
    assert r.status_code == 422, r.get_data()[:300]
    assert r.get_json()["error"]["details"]["field"] == "processing.site.a?"
    assert [s["id"] for s in c.get("/api/v1/sessions", headers=h).get_json()["sessions"]] == [sid]


def test_a_site_file_or_processing_form_field_with_an_integer_beyond_any_float_is_a_422_naming_the_field(env):
    app, c, h, _ = env
    body, ctype = multipart({"file": (_with(_SITE, ("floors", 0, "floor"), HUGE_INT), "site.json")})
    r = c.post("/api/v1/sites", data=body, content_type=ctype, headers=h)
    assert r.status_code == 422 and r.get_json()["error"]["details"]["field"] == "floors[0].floor", r.get_data()[:300]
    log = json.dumps(phone_batch("f", 0.0, duration_s=2.0)).encode()
    processing = _with({"site_id": "x", "start": [1.0, 2.0]}, ("start", 0), HUGE_INT).decode()
    body, ctype = multipart({"file": (log, "walk.json"), "processing": processing})
    r = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
    assert r.status_code == 422, r.get_data()[:300]
    assert r.get_json()["error"]["details"]["field"] == "processing.start[0]"


def test_a_batch_to_a_session_deleted_while_the_batch_is_checked_is_a_404_and_nothing_is_stored(env, monkeypatch):
    """A DELETE of the session between the batch route's lookup of it and the batch's insert (a phone uploading while
    its user deletes the session) was a 500: the insert's foreign key failed, and the store took that for a replay
    of a batch it then did not find (AssertionError). It is the 404 of a session that is no more."""
    from server import plausibility

    app, c, h, _ = env
    sid = c.post("/api/v1/sessions", json={"session_id": "going"}, headers=h).get_json()["id"]
    check = plausibility.check_batch

    def deleted_meanwhile(*args: Any, **kwargs: Any) -> None:
        check(*args, **kwargs)
        app.extensions["pdr"].store.delete_session(sid)

    monkeypatch.setattr(plausibility, "check_batch", deleted_meanwhile)
    r = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("late", 0.0), headers=h)
    assert r.status_code == 404 and "no session" in r.get_json()["error"]["message"], r.get_data()[:300]
    assert [s["id"] for s in c.get("/api/v1/sessions", headers=h).get_json()["sessions"]] == [env[3]]
    with app.extensions["pdr"].store.engine.connect() as conn:
        from server import db
        assert conn.execute(db.batches.select().where(db.batches.c.session_id == sid)).first() is None


def test_a_session_created_for_a_user_deleted_meanwhile_is_a_401_at_once(env, monkeypatch):
    """A user deleted (pdr users delete) between a request's authentication and its session's insert: the insert's
    foreign key failed, which the store took for the same key stored meanwhile by another request and tried again,
    without end, each try holding a database connection: the request hung 30 s with every other request waiting for a
    connection, then was a 503 'retry later'. It is a 401 at once, and nothing is stored."""
    from sqlalchemy import delete, func, select

    from server import db
    from server.store import Store

    app, c, h, _ = env
    create = Store.create_session

    tries: list[int] = []

    def user_deleted_meanwhile(self: Store, user_id: int, **kwargs: Any) -> tuple[str, bool]:
        tries.append(user_id)              # the store's retry comes back through here
        with self.engine.begin() as conn:
            conn.execute(delete(db.users).where(db.users.c.id == user_id))
        return create(self, user_id, **kwargs)

    monkeypatch.setattr(Store, "create_session", user_deleted_meanwhile)
    r = c.post("/api/v1/sessions", json={"session_id": "orphan"}, headers=h)
    assert r.status_code == 401 and "deleted" in r.get_json()["error"]["message"], r.get_data()[:300]
    assert len(tries) == 1                 # refused at the first failed insert, not tried again
    with app.extensions["pdr"].store.engine.connect() as conn:
        assert conn.execute(select(func.count()).select_from(db.sessions)).scalar() == 0


def test_the_first_batches_of_a_session_sent_at_once_are_all_taken(env):
    """A phone sending its first two batches at once (a retry and the next one, four threads on a real pdr serve):
    both requests found no device of the session yet, both inserted it, and the second insert broke the devices'
    (session, role) key: a 500 for a batch that had been stored. Here the other request's insert is made to land
    between this one's lookup and its insert; the batch is answered 201 and the session has its one phone."""
    from sqlalchemy import event, insert

    from server import db

    app, c, h, _ = env
    sid = c.post("/api/v1/sessions", json={"session_id": "at-once"}, headers=h).get_json()["id"]
    engine = app.extensions["pdr"].store.engine
    raced: list[bool] = []

    def other_request_first(conn: Any, cursor: Any, statement: str, *args: Any) -> None:
        if statement.startswith("INSERT INTO devices") and not raced:
            raced.append(True)
            with engine.begin() as other:
                other.execute(insert(db.devices).values(session_id=sid, role="phone", device_id="", platform="android",
                                                        model="test"))

    event.listen(engine, "before_cursor_execute", other_request_first)
    try:
        r = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("first", 0.0), headers=h)
    finally:
        event.remove(engine, "before_cursor_execute", other_request_first)
    assert raced and r.status_code == 201, r.get_data()[:300]
    detail = c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert [(d["role"], d["model"]) for d in detail["devices"]] == [("phone", "test")]
    assert [b["batch_id"] for b in detail["batch_list"]] == ["first"]
