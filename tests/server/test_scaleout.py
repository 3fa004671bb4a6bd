"""Scale-out pieces in one process: leases, retries, dead letters, reconciler, RQ jobs, quota, degraded answers.

Leases and the worker runtime run on SQLite (the code is plain SQL); the RQ tests use the real Redis of
the machine in a namespace of their own (skipped when Redis is absent).
"""

from __future__ import annotations

import json
from datetime import timedelta
from typing import Any

import pytest
from sqlalchemy import exc as sa_exc
from sqlalchemy import select, update

from pdr.recording import Recording
from server import auth, db
from server.config import load_settings
from server.leases import LeaseLost, Leases
from server.processing import ProcessorOutput, SessionContext
from server.queue import RetryPolicy, WorkerRuntime
from tests.server.conftest import CountingProcessor, bearer, make_app
from tests.server.helpers import phone_batch
from tests.server.realservers import redis_namespace  # noqa: F401  (fixture)


class FakeQueue:
    """Stands in for :class:`server.queue.SessionQueue` where Redis is not the subject."""

    def __init__(self) -> None:
        self.enqueued: list[str] = []
        self.reports: list[str] = []

    def enqueue(self, session_id: str, verify: bool = False) -> bool:
        self.enqueued.append(session_id)
        return True

    def enqueue_report(self, report_id: str, verify: bool = False) -> bool:
        self.reports.append(report_id)
        return True


def _setup(tmp_path: Any, factory: Any = CountingProcessor, **cfg: Any) -> tuple[Any, Any, dict[str, str]]:
    app = make_app(tmp_path, worker="none", processor_factory=factory, **cfg)
    with app.extensions["pdr"].store.engine.begin() as conn:
        token = auth.add_user(conn, "ann")
    return app, app.test_client(), bearer(token)


def _session_with_batches(c: Any, h: dict[str, str], starts: list[float], name: str = "walk") -> str:
    sid = c.post("/api/v1/sessions", json={"session_id": name}, headers=h).get_json()["id"]
    for i, start in enumerate(starts):
        assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", start), headers=h).status_code == 201
    return sid


def _runtime(app: Any, owner: str = "w1", max_attempts: int = 5, sleeps: list[float] | None = None) -> WorkerRuntime:
    svc = app.extensions["pdr"]
    record = sleeps if sleeps is not None else []
    return WorkerRuntime(svc.processing, Leases(svc.store.engine, owner, ttl_s=30.0, max_attempts=max_attempts),
                         FakeQueue(), RetryPolicy(retries=4, first_s=0.5), sleep=record.append)  # type: ignore[arg-type]


def _east(c: Any, sid: str, h: dict[str, str]) -> list[float]:
    return [p["east_m"] for p in c.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]]


def test_settings_accept_redis_worker_and_reject_unknown():
    s = load_settings(environ={"PDR_WORKER": "redis", "REDIS_URL": "redis://h:1/2", "PDR_DATA_QUOTA_MB": "1.5"})
    assert (s.worker, s.redis_url, s.data_quota_bytes) == ("redis", "redis://h:1/2", int(1.5 * 2**20))
    with pytest.raises(ValueError, match="PDR_WORKER must be"):
        load_settings(environ={"PDR_WORKER": "celery"})


def test_lease_excludes_other_workers_until_released_or_expired(tmp_path):
    app, c, h = _setup(tmp_path)
    sid = _session_with_batches(c, h, [0.0])
    engine = app.extensions["pdr"].store.engine
    a, b = Leases(engine, "a", ttl_s=30), Leases(engine, "b", ttl_s=30)
    assert a.claim(sid) and a.claim(sid)  # re-entrant for its owner
    assert not b.claim(sid)
    assert a.renew(sid) and not b.renew(sid)
    a.release(sid)
    assert b.claim(sid) and not a.claim(sid)
    with engine.begin() as conn:  # b dies: its lease runs out
        conn.execute(update(db.session_leases).values(expires_at=db.utcnow() - timedelta(seconds=1)))
    assert sid in a.orphaned_sessions()
    assert a.claim(sid)
    with engine.begin() as conn, pytest.raises(LeaseLost):
        b.check(sid, conn)
    assert a.orphaned_sessions() == []


