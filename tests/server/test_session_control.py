"""Control requests (DELETE, reprocess, PUT .../processing) while a processing pass of the session is running, in the
embedded mode (the in-process worker) and in the scale-out mode (PostgreSQL, a worker runtime under its lease).

A processor that holds its pass open until the test releases it: each request must be answered while the pass is
held (the processor records whether its wait ran out instead), and the pass must then write nothing stale.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest
from flask import Flask
from flask.testing import FlaskClient

from server import db
from server.leases import Leases
from server.processing import SessionContext
from server.queue import WorkerRuntime
from tests.server.conftest import CountingProcessor, bearer, make_app
from tests.server.helpers import phone_batch
from tests.server.realservers import pg_database  # noqa: F401  (fixture)
from tests.server.test_scaleout import FakeQueue

#: Longest a held pass waits for the test, s: a request that waited for the pass would be answered only then.
HOLD_S = 60.0


class Gate:
    """Holds the processing of the batches named in ``hold`` until :meth:`release`."""

    def __init__(self) -> None:
        self.hold: set[str] = set()
        self.entered = threading.Event()
        self.released = threading.Event()
        self.ran_out = False

    def wait(self) -> None:
        self.entered.set()
        if not self.released.wait(HOLD_S):
            self.ran_out = True

    def release(self) -> None:
        self.released.set()


GATE = Gate()


class GatedProcessor(CountingProcessor):
    """:class:`CountingProcessor` whose rows have north_m 1 with the option ``foot.zaru`` (0 without), and whose
    update waits at :data:`GATE` for a batch whose first sample is at a time (s after the batches' origin) in
    ``GATE.hold``.
    """

    def __init__(self, ctx: SessionContext, state: bytes | None) -> None:
        super().__init__(ctx, state)
        self.north_m = 1.0 if ctx.meta.get("processing", {}).get("foot", {}).get("zaru") else 0.0

    def update(self, recording: Any) -> Any:
        first_s = round(min(int(s.t_ns[0]) for s in recording.streams.values()) / 1e9 - 1_700_000_000)
        if str(first_s) in GATE.hold:
            GATE.hold.discard(str(first_s))
            GATE.wait()
        out = super().update(recording)
        out.track = [replace(row, north_m=self.north_m) for row in out.track]
        return out


@pytest.fixture
def gated(tmp_path: Any) -> Iterator[tuple[Flask, FlaskClient, dict[str, str]]]:
    global GATE
    GATE = Gate()
    app = make_app(tmp_path, processor_factory=GatedProcessor)
    from server import auth
    with app.extensions["pdr"].store.engine.begin() as conn:
        h = bearer(auth.add_user(conn, "alice"))
    yield app, app.test_client(), h
    GATE.release()
    app.extensions["pdr"].worker.stop()


def _session(client: FlaskClient, h: dict[str, str], key: str, **body: Any) -> str:
    resp = client.post("/api/v1/sessions", json={"session_id": key, **body}, headers=h)
    assert resp.status_code == 201, resp.get_data()[:300]
    return str(resp.get_json()["id"])


def _upload(client: FlaskClient, h: dict[str, str], sid: str, *starts: int) -> None:
    for i in starts:
        resp = client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)), headers=h)
        assert resp.status_code == 201, resp.get_data()[:300]


def _held(app: Flask) -> None:
    """Wait until the worker's pass is held at the gate."""
    assert GATE.entered.wait(HOLD_S), "the worker never reached the held batch"


def _rows_of(app: Flask, sid: str) -> dict[str, int]:
    """How many rows each table holds for the session."""
    tables = (db.batches, db.track_points, db.events, db.processor_states, db.devices, db.session_leases)
    with app.extensions["pdr"].store.engine.connect() as conn:
        count = {t.name: len(list(conn.execute(t.select().where(t.c.session_id == sid)))) for t in tables}
        return count | {"sessions": len(list(conn.execute(db.sessions.select().where(db.sessions.c.id == sid))))}


def _track(client: FlaskClient, h: dict[str, str], sid: str) -> list[tuple[float, float]]:
    resp = client.get(f"/api/v1/sessions/{sid}/track", headers=h)
    assert resp.status_code == 200, resp.get_data()[:300]
    return [(p["east_m"], p["north_m"]) for p in resp.get_json()["points"]]


def test_delete_during_a_pass_is_answered_at_once_and_the_pass_writes_nothing_back(gated, caplog):
    app, client, h = gated
    sid = _session(client, h, "walk", device={"role": "phone"})
    GATE.hold.add("1")
    _upload(client, h, sid, 0, 1, 2)
    _held(app)                                            # b0 committed, b1 held, b2 pending

    resp = client.delete(f"/api/v1/sessions/{sid}", headers=h)
    assert resp.status_code == 204, resp.get_data()[:300]
    assert not GATE.ran_out                               # answered while the pass was held
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).status_code == 404
    assert set(_rows_of(app, sid).values()) == {0}        # the batches and b0's results went with it

    GATE.release()
    assert app.extensions["pdr"].worker.wait_idle()
    assert set(_rows_of(app, sid).values()) == {0}        # b1's results were not written, b2 not processed
    assert not [r for r in caplog.records if r.levelname == "ERROR"]   # the pass stopped, nothing failed
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).status_code == 404
    assert client.get("/api/v1/sessions", headers=h).get_json()["sessions"] == []
    resp = client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b9", 9.0), headers=h)
    assert resp.status_code == 404                        # the session does not come back

    other = _session(client, h, "next")                   # the worker goes on with other sessions
    _upload(client, h, other, 0)
    assert app.extensions["pdr"].worker.wait_idle()
    assert _track(client, h, other) == [(1.0, 0.0)]


