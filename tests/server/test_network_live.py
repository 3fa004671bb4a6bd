"""Issue 26 against a real ``pdr serve`` process, for the items whose other tests use the Flask test client:
decode once and bounded readers (2), the masked database password (5), Allan reports and a crash (6), a batch
that crashes the process on every start (7), hostile uploads and form fields (8), replays in other whitespace (9).
"""

from __future__ import annotations

import io
import json
import signal
import subprocess
import threading
import time
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import select, update

from server import db
from server.client import Client, add_user, running_server, start_server, stop_server, wait_healthy
from server.config import REPO_ROOT
from server.db import make_engine
from tests.server.helpers import multipart, phone_batch
from tests.server.poison_processor import EXIT_CODE
from tests.server.realservers import pg_database  # noqa: F401  (fixture)

pytestmark = pytest.mark.timeout(300)

SIM = REPO_ROOT / "mobile_logs" / "sim"
MB = 1024 * 1024
COUNTING = {"PDR_PROCESSOR": "tests.server.conftest:CountingProcessor", "PYTHONPATH": str(REPO_ROOT)}


def _wait_status(c: Client, sid: str, timeout_s: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while (detail := c.request("GET", f"/api/v1/sessions/{sid}").json())["status"] not in ("done", "failed"):
        assert time.monotonic() < deadline, detail
        time.sleep(0.2)
    return detail


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str, Path]]:
    """A server with the counting processor, one reader child at a time, small limits; (url, token, data dir)."""
    data = tmp_path_factory.mktemp("live")
    env = {**COUNTING, "PDR_READERS": "1", "PDR_MAX_UPLOAD_MB": "4", "PDR_MAX_BATCH_MB": "0.5"}
    with running_server(data, env) as (url, penv, _):
        yield url, add_user(penv, "lena"), data


