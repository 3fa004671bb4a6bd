"""The PostgreSQL path (migrations, ingest, processing, reads) against a real server when one is reachable.

The database comes from the ``pg_database`` fixture of :mod:`tests.server.realservers` (skipped cleanly
when no server can be reached).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from flask import Flask

from server import auth
from tests.server.conftest import bearer, make_app
from tests.server.helpers import multipart, phone_batch
from tests.server.realservers import pg_database  # noqa: F401  (fixture)
from tests.server.test_upload_names import _ms_trace


@contextmanager
def pg_app(tmp_path: Path, database_url: str) -> Iterator[tuple[Flask, dict[str, str]]]:
    """The app on the PostgreSQL database with one user, and that user's authorisation header; stopped after."""
    app = make_app(tmp_path, database_url=database_url)
    try:
        with app.extensions["pdr"].store.engine.begin() as conn:
            h = bearer(auth.add_user(conn, "pg-user"))
        yield app, h
    finally:
        app.extensions["pdr"].worker.stop()
        app.extensions["pdr"].store.engine.dispose()


def test_postgres_ingest_process_read(tmp_path, pg_database):  # noqa: F811
    with pg_app(tmp_path, pg_database) as (app, h):
        svc = app.extensions["pdr"]
        assert svc.settings.database_url.startswith("postgresql+psycopg://")
        c = app.test_client()
        sid = c.post("/api/v1/sessions", json={"session_id": "pg-walk"}, headers=h).get_json()["id"]
        for i in (0, 2, 1):
            resp = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
            assert resp.status_code == 201
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 1.0), headers=h).status_code == 200
        svc.worker.wait_idle()
        pts = c.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
        assert [p["east_m"] for p in pts] == [1.0, 2.0, 3.0]
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 9.0), headers=h).status_code == 409


def test_postgres_stores_an_uploaded_file_of_a_long_name_and_refuses_overlong_keys_with_a_4xx(tmp_path,
                                                                                            pg_database):  # noqa: F811
    """In PostgreSQL, which enforces VARCHAR lengths (SQLite does not): a log file named
    'a_rather_long_recording_name_from_my_phone.json' was a 500 (its 'file:native/NAME' over batches.payload_format's
    40 characters) and left an empty session behind, whose key then refused the retry (409); it is stored now. A form
    session_id of 300 characters, and a Sensor Logger messageId of 250 (its batch id 'msg-ID' over 200), were 500s:
    now a 422 naming the field and a 499 naming it, with nothing stored."""
    with pg_app(tmp_path, pg_database) as (app, h):
        c = app.test_client()
        log = json.dumps(phone_batch("f", 0.0, duration_s=2.0)).encode()
        body, ctype = multipart({"file": (log, "a_rather_long_recording_name_from_my_phone.json")})
        resp = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
        assert resp.status_code == 201, resp.get_data()[:300]
        (batch,) = c.get(f"/api/v1/sessions/{resp.get_json()['id']}", headers=h).get_json()["batch_list"]
        assert batch["format"] == "file:native/a_rather_long_recording_name_from_my_phone.json"

        body, ctype = multipart({"file": (log, "walk.json"), "session_id": "s" * 300})
        resp = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
        assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "session_id"
        message = {"messageId": "m" * 250, "sessionId": "sl", "deviceId": "d", "payload": [
            {"name": "accelerometer", "time": 1_700_000_000_000_000_000 + i * 10_000_000,
             "values": {"x": 0.0, "y": 0.0, "z": 9.81}} for i in range(3)]}
        resp = c.post("/api/v1/ingest/sensor-logger", json=message, headers=h)
        assert resp.status_code == 499 and "messageId" in resp.get_data(as_text=True), resp.get_data()[:300]
        assert len(c.get("/api/v1/sessions", headers=h).get_json()["sessions"]) == 1


