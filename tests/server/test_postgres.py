"""The PostgreSQL path (migrations, ingest, processing, reads) against a real server when one is reachable.

The database comes from the ``pg_database`` fixture of :mod:`tests.server.realservers` (skipped cleanly
when no server can be reached).
"""

from __future__ import annotations

from server import auth
from tests.server.conftest import bearer, make_app
from tests.server.helpers import phone_batch
from tests.server.realservers import pg_database  # noqa: F401  (fixture)


def test_postgres_ingest_process_read(tmp_path, pg_database):  # noqa: F811
    pg_url = pg_database
    app = make_app(tmp_path, database_url=pg_url)
    try:
        svc = app.extensions["pdr"]
        assert svc.settings.database_url.startswith("postgresql+psycopg://")
        with svc.store.engine.begin() as conn:
            token = auth.add_user(conn, "pg-user")
        c = app.test_client()
        h = bearer(token)
        sid = c.post("/api/v1/sessions", json={"session_id": "pg-walk"}, headers=h).get_json()["id"]
        for i in (0, 2, 1):
            resp = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
            assert resp.status_code == 201
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 1.0), headers=h).status_code == 200
        svc.worker.wait_idle()
        pts = c.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
        assert [p["east_m"] for p in pts] == [1.0, 2.0, 3.0]
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b1", 9.0), headers=h).status_code == 409
    finally:
        app.extensions["pdr"].worker.stop()
        app.extensions["pdr"].store.engine.dispose()