def test_reprocess_during_a_pass_is_answered_at_once_and_rebuilds_everything_accepted(gated):
    app, client, h = gated
    sid = _session(client, h, "walk")
    _upload(client, h, sid, 0, 1)
    assert app.extensions["pdr"].worker.wait_idle()
    GATE.hold.add("2")
    _upload(client, h, sid, 2, 3)
    _held(app)                                            # b2 held, b3 pending

    resp = client.post(f"/api/v1/sessions/{sid}/reprocess", headers=h)
    assert resp.status_code == 202 and resp.get_json() == {"id": sid, "status": "pending"}, resp.get_data()[:300]
    assert not GATE.ran_out
    _upload(client, h, sid, 4)                            # the phone goes on streaming meanwhile

    GATE.release()
    assert app.extensions["pdr"].worker.wait_idle()
    # One rebuild of every accepted batch in time order (a count of 1..5): no row of the pass begun before it.
    assert _track(client, h, sid) == [(float(n), 0.0) for n in range(1, 6)]
    session = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert session["status"] == "done" and session["batches"] == {"done": 5} and not session["rebuilding"]


def test_new_processing_options_during_a_pass_are_answered_at_once_and_applied_to_every_batch(gated):
    app, client, h = gated
    sid = _session(client, h, "walk")
    GATE.hold.add("0")
    _upload(client, h, sid, 0, 1)
    _held(app)                   # b0 held by a processor made with the old options; b1 next in the same pass

    resp = client.put(f"/api/v1/sessions/{sid}/processing", json={"foot": {"zaru": True}}, headers=h)
    assert resp.status_code == 202, resp.get_data()[:300]
    assert resp.get_json() == {"id": sid, "status": "pending", "processing": {"foot": {"zaru": True}}}
    assert not GATE.ran_out

    GATE.release()
    assert app.extensions["pdr"].worker.wait_idle()
    # Nothing the pass begun with the old options computed is kept: both batches with the new ones, counted once.
    assert _track(client, h, sid) == [(1.0, 1.0), (2.0, 1.0)]
    session = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert session["status"] == "done" and session["batches"] == {"done": 2} and not session["rebuilding"]
    assert session["processing"] == {"foot": {"zaru": True}}
    with app.extensions["pdr"].store.engine.connect() as conn:
        states = list(conn.execute(db.processor_states.select().where(db.processor_states.c.session_id == sid)))
    assert [json.loads(s.state) for s in states] == [{"count": 2}]


def test_control_requests_reach_a_worker_of_the_scale_out_mode_mid_pass(tmp_path, pg_database):  # noqa: F811
    """PostgreSQL, web process without a worker, a ``pdr worker`` runtime (under its session lease) in a thread: the
    web process's requests are answered while the worker's pass is held, and the worker applies them.
    """
    global GATE
    GATE = Gate()
    app = make_app(tmp_path, database_url=pg_database, worker="none", processor_factory=GatedProcessor)
    svc = app.extensions["pdr"]
    try:
        from server import auth
        with svc.store.engine.begin() as conn:
            h = bearer(auth.add_user(conn, "alice"))
        client = app.test_client()
        runtime = WorkerRuntime(svc.processing, Leases(svc.store.engine, "w1"), FakeQueue())  # type: ignore[arg-type]

        def run(sid: str) -> tuple[threading.Thread, list[str]]:
            answers: list[str] = []
            thread = threading.Thread(target=lambda: answers.append(runtime.run_session(sid)), daemon=True)
            thread.start()
            return thread, answers

        kept = _session(client, h, "kept")
        GATE.hold.add("0")
        _upload(client, h, kept, 0, 1)
        thread, answers = run(kept)
        _held(app)
        resp = client.put(f"/api/v1/sessions/{kept}/processing", json={"foot": {"zaru": True}}, headers=h)
        assert resp.status_code == 202 and not GATE.ran_out, resp.get_data()[:300]
        GATE.release()
        thread.join(HOLD_S)
        assert answers == ["done"]
        assert _track(client, h, kept) == [(1.0, 1.0), (2.0, 1.0)]

        GATE = Gate()
        gone = _session(client, h, "gone")
        GATE.hold.add("0")
        _upload(client, h, gone, 0, 1)
        thread, answers = run(gone)
        _held(app)
        assert client.delete(f"/api/v1/sessions/{gone}", headers=h).status_code == 204 and not GATE.ran_out
        GATE.release()
        thread.join(HOLD_S)
        assert answers == ["done"]
        assert set(_rows_of(app, gone).values()) == {0}
        assert [s["id"] for s in client.get("/api/v1/sessions", headers=h).get_json()["sessions"]] == [kept]
    finally:
        GATE.release()
        svc.worker.stop()
        svc.store.engine.dispose()