def test_postgres_refuses_text_it_cannot_store_with_a_4xx_naming_the_field(tmp_path, pg_database):  # noqa: F811
    """PostgreSQL refuses a NUL character in text (SQLite stores it): a session's name "a\\u0000b", a Sensor Logger
    deviceId, a group's name and a site file's name field holding one were 500s, and so was a log file whose header
    names a phone model of 201 characters (over devices.model's 200). Each is a 422 (the app's 499) naming the field,
    with nothing stored. A Sensor Logger sessionId of 200 characters (the most it may have) was a 500, its
    session's name 'Sensor Logger ID' over the 200 of sessions.name: the name is cut there. So were GET
    /api/v1/sessions/a%00b and a group's tracks of agent a%00b: a 400 naming the parameter."""
    with pg_app(tmp_path, pg_database) as (app, h):
        svc = app.extensions["pdr"]
        c = app.test_client()
        resp = c.post("/api/v1/sessions", json={"session_id": "nul", "name": "a\x00b"}, headers=h)
        assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "name", resp.get_data()
        message = {"messageId": 1, "sessionId": "sl", "deviceId": "phone\x00", "payload": [
            {"name": "accelerometer", "time": 1_700_000_000_000_000_000 + i * 10_000_000,
             "values": {"x": 0.0, "y": 0.0, "z": 9.81}} for i in range(3)]}
        resp = c.post("/api/v1/ingest/sensor-logger", json=message, headers=h)
        assert resp.status_code == 499 and "deviceId" in resp.get_data(as_text=True), resp.get_data()[:300]
        resp = c.post("/api/v1/ingest/sensor-logger", json=message | {"sessionId": "s" * 200, "deviceId": "d"},
                      headers=h)
        assert resp.status_code == 200, resp.get_data()[:300]
        (session,) = c.get("/api/v1/sessions", headers=h).get_json()["sessions"]
        assert session["session_id"] == "s" * 200 and len(session["name"]) == 200
        svc.store.delete_session(session["id"])
        resp = c.post("/api/v1/groups", json={"name": "team\x00"}, headers=h)
        assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "name", resp.get_data()
        body, ctype = multipart({"file": (b'{"floors": [{"floor": 0, "walkable": {"type": "Polygon", "coordinates": '
                                          b'[[[0, 0], [9, 0], [9, 9], [0, 9], [0, 0]]]}}]}', "hall.json"),
                                 "name": "hall\x00"})
        resp = c.post("/api/v1/sites", data=body, content_type=ctype, headers=h)
        assert resp.status_code == 422 and resp.get_json()["error"]["details"]["field"] == "name", resp.get_data()
        body, ctype = multipart({"file": (_ms_trace(b"M" * 201), "trace.txt")})
        resp = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
        assert resp.status_code == 422 and resp.get_json()["error"]["details"]["device"] == "model", resp.get_data()
        assert c.get("/api/v1/sessions", headers=h).get_json()["sessions"] == []
        assert c.get("/api/v1/groups", headers=h).get_json()["groups"] == []
        assert c.get("/api/v1/sites", headers=h).get_json()["sites"] == []

        group = c.post("/api/v1/groups", json={"name": "team"}, headers=h).get_json()["id"]
        for url, field in [("/api/v1/sessions/a%00b", "session_id"), ("/api/v1/sites/a%00b", "site_id"),
                           (f"/api/v1/groups/{group}/tracks?agent=a%00b", "agent")]:
            resp = c.get(url, headers=h)
            assert resp.status_code == 400 and resp.get_json()["error"]["details"]["field"] == field, url


def test_postgres_a_session_created_for_a_user_deleted_meanwhile_is_a_401_at_once(tmp_path, pg_database,  # noqa: F811
                                                                                   monkeypatch):
    """The user deleted between authentication and the session's insert: the foreign key's refusal was retried
    without end, each try holding a pooled connection, and the request hung 30 s, then was a 503 (tests/server/
    test_hostile_input.py does the same on SQLite)."""
    from sqlalchemy import delete

    from server import db
    from server.store import Store

    with pg_app(tmp_path, pg_database) as (app, h):
        create = Store.create_session
        tries: list[int] = []

        def user_deleted_meanwhile(self: Store, user_id: int, **kwargs: object) -> tuple[str, bool]:
            tries.append(user_id)          # the store's retry comes back through here
            with self.engine.begin() as conn:
                conn.execute(delete(db.users).where(db.users.c.id == user_id))
            return create(self, user_id, **kwargs)  # type: ignore[arg-type]

        monkeypatch.setattr(Store, "create_session", user_deleted_meanwhile)
        resp = app.test_client().post("/api/v1/sessions", json={"session_id": "orphan"}, headers=h)
        assert resp.status_code == 401 and len(tries) == 1, resp.get_data()[:300]   # refused at once, not retried