def test_runtime_processes_in_time_order_and_reports_busy(tmp_path):
    app, c, h = _setup(tmp_path)
    sid = _session_with_batches(c, h, [2.0, 0.0, 1.0])
    rt = _runtime(app)
    assert Leases(app.extensions["pdr"].store.engine, "other").claim(sid)
    assert rt.run_session(sid) == "busy"
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["batches"] == {"pending": 3}
    Leases(app.extensions["pdr"].store.engine, "other").release(sid)
    assert rt.run_session(sid) == "done"
    assert _east(c, sid, h) == [1.0, 2.0, 3.0]
    with app.extensions["pdr"].store.engine.connect() as conn:
        assert conn.execute(select(db.session_leases)).first() is None  # released


class Flaky:
    """A processor factory whose processors raise a lost-connection error for the first ``failures`` updates."""

    def __init__(self, failures: int) -> None:
        self.failures = failures

    def __call__(self, ctx: SessionContext, state: bytes | None) -> Any:
        outer = self

        class P(CountingProcessor):
            def update(self, recording: Recording) -> ProcessorOutput:
                if outer.failures > 0:
                    outer.failures -= 1
                    raise sa_exc.OperationalError("UPDATE ...", {}, Exception("server closed the connection"))
                return super().update(recording)

        return P(ctx, state)


def test_transient_failure_is_retried_with_exponential_backoff(tmp_path):
    app, c, h = _setup(tmp_path, factory=Flaky(failures=2))
    sid = _session_with_batches(c, h, [0.0, 1.0])
    sleeps: list[float] = []
    assert _runtime(app, sleeps=sleeps).run_session(sid) == "done"
    assert sleeps == [0.5, 1.0]
    detail = c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert detail["batches"] == {"done": 2} and detail["status"] == "done"
    assert _east(c, sid, h) == [1.0, 2.0]


def test_batch_that_keeps_failing_becomes_a_visible_dead_letter_and_reprocess_retries_it(tmp_path):
    flaky = Flaky(failures=100)
    app, c, h = _setup(tmp_path, factory=flaky)
    sid = _session_with_batches(c, h, [0.0, 1.0])
    flaky.failures = 3  # the first batch fails three times: with max_attempts=3 it is dead, the second one runs
    assert _runtime(app, max_attempts=3).run_session(sid) == "done"
    detail = c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert detail["batches"] == {"dead": 1, "done": 1}
    assert detail["status"] == "failed"
    dead = next(b for b in detail["batch_list"] if b["status"] == "dead")
    assert dead["batch_id"] == "b0"
    assert "dead letter" in dead["error"] and "server closed the connection" in dead["error"]
    assert c.post(f"/api/v1/sessions/{sid}/reprocess", headers=h).status_code == 202
    assert _runtime(app, max_attempts=3).run_session(sid) == "done"
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["batches"] == {"done": 2}
    assert _east(c, sid, h) == [1.0, 2.0]


def test_giving_up_after_the_last_retry_reraises_and_leaves_the_batch_for_the_reconciler(tmp_path):
    app, c, h = _setup(tmp_path, factory=Flaky(failures=100))
    sid = _session_with_batches(c, h, [0.0])
    rt = _runtime(app, max_attempts=100)
    with pytest.raises(sa_exc.OperationalError):
        rt.run_session(sid)
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["batches"] == {"processing": 1}
    assert rt.reconcile() == 1 and rt.queue.enqueued == [sid]  # type: ignore[attr-defined]