def test_uploads_are_read_once_by_bounded_readers_and_processing_never_rereads(live):
    """Item 2: a zip bomb is refused from its central directory; four uploads at once through one reader child all
    succeed; processing reads the stored decoded recording: with every raw payload replaced by garbage, a
    reprocess gives the same track."""
    url, token, data = live
    c = Client(url, token)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("Accelerometer.csv", b"\0" * (256 * MB))
    body, ctype = multipart({"file": (buf.getvalue(), "bomb.zip")})
    r = c.request("POST", "/api/v1/sessions", raw=body, content_type=ctype)
    assert r.status == 422 and "compression bomb" in r.json()["error"]["message"], r.body[:300]

    raw = (SIM / "hand_escalator.zip").read_bytes()
    answers: list[Any] = [None] * 4

    def upload(k: int) -> None:
        b, t = multipart({"file": (raw, "hand_escalator.zip"), "session_id": f"parallel-{k}"})
        cl = Client(url, token, timeout_s=120.0)
        answers[k] = cl.request("POST", "/api/v1/sessions", raw=b, content_type=t)
        cl.close()

    threads = [threading.Thread(target=upload, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert [a.status for a in answers] == [201] * 4, [a.body[:200] for a in answers]
    sids = [a.json()["id"] for a in answers]
    tracks = []
    for sid in sids:
        assert _wait_status(c, sid)["status"] == "done"
        tracks.append(c.request("GET", f"/api/v1/sessions/{sid}/track").json()["points"])
    engine = make_engine(f"sqlite:///{data / 'pdr.sqlite3'}")
    try:
        with engine.begin() as conn:
            rows = conn.execute(select(db.batches.c.decoded).where(db.batches.c.session_id.in_(sids))).all()
            assert len(rows) == 4 and all(r.decoded is not None for r in rows)
            import zlib
            conn.execute(update(db.batches).where(db.batches.c.session_id == sids[0])
                         .values(payload=zlib.compress(b"garbage, not a zip"), payload_sha256="0" * 64))
    finally:
        engine.dispose()
    assert c.request("POST", f"/api/v1/sessions/{sids[0]}/reprocess").status == 202
    time.sleep(0.5)
    assert _wait_status(c, sids[0])["status"] == "done"
    assert c.request("GET", f"/api/v1/sessions/{sids[0]}/track").json()["points"] == tracks[0]
    c.close()


@pytest.mark.parametrize("name", ["..", "a" * 300 + ".csv", "../../x.csv"])
def test_hostile_upload_names_are_4xx_on_a_live_server(live, name):
    """Item 8: file names that are a parent folder, too long or a path."""
    url, token, _ = live
    c = Client(url, token)
    body, ctype = multipart({"file": (b"not a log at all\n", name)})
    r = c.request("POST", "/api/v1/sessions", raw=body, content_type=ctype)
    c.close()
    assert 400 <= r.status < 500 and "error" in r.json(), r.body[:300]


def test_deep_and_large_form_fields_are_4xx_with_the_right_limit_on_a_live_server(live):
    """Item 8: a ``processing`` field of 100 000 ``[`` and a 600 KB field (the batch limit is 0.5 MB here)."""
    url, token, _ = live
    c = Client(url, token)
    body, ctype = multipart({"file": (b"t,x\n1,2\n", "a.csv"), "processing": "[" * 100_000})
    r = c.request("POST", "/api/v1/sessions", raw=body, content_type=ctype)
    assert 400 <= r.status < 500, r.body[:300]
    body, ctype = multipart({"processing": "x" * (600 * 1024), "file": (b"t,x\n1,2\n", "a.csv")})
    r = c.request("POST", "/api/v1/sessions", raw=body, content_type=ctype)
    assert r.status == 413, r.body[:300]
    assert "form field too large: the limit of this route is 524288 bytes" in r.json()["error"]["message"]
    c.close()


def test_replays_in_other_whitespace_are_duplicates_on_a_live_server(live):
    """Item 9: the same batch and the same Sensor Logger message re-sent with other whitespace and key order."""
    url, token, _ = live
    c = Client(url, token)
    sid = c.request("POST", "/api/v1/sessions", {"session_id": "replays"}).json()["id"]
    batch = phone_batch("b0", 0.0)
    first = c.request("POST", f"/api/v1/sessions/{sid}/batches", raw=json.dumps(batch).encode())
    again = c.request("POST", f"/api/v1/sessions/{sid}/batches",
                      raw=json.dumps(batch, indent=2, sort_keys=True).encode())
    assert first.status == 201 and again.status == 200 and again.json()["duplicate"] is True
    changed = dict(batch, streams={k: dict(v, values=[[1.0, 2.0, 3.0]] * len(v["values"]))
                                   for k, v in batch["streams"].items()})
    assert c.request("POST", f"/api/v1/sessions/{sid}/batches", changed).status == 409
    msg = {"messageId": 3, "sessionId": "push-ws", "deviceId": "d",
           "payload": [{"name": "accelerometer", "time": 1_700_000_000_000_000_000 + k * 20_000_000,
                        "values": {"x": 0.0, "y": 0.0, "z": 9.81}} for k in range(20)]}
    push = Client(url)  # as the app pushes: the token in the query string
    path = f"/api/v1/ingest/sensor-logger?token={token}"
    one = push.request("POST", path, raw=json.dumps(msg).encode())
    two = push.request("POST", path, raw=json.dumps(msg, indent=4, sort_keys=True).encode())
    assert one.status == 200 and two.status == 200 and two.json()["duplicate"] is True
    detail = _wait_status(c, one.json()["session"])
    assert [b["status"] for b in detail["batch_list"]] == ["done"]  # stored and processed once
    push.close()
    c.close()


def test_serve_never_prints_the_database_password(tmp_path, pg_database):  # noqa: F811
    """Item 5: ``pdr serve`` on PostgreSQL with a password in ``DATABASE_URL`` logs the URL masked."""
    secret = "s3cret-pw-26"
    url = pg_database.replace("postgresql://postgres@", f"postgresql://postgres:{secret}@", 1)
    assert secret in url
    with running_server(tmp_path, {**COUNTING, "DATABASE_URL": url}) as (base, env, _):
        token = add_user(env, "pam")
        c = Client(base, token)
        assert c.request("GET", "/api/v1/sessions").status == 200
        c.close()
    log = (tmp_path / "server.log").read_text()
    assert "pdr service on" in log and "postgres" in log and secret not in log, log[-1500:]


def _start(data: Path, env: dict[str, str]) -> tuple[subprocess.Popen[bytes], str]:
    """Start ``pdr serve`` without waiting for it (it may crash at once); returns (process, url)."""
    proc, url, _ = start_server(data, env)
    return proc, url


def test_a_batch_that_kills_the_process_is_dead_lettered_after_max_attempts(tmp_path):
    """Item 7: a batch whose processing kills ``pdr serve`` (as a native crash would) kills it on the next start
    too; the start after ``PDR_MAX_ATTEMPTS`` interruptions dead-letters it and the service stays up, the other
    sessions untouched."""
    env = {"PDR_PROCESSOR": "tests.server.poison_processor:PoisonProcessor", "PYTHONPATH": str(REPO_ROOT),
           "PDR_MAX_ATTEMPTS": "2"}
    with running_server(tmp_path, env) as (url, penv, proc):
        token = add_user(penv, "pia")
        c = Client(url, token)
        good = c.request("POST", "/api/v1/sessions", {"session_id": "good"}).json()["id"]
        assert c.request("POST", f"/api/v1/sessions/{good}/batches", phone_batch("g0", 0.0)).status == 201
        assert _wait_status(c, good)["status"] == "done"
        bad = c.request("POST", "/api/v1/sessions", {"session_id": "bad"}).json()["id"]
        poison = phone_batch("p0", 0.0)
        poison["device"]["model"] = "poison"
        assert c.request("POST", f"/api/v1/sessions/{bad}/batches", poison).status == 201  # stored, then crash
        assert proc.wait(timeout=60) == EXIT_CODE
        c.close()
    proc, url = _start(tmp_path, env)  # the restart takes the interrupted batch again, and dies again
    try:
        assert proc.wait(timeout=120) == EXIT_CODE
    finally:
        stop_server(proc)
    proc, url = _start(tmp_path, env)  # interrupted twice: dead-lettered, not run
    try:
        wait_healthy(url, proc, log_path=tmp_path / "server.log")
        c = Client(url, token)
        time.sleep(1.0)
        assert proc.poll() is None
        detail = c.request("GET", f"/api/v1/sessions/{bad}").json()
        (batch,) = detail["batch_list"]
        assert batch["status"] == "dead" and "interrupted 2 times" in (batch.get("error") or ""), detail
        assert _wait_status(c, good)["status"] == "done"
        assert len(c.request("GET", f"/api/v1/sessions/{good}/track").json()["points"]) == 1
        assert c.request("POST", f"/api/v1/sessions/{bad}/batches", phone_batch("p1", 1.0)).status == 201
        assert _wait_status(c, bad)["batch_list"][-1]["status"] == "done"  # the session goes on
        c.close()
    finally:
        stop_server(proc)


def test_allan_report_of_a_killed_server_is_finished_after_its_restart(tmp_path):
    """Item 6: ``pdr serve`` killed (SIGKILL) right after accepting an Allan report; the restarted service finishes
    it from the stored upload."""
    from tests.server.test_models_reports import _static_npz

    body, ctype = multipart({"file": (_static_npz(seconds=60.0), "static.npz")})
    with running_server(tmp_path, COUNTING) as (url, penv, proc):
        token = add_user(penv, "kim")
        c = Client(url, token)
        r = c.request("POST", "/api/v1/reports/allan", raw=body, content_type=ctype)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        c.close()
    assert r.status == 202, r.body[:300]
    rid = r.json()["id"]
    with running_server(tmp_path, COUNTING) as (url, _, _):
        c = Client(url, token)
        deadline = time.monotonic() + 240
        while (rep := c.request("GET", f"/api/v1/reports/{rid}").json())["status"] == "pending":
            assert time.monotonic() < deadline
            time.sleep(0.3)
        assert rep["status"] == "done", rep
        assert c.request("GET", f"/api/v1/reports/{rid}/report.html").status == 200
        c.close()
