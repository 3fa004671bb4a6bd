"""Ingest and processing: durability, idempotency, time order, rebuilds, failures, access control."""

from __future__ import annotations

import json

import numpy as np
from flask.testing import FlaskClient

from tests.server.conftest import bearer, make_app
from tests.server.helpers import phone_batch


def _new_session(client: FlaskClient, token: str, name: str = "walk") -> str:
    return client.post("/api/v1/sessions", json={"session_id": name}, headers=bearer(token)).get_json()["id"]


def _track(client: FlaskClient, sid: str, token: str) -> list[dict]:
    return client.get(f"/api/v1/sessions/{sid}/track", headers=bearer(token)).get_json()["points"]


def test_batches_processed_in_time_order_even_when_sent_out_of_order(app, client, tokens):
    h = bearer(tokens["alice"])
    sid = _new_session(client, tokens["alice"])
    for i in (0, 1, 2):
        resp = client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
        assert resp.status_code == 201
    app.extensions["pdr"].worker.wait_idle()
    in_order = _track(client, sid, tokens["alice"])
    assert [p["east_m"] for p in in_order] == [1.0, 2.0, 3.0]

    # A late batch from before everything processed so far: the session is rebuilt in time order.
    sid2 = _new_session(client, tokens["alice"], "walk-2")
    for i in (0, 2, 1):
        client.post(f"/api/v1/sessions/{sid2}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
        app.extensions["pdr"].worker.wait_idle()
    assert _track(client, sid2, tokens["alice"]) == in_order


def test_a_stream_sent_a_batch_late_does_not_rebuild_the_session_at_every_batch(app, client, tokens, monkeypatch):
    # A phone that sends its gyroscope one batch late: every batch starts (its gyroscope) before the end of the last
    # one (its accelerometer). Before, each such batch was taken as out of order and rebuilt the whole session from
    # its raw batches (a cost growing with the session at every batch); now they go on in arrival order. A batch that
    # ends before what was processed still rebuilds.
    from pdr.io.native import batch_to_json
    from pdr.recording import DeviceInfo, Recording, SensorStream

    def batch(i: int, gyro_from: float) -> dict:
        t0 = 1_700_000_000_000_000_000
        acc_t = (t0 + np.round((i + np.arange(50) / 50) * 1e9)).astype(np.int64)
        gyro_t = (t0 + np.round((gyro_from + np.arange(50) / 50) * 1e9)).astype(np.int64)
        rec = Recording({"acc": SensorStream("acc", acc_t, np.tile([0.0, 0.0, 9.81], (50, 1))),
                         "gyro": SensorStream("gyro", gyro_t, np.zeros((50, 3)))}, DeviceInfo(role="phone"))
        return batch_to_json(rec, session_id="s1", batch_id=f"b{i}")

    rebuilds: list[str] = []
    store = app.extensions["pdr"].store
    clear = store.clear_results

    def counted(session_id: str) -> None:
        rebuilds.append(session_id)
        clear(session_id)

    monkeypatch.setattr(store, "clear_results", counted)
    h = bearer(tokens["alice"])
    sid = _new_session(client, tokens["alice"])
    for i in range(1, 6):
        assert client.post(f"/api/v1/sessions/{sid}/batches", json=batch(i, i - 1.0), headers=h).status_code == 201
        app.extensions["pdr"].worker.wait_idle()
    assert rebuilds == [] and [p["east_m"] for p in _track(client, sid, tokens["alice"])] == [1.0, 2.0, 3.0, 4.0, 5.0]
    client.post(f"/api/v1/sessions/{sid}/batches", json=batch(0, 0.0), headers=h)   # from before all of them
    app.extensions["pdr"].worker.wait_idle()
    assert rebuilds == [sid] and len(_track(client, sid, tokens["alice"])) == 6


def test_reprocess_gives_identical_results(app, client, tokens):
    h = bearer(tokens["alice"])
    sid = _new_session(client, tokens["alice"])
    for i in range(4):
        client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
    app.extensions["pdr"].worker.wait_idle()
    before = _track(client, sid, tokens["alice"])
    steps_before = client.get(f"/api/v1/sessions/{sid}/steps", headers=h).get_json()["steps"]
    assert client.post(f"/api/v1/sessions/{sid}/reprocess", headers=h).status_code == 202
    app.extensions["pdr"].worker.wait_idle()
    assert _track(client, sid, tokens["alice"]) == before
    assert client.get(f"/api/v1/sessions/{sid}/steps", headers=h).get_json()["steps"] == steps_before


def test_since_returns_only_new_rows(app, client, tokens):
    h = bearer(tokens["alice"])
    sid = _new_session(client, tokens["alice"])
    for i in range(3):
        client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
    app.extensions["pdr"].worker.wait_idle()
    full = client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()
    later = client.get(f"/api/v1/sessions/{sid}/track?since={full['points'][0]['t_s']}", headers=h).get_json()
    assert later["points"] == full["points"][1:]
    csv_text = client.get(f"/api/v1/sessions/{sid}/track?format=csv", headers=h).get_data(as_text=True)
    assert csv_text.splitlines()[0] == "t_s,east_m,north_m,up_m,floor,heading_deg,step_length_m,mode,device"
    assert len(csv_text.splitlines()) == 4


def test_geojson_is_rfc_7946_lon_lat_of_a_geo_referenced_session_only(app, client, tokens):
    """Local metres once went out as "coordinates", which GIS tools read as degrees: without an origin the answer
    is 409; with one, lon/lat, a LineString of two or more positions or a Point for one step."""
    from pdr.frames import geodetic_to_local_enu
    from tests.geojson_rfc7946 import check_rfc7946

    h = bearer(tokens["alice"])
    local = _new_session(client, tokens["alice"], "local")
    client.post(f"/api/v1/sessions/{local}/batches", json=phone_batch("b0", 0.0), headers=h)
    geo = client.post("/api/v1/sessions", json={"session_id": "geo", "origin": {"lat_deg": 51.5, "lon_deg": -0.12}},
                      headers=h).get_json()["id"]
    client.post(f"/api/v1/sessions/{geo}/batches", json=phone_batch("b0", 0.0), headers=h)
    app.extensions["pdr"].worker.wait_idle()
    r = client.get(f"/api/v1/sessions/{local}/track?format=geojson", headers=h)
    assert r.status_code == 409 and r.get_json()["error"]["code"] == "not_geo_referenced"
    assert "not geo-referenced" in r.get_json()["error"]["message"]
    one = json.loads(client.get(f"/api/v1/sessions/{geo}/track?format=geojson", headers=h).data)
    check_rfc7946(one)
    assert one["features"][0]["geometry"]["type"] == "Point"  # one step: no one-position LineString
    for i in (1, 2):
        client.post(f"/api/v1/sessions/{geo}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
    app.extensions["pdr"].worker.wait_idle()
    r = client.get(f"/api/v1/sessions/{geo}/track?format=geojson", headers=h)
    assert r.mimetype == "application/geo+json"
    doc = json.loads(r.data)
    check_rfc7946(doc)
    (line,) = doc["features"]
    assert line["geometry"]["type"] == "LineString" and line["properties"]["device"] == "phone"
    lon, lat = np.array(line["geometry"]["coordinates"]).T
    np.testing.assert_allclose(geodetic_to_local_enu(lat, lon, 51.5, -0.12), [[1, 0], [2, 0], [3, 0]], atol=0.02)


def test_processing_failure_keeps_raw_batch_and_is_visible(tmp_path, tokens):  # noqa: ARG001
    class Broken:
        def __init__(self, ctx, state):  # noqa: ANN001
            pass

        def update(self, recording):  # noqa: ANN001
            raise RuntimeError("algorithm bug")

        def to_bytes(self) -> bytes:
            return b""

    app = make_app(tmp_path / "broken", processor_factory=Broken)
    try:
        from server import auth
        with app.extensions["pdr"].store.engine.begin() as conn:
            token = auth.add_user(conn, "carol")
        c = app.test_client()
        sid = _new_session(c, token)
        resp = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b0", 0.0), headers=bearer(token))
        assert resp.status_code == 201
        app.extensions["pdr"].worker.wait_idle()
        detail = c.get(f"/api/v1/sessions/{sid}", headers=bearer(token)).get_json()
        assert detail["status"] == "failed"
        assert "algorithm bug" in detail["batch_list"][0]["error"]
        from sqlalchemy import select

        from server import db
        with app.extensions["pdr"].store.engine.connect() as conn:  # raw data kept, and what was decoded at ingest
            row = conn.execute(select(db.batches.c.payload, db.batches.c.decoded)).one()
        assert row.payload and row.decoded
    finally:
        app.extensions["pdr"].worker.stop()


def test_accepted_batches_survive_restart_and_are_processed(tmp_path):
    from server import auth

    first = make_app(tmp_path, worker="none")  # accepts and stores, processes nothing
    with first.extensions["pdr"].store.engine.begin() as conn:
        token = auth.add_user(conn, "dave")
    c = first.test_client()
    sid = _new_session(c, token)
    for i in range(3):
        c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=bearer(token))
    first.extensions["pdr"].store.engine.dispose()

    second = make_app(tmp_path)  # same data directory: the pending batches are recovered and processed
    try:
        second.extensions["pdr"].worker.wait_idle()
        pts = _track(second.test_client(), sid, token)
        assert [p["east_m"] for p in pts] == [1.0, 2.0, 3.0]
    finally:
        second.extensions["pdr"].worker.stop()


def test_devices_pairing_and_listing(client, tokens):
    h = bearer(tokens["alice"])
    sid = _new_session(client, tokens["alice"])
    resp = client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "left_foot", "model": "MTw"}, headers=h)
    assert resp.status_code == 201
    roles = [d["role"] for d in resp.get_json()["devices"]]
    assert roles == ["left_foot"]
    listing = client.get("/api/v1/sessions", headers=h).get_json()["sessions"]
    assert [s["id"] for s in listing] == [sid] and listing[0]["session_id"] == "walk"


def test_processor_states_are_stored_as_written_and_older_zlib_rows_still_load():
    import zlib

    from pdr import state_codec
    from server.store import unpack_state

    state = state_codec.dumps({"a": [1.5, 2.5]})
    assert unpack_state(state) == state
    assert unpack_state(b'{"navigator": null}') == b'{"navigator": null}'
    assert unpack_state(zlib.compress(state, 6)) == state  # a row written before states were stored raw


def test_a_sessions_lock_is_shared_while_held_and_forgotten_after() -> None:
    """One processing pass per session at a time, without a lock kept for every session a long-running server saw."""
    import gc
    import threading

    from server.processing import SessionLocks

    locks = SessionLocks()
    held = locks.get("s1")
    assert locks.get("s1") is held and locks.get("s2") is not held
    with held:
        waiter_got: list[bool] = []
        t = threading.Thread(target=lambda: waiter_got.append(locks.get("s1").acquire(timeout=0)))
        t.start()
        t.join()
        assert waiter_got == [False]            # the same lock: taken while the pass holds it
    del held
    gc.collect()
    assert len(locks._locks) == 0