def test_worker_that_lost_its_lease_commits_nothing(tmp_path):
    holder: dict[str, Any] = {}

    def stalling(ctx: SessionContext, state: bytes | None) -> Any:
        class P(CountingProcessor):
            def update(self, recording: Recording) -> ProcessorOutput:
                if "stolen" not in holder:  # worker a stalls past its TTL; worker b takes the session over
                    holder["stolen"] = True
                    engine = holder["app"].extensions["pdr"].store.engine
                    with engine.begin() as conn:
                        conn.execute(update(db.session_leases).values(expires_at=db.utcnow() - timedelta(seconds=1)))
                    assert Leases(engine, "b").claim(ctx.session_id)
                return super().update(recording)
        return P(ctx, state)

    app, c, h = _setup(tmp_path, factory=stalling)
    holder["app"] = app
    sid = _session_with_batches(c, h, [0.0, 1.0])
    assert _runtime(app, owner="a").run_session(sid) == "lease lost"
    assert _east(c, sid, h) == []
    assert _runtime(app, owner="b").run_session(sid) == "done"
    assert _east(c, sid, h) == [1.0, 2.0]


def test_data_quota_refuses_uploads_with_507_and_keeps_accepted_batches(tmp_path):
    app, c, h = _setup(tmp_path)
    quota = app.extensions["pdr_quota"]
    quota.refresh_s = 0.0
    quota.quota_bytes = quota.usage_bytes() + 300_000
    sid = c.post("/api/v1/sessions", json={"session_id": "full"}, headers=h).get_json()["id"]
    accepted, refused = [], None
    for i in range(2000):
        r = c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i:04d}", float(i), rate_hz=200.0),
                   headers=h)
        if r.status_code == 507:
            refused = r.get_json()["error"]
            break
        assert r.status_code == 201
        accepted.append(f"b{i:04d}")
    assert refused is not None and accepted
    assert refused["code"] == "insufficient_storage" and "quota" in refused["message"]
    assert "not stored" in refused["message"] and "kept" in refused["message"]
    big = json.dumps({"messageId": 1, "payload": ["x" * 400_000]})
    sl = c.post("/api/v1/ingest/sensor-logger", data=big, headers=h, content_type="application/json")
    assert sl.status_code == 499 and b"quota" in sl.data
    detail = c.get(f"/api/v1/sessions/{sid}", headers=h).get_json()  # reads keep working
    assert [b["batch_id"] for b in detail["batch_list"]] == accepted
    quota.quota_bytes = 0  # the operator frees space: uploads resume, processing takes everything
    assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("late", 1e4), headers=h).status_code == 201
    assert _runtime(app).run_session(sid) == "done"
    assert len(_east(c, sid, h)) == len(accepted) + 1


def test_unreachable_database_answers_503_with_retry_after(tmp_path, monkeypatch):
    app, c, h = _setup(tmp_path)
    store = app.extensions["pdr"].store

    def down(*args: Any, **kwargs: Any) -> Any:
        raise sa_exc.OperationalError("SELECT", {}, Exception("connection refused"))

    monkeypatch.setattr(store, "list_sessions", down)
    r = c.get("/api/v1/sessions", headers=h)
    assert r.status_code == 503 and r.headers["Retry-After"] == "5"
    assert "retry later" in r.get_json()["error"]["message"]


# -- with the machine's Redis ----------------------------------------------------------------------------
def test_enqueue_is_deduplicated_per_session_until_the_job_starts(redis_namespace):  # noqa: F811
    from server.queue import SessionQueue, redis_client

    url, ns = redis_namespace
    q = SessionQueue(redis_client(url), ns)
    assert q.enqueue("s1") and not q.enqueue("s1") and q.enqueue("s2")
    assert q.queue.count == 2
    flag = q.redis.get(q.flag_key("s1"))
    assert isinstance(flag, bytes)
    job_id = flag.decode()
    q.started("s1", "some-other-job")
    assert not q.enqueue("s1")
    q.started("s1", job_id)
    assert q.enqueue("s1") and q.queue.count == 3
    q.queue.empty()  # Redis lost its queue: the flags point at jobs that no longer exist
    q.redis.delete(*[f"rq:job:{j}" for j in q.queue.get_job_ids()] or ["-"])
    for key in q.redis.scan_iter(match="rq:job:" + ns + "*"):
        q.redis.delete(key)
    assert not q.enqueue("s1") and q.enqueue("s1", verify=True)


def test_rq_worker_processes_what_web_processes_enqueue_and_recovers_a_lost_queue(tmp_path,
                                                                                  redis_namespace):  # noqa: F811
    from rq import SimpleWorker

    from server.queue import SessionQueue, redis_client, set_runtime

    url, ns = redis_namespace
    app = make_app(tmp_path, worker="redis", redis_url=url, redis_namespace=ns)
    svc = app.extensions["pdr"]
    with svc.store.engine.begin() as conn:
        h = bearer(auth.add_user(conn, "rq"))
    c = app.test_client()
    sids = [_session_with_batches(c, h, [2.0, 0.0, 1.0], name=f"walk-{k}") for k in range(2)]
    queue = SessionQueue(redis_client(url), ns)
    assert queue.queue.count == 2  # one job per session for three uploads each
    runtime = WorkerRuntime(svc.processing, Leases(svc.store.engine, f"{ns}-w"), queue)
    set_runtime(runtime)
    try:
        SimpleWorker([queue.queue], connection=queue.redis, name=f"{ns}-w").work(burst=True, logging_level="ERROR")
        for sid in sids:
            assert _east(c, sid, h) == [1.0, 2.0, 3.0]
        assert c.post(f"/api/v1/sessions/{sids[0]}/batches", json=phone_batch("b9", 9.0), headers=h).status_code == 201
        queue.queue.empty()  # the job is lost (Redis restarted without persistence)
        assert runtime.reconcile() == 1
        SimpleWorker([queue.queue], connection=queue.redis, name=f"{ns}-w2").work(burst=True, logging_level="ERROR")
        assert _east(c, sids[0], h) == [1.0, 2.0, 3.0, 4.0]
    finally:
        set_runtime(None)
        svc.worker.stop()


def test_failed_authentications_are_limited_across_processes(tmp_path, redis_namespace):  # noqa: F811
    url, ns = redis_namespace
    apps = [make_app(tmp_path / str(k), worker="redis", redis_url=url, redis_namespace=ns, auth_failures_per_minute=3)
            for k in range(2)]
    clients = [a.test_client() for a in apps]
    bad = bearer("pdr_" + "x" * 43)
    assert [clients[k].get("/api/v1/sessions", headers=bad).status_code for k in (0, 0, 1)] == [401, 401, 401]
    r = clients[1].get("/api/v1/sessions", headers=bad)
    assert r.status_code == 429 and "too many failed" in r.get_json()["error"]["message"]
    assert clients[0].get("/api/v1/sessions", headers=bad).status_code == 429


def test_tokens_never_reach_the_logs(tmp_path, caplog):
    import logging

    app, c, h = _setup(tmp_path, factory=Flaky(failures=1))  # the retry is logged
    token = h["Authorization"].split()[1]
    wrong = "pdr_" + "w" * 43
    sid = _session_with_batches(c, h, [0.0])
    with caplog.at_level(logging.DEBUG):
        c.post(f"/api/v1/sessions/{sid}/batches?token={token}", data=b"{bad", content_type="application/json")
        c.post(f"/api/v1/sessions/{sid}/batches?token={wrong}", json=phone_batch("x", 5.0))
        c.get("/api/v1/sessions", headers=bearer(wrong))
        c.post("/api/v1/ingest/sensor-logger?token=" + token, data=b"[]", content_type="application/json")
        _runtime(app).run_session(sid)
    assert caplog.records and token not in caplog.text and wrong not in caplog.text
