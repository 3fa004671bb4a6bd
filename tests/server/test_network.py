"""The service on a real network (issue 26), against a real ``pdr serve`` process where the transport matters:
body limits from the headers, the failure limiter and proxies, scoped tokens, the access log, hostile uploads,
idempotent replays in other whitespace, deletion and retention."""

from __future__ import annotations

import gzip
import io
import json
import re
import socket
import subprocess
import time
import zipfile
from datetime import timedelta
from typing import Any

import pytest
from sqlalchemy import select, update

from server import auth, db
from server.client import Client, add_user, pdr_command, running_server
from server.jobs import InProcessWorker
from server.sandbox import check_compressed, safe_filename
from tests.server.conftest import bearer, make_app
from tests.server.helpers import multipart, phone_batch
from tests.server.realservers import pg_database, redis_namespace  # noqa: F401  (fixtures)

pytestmark = pytest.mark.timeout(240)

MB = 1024 * 1024


def _raw_exchange(url: str, head: bytes, body_part: bytes = b"", timeout_s: float = 5.0) -> tuple[bytes, float]:
    """Send request headers (and the start of a body), then read the answer; returns (answer, seconds)."""
    host, port = url.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=timeout_s) as sock:
        t0 = time.perf_counter()
        sock.sendall(head + body_part)
        data = b""
        while b"\r\n\r\n" not in data or not _complete(data):
            chunk = sock.recv(65536)
            if not chunk:
                break
            data += chunk
        return data, time.perf_counter() - t0


def _complete(data: bytes) -> bool:
    head, _, body = data.partition(b"\r\n\r\n")
    for line in head.split(b"\r\n"):
        if line.lower().startswith(b"content-length:"):
            return len(body) >= int(line.split(b":")[1])
    return False


def _status(answer: bytes) -> int:
    return int(answer.split(b" ", 2)[1])


def _json_body(answer: bytes) -> dict:
    return json.loads(answer.partition(b"\r\n\r\n")[2])


def _tmp_bytes(paths: list) -> int:
    return sum(p.stat().st_size for d in paths for p in d.rglob("*") if p.is_file())


# -- 1. body limits ---------------------------------------------------------------------------------------------
def test_bodies_over_the_route_limit_are_refused_from_the_headers(tmp_path):
    env = {"PDR_MAX_UPLOAD_MB": "16", "PDR_MAX_BATCH_MB": "2"}
    with running_server(tmp_path / "srv", env) as (url, penv, _):
        token = add_user(penv, "ulla")
        before = _tmp_bytes([tmp_path / "srv"])
        cases = [  # (route, content type, declared bytes, limit quoted)
            ("/api/v1/sessions/x/batches", "application/json", 900 * MB, 2 * MB),
            ("/api/v1/ingest/sensor-logger", "application/json", 5 * MB, 2 * MB),
            ("/api/v1/sessions", "multipart/form-data; boundary=x", 200 * MB, 16 * MB),
            ("/api/v1/reports/allan", "multipart/form-data; boundary=x", 17 * MB, 16 * MB),
            ("/api/v1/sessions", "application/json", 3 * MB, 2 * MB),
        ]
        for path, ctype, declared, limit in cases:
            for auth_header in (b"", f"Authorization: Bearer {token}\r\n".encode()):  # with or without a token
                head = (f"POST {path} HTTP/1.1\r\nHost: t\r\nContent-Type: {ctype}\r\n"
                        f"Content-Length: {declared}\r\n").encode() + auth_header + b"\r\n"
                # answered while the client has sent only the headers and 1000 bytes: refused from the headers
                answer, _ = _raw_exchange(url, head, b"x" * 1000)
                if path == "/api/v1/ingest/sensor-logger":  # the app shows its user only a 499's text
                    assert _status(answer) == 499 and b"text/plain" in answer.partition(b"\r\n\r\n")[0]
                    assert b"message too large" in answer and str(limit).encode() in answer, answer[:300]
                    continue
                assert _status(answer) == 413, (path, answer[:300])
                err = _json_body(answer)["error"]
                assert err["details"]["limit_bytes"] == limit and str(limit) in err["message"], (path, err)
        # a chunked body is refused while it streams, once past the route's limit
        head = (b"POST /api/v1/sessions/x/batches HTTP/1.1\r\nHost: t\r\nContent-Type: application/json\r\n"
                b"Transfer-Encoding: chunked\r\n\r\n")
        chunk = b"%x\r\n" % (256 * 1024) + b"x" * (256 * 1024) + b"\r\n"
        answer, _ = _raw_exchange(url, head, chunk * 12)
        assert _status(answer) == 413 and _json_body(answer)["error"]["details"]["limit_bytes"] == 2 * MB
        # within the limit, a route answers as usual
        c = Client(url, token)
        assert c.request("POST", "/api/v1/sessions", {"session_id": "fine"}).status == 201
        c.close()
        assert _tmp_bytes([tmp_path / "srv"]) - before < 1 * MB  # nothing of the refused bodies was kept


def test_body_limit_middleware_without_waitress(tmp_path):
    app = make_app(tmp_path, max_batch_mb=0.5)
    try:
        with app.extensions["pdr"].store.engine.begin() as conn:
            h = bearer(auth.add_user(conn, "vic"))
        c = app.test_client()
        r = c.post("/api/v1/sessions/x/batches", data=b"{" * (600 * 1024), content_type="application/json",
                   headers=h)
        assert r.status_code == 413 and r.get_json()["error"]["details"]["limit_bytes"] == 512 * 1024
        # an unsized (chunked) body is counted while it is read
        r = c.post("/api/v1/sessions/x/batches", input_stream=io.BytesIO(b" " * (600 * 1024)),
                   content_type="application/json", headers={**h, "Transfer-Encoding": "chunked"})
        assert r.status_code == 413 and "524288 bytes" in r.get_json()["error"]["message"]
    finally:
        app.extensions["pdr"].worker.stop()


# -- 2. compressed uploads ----------------------------------------------------------------------------------------
def test_compression_bombs_are_refused_before_inflating():
    zeros = b"\0" * (64 * MB)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("Accelerometer.csv", zeros)
    with pytest.raises(Exception, match="compression ratio of .* refused as a compression bomb"):
        check_compressed(buf.getvalue(), "bomb.zip")
    with pytest.raises(Exception, match="compression bomb"):
        check_compressed(gzip.compress(zeros), "bomb.csv.gz")
    text = "\n".join(f"{i * 0.01:.3f},{(i * 7919) % 1000 / 100:.4f},0.1,9.81" for i in range(100_000)).encode()
    check_compressed(gzip.compress(text), "walk.csv.gz")  # a real-looking log passes
    check_compressed(text, "walk.csv")


def test_a_gzip_cut_short_is_judged_by_what_it_inflates_to_not_by_its_last_four_bytes():
    """A cut gzip's last 4 bytes are compressed data, not the size it declares: a real log cut short was refused
    as a compression bomb (or as too large); it is now measured, passes, and is read as far as it goes. A bomb cut
    short is still refused."""
    text = "\n".join(f"{i * 0.01:.3f},{(i * 7919) % 1000 / 100:.4f},0.1,9.81" for i in range(400_000)).encode()
    whole = gzip.compress(text)
    cut = next(whole[:n] for n in range(len(whole) // 2, len(whole))
               if int.from_bytes(whole[n - 4:n], "little") > 200 * n)       # trailer bytes that look like a bomb
    check_compressed(cut, "walk.csv.gz")
    bomb = gzip.compress(b"\0" * (64 * MB))
    with pytest.raises(Exception, match="compression bomb"):
        check_compressed(bomb[: len(bomb) // 2], "bomb.csv.gz")


def test_zip_bomb_upload_is_a_quick_422(client, tokens):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("Accelerometer.csv", b"\0" * (256 * MB))
    body, ctype = multipart({"file": (buf.getvalue(), "bomb.zip")})
    r = client.post("/api/v1/sessions", data=body, content_type=ctype, headers=bearer(tokens["alice"]))
    # refused from the central directory (the message of the header check), not after inflating 256 MB
    assert r.status_code == 422 and "compression bomb" in r.get_json()["error"]["message"]


def test_a_gzip_upload_to_pdr_serve_is_inflated_within_the_route_limit(tmp_path):
    """Under waitress (pdr serve), as phones send it: a gzip batch, sized or chunked, is taken as the same batch sent
    plain (it was a 415); a gzip bomb (10 MB of zeros in 10 kB, the batch limit 2 MB) is a 413 quoting the route's
    limit without inflating past it; a corrupt stream is a 400 naming Content-Encoding; the server goes on."""
    import http.client

    with running_server(tmp_path / "srv", {"PDR_MAX_UPLOAD_MB": "16", "PDR_MAX_BATCH_MB": "2"}) as (url, penv, proc):
        token = add_user(penv, "gus")
        c = Client(url, token)
        sid = c.request("POST", "/api/v1/sessions", {"session_id": "zipped"}).json()["id"]
        host, port = url.removeprefix("http://").split(":")

        def post(batch_body: bytes, chunked: bool = False) -> tuple[int, dict[str, Any]]:
            conn = http.client.HTTPConnection(host, int(port), timeout=30)
            headers = {"Authorization": f"Bearer {token}", "Content-Type": "application/json",
                       "Content-Encoding": "gzip"}
            conn.request("POST", f"/api/v1/sessions/{sid}/batches",
                         body=iter([batch_body]) if chunked else batch_body, headers=headers,
                         encode_chunked=chunked)
            resp = conn.getresponse()
            answer = resp.status, json.loads(resp.read())
            conn.close()
            return answer

        status, answer = post(gzip.compress(json.dumps(phone_batch("b1", 0.0)).encode()))
        assert status == 201 and answer["batch_id"] == "b1", answer
        status, answer = post(gzip.compress(json.dumps(phone_batch("b2", 1.0)).encode()), chunked=True)
        assert status == 201 and answer["batch_id"] == "b2", answer
        assert c.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch("b1", 0.0)).json()["duplicate"]
        bomb = gzip.compress(b'{"batch_id": "bomb", "x": "' + b"0" * (10 * MB) + b'"}')
        for chunked in (False, True):
            status, answer = post(bomb, chunked)
            assert status == 413 and answer["error"]["details"]["limit_bytes"] == 2 * MB, answer
        status, answer = post(b"\x1f\x8b\x08\x00" + b"\xff" * 1000)
        assert status == 400 and answer["error"]["details"]["field"] == "Content-Encoding", answer
        batches = c.request("GET", f"/api/v1/sessions/{sid}").json()["batch_list"]
        assert sorted(b["batch_id"] for b in batches) == ["b1", "b2"] and proc.poll() is None
        c.close()


# -- 3. the failure limiter ---------------------------------------------------------------------------------------
def test_failed_logins_never_lock_out_a_valid_token(tmp_path):
    with running_server(tmp_path, {"PDR_AUTH_FAILURES_PER_MINUTE": "5"}) as (url, env, _):
        token = add_user(env, "wanda")
        bad = Client(url, "pdr_" + "x" * 43)
        statuses = [bad.request("GET", "/api/v1/sessions").status for _ in range(8)]
        assert statuses[:5] == [401] * 5 and set(statuses[5:]) == {429}
        good = Client(url, token)
        assert good.request("GET", "/api/v1/sessions").status == 200
        msg = {"messageId": 1, "sessionId": "s", "deviceId": "d", "payload": []}
        assert good.request("POST", f"/api/v1/ingest/sensor-logger?token={token}", msg).status == 200
        bad.close()
        good.close()


def test_trusted_proxy_address_is_the_forwarded_client(tmp_path):
    with running_server(tmp_path, {"PDR_AUTH_FAILURES_PER_MINUTE": "3", "PDR_TRUSTED_PROXIES": "1"}) as (url, _, _):
        host, port = url.removeprefix("http://").split(":")

        def get(client_ip: str, token: str) -> int:
            head = (f"GET /api/v1/sessions HTTP/1.1\r\nHost: t\r\nAuthorization: Bearer {token}\r\n"
                    f"X-Forwarded-For: {client_ip}\r\n\r\n").encode()
            return _status(_raw_exchange(url, head)[0])

        assert [get("10.0.0.1", f"pdr_a{i}xxxxxxxxxx") for i in range(4)] == [401, 401, 401, 429]
        assert get("10.0.0.2", "pdr_zzzzzzzzzzzz") == 401  # another client behind the same proxy is not blocked


# -- 4. scoped tokens -----------------------------------------------------------------------------------------------
def _cli(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*pdr_command(), "users", *args], env=env, capture_output=True, text=True)


def test_scoped_tokens_listing_and_revocation_by_prefix(tmp_path):
    with running_server(tmp_path) as (url, env, _):
        full = add_user(env, "xena")
        ingest = _cli(env, "token", "xena", "--scope", "ingest", "--expires", "30").stdout.strip()
        read = _cli(env, "token", "xena", "--scope", "read").stdout.strip()
        assert _cli(env, "token", "xena", "--scope", "admin").returncode == 2
        f, i, r = Client(url, full), Client(url, ingest), Client(url, read)
        sid = i.request("POST", "/api/v1/sessions", {"session_id": "phone"}).json()["id"]
        assert i.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch("b0", 0.0)).status == 201
        denied = i.request("GET", f"/api/v1/sessions/{sid}")
        assert denied.status == 403 and "scope 'ingest'" in denied.json()["error"]["message"]
        assert r.request("GET", f"/api/v1/sessions/{sid}").status == 200
        assert r.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch("b1", 1.0)).status == 403
        assert r.request("DELETE", f"/api/v1/sessions/{sid}").status == 403
        assert f.request("GET", f"/api/v1/sessions/{sid}").status == 200

        listing = _cli(env, "tokens", "xena").stdout.splitlines()
        rows = {line.split("\t")[0]: line.split("\t") for line in listing[1:]}
        assert set(rows) == {full[:10], ingest[:10], read[:10]}
        assert rows[ingest[:10]][1] == "ingest" and rows[ingest[:10]][3] != "-"  # expires
        assert rows[read[:10]][1] == "read" and rows[read[:10]][4] != "-"  # last used
        assert full not in "\n".join(listing)

        out = _cli(env, "revoke", "xena", "--token", ingest[:10])
        assert "revoked 1 token" in out.stdout
        assert i.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch("b2", 2.0)).status == 401
        assert f.request("GET", "/api/v1/sessions").status == 200  # the others keep working
        assert _cli(env, "revoke", "xena", "--token", "pdr_nonexist").returncode == 2
        for c in (f, i, r):
            c.close()
        log = (tmp_path / "server.log").read_text()
    # 5. the access log: method, path without the query string, status, duration, user; never a token
    assert f"GET /api/v1/sessions/{sid} 403" in log and "user=1" in log
    assert all(t[4:] not in log for t in (full, ingest, read))


def test_expired_token_is_refused(app, client, tokens):
    with app.extensions["pdr"].store.engine.begin() as conn:
        uid = auth.user_id(conn, "alice")
        short = auth.issue_token(conn, uid, "read", expires_days=1)
        conn.execute(update(db.api_tokens).where(db.api_tokens.c.prefix == short[:10])
                     .values(expires_at=db.utcnow() - timedelta(seconds=1)))
    r = client.get("/api/v1/sessions", headers=bearer(short))
    assert r.status_code == 401 and "expired" in r.get_json()["error"]["message"]


@pytest.mark.parametrize("days", [0.0, -1.0, float("nan"), float("inf"), 1e12, 36_526.0])
def test_a_token_lifetime_beyond_a_century_or_not_positive_is_refused(app, tokens, days):
    # 1e12 days overflowed datetime (an OverflowError traceback from `pdr users token NAME --expires 1e12`).
    with app.extensions["pdr"].store.engine.begin() as conn:
        uid = auth.user_id(conn, "alice")
        with pytest.raises(ValueError, match="--expires must be a positive number of days, at most 36525"):
            auth.issue_token(conn, uid, "read", expires_days=days)
        assert auth.issue_token(conn, uid, "read", expires_days=36_525.0).startswith("pdr_")


def test_serve_masks_the_database_password():
    from server.config import safe_url

    shown = safe_url("postgresql+psycopg://pdr:s3cret@db.example:5432/pdr")
    assert "s3cret" not in shown and "db.example" in shown


# -- 6. poison batch in the embedded worker ------------------------------------------------------------------------
def test_embedded_worker_dead_letters_a_batch_interrupted_too_often(tmp_path):
    app = make_app(tmp_path, max_attempts=3)
    with app.extensions["pdr"].store.engine.begin() as conn:
        h = bearer(auth.add_user(conn, "yuri"))
    c = app.test_client()
    sid = c.post("/api/v1/sessions", json={"session_id": "poison"}, headers=h).get_json()["id"]
    assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b0", 0.0), headers=h).status_code == 201
    app.extensions["pdr"].worker.wait_idle()
    app.extensions["pdr"].worker.stop()
    engine = app.extensions["pdr"].store.engine
    statuses = []
    for _ in range(3):  # each start finds the batch interrupted mid-processing (as a crash leaves it)
        with engine.begin() as conn:
            conn.execute(update(db.batches).where(db.batches.c.session_id == sid).values(status="processing"))
        again = make_app(tmp_path, worker="none")
        InProcessWorker(again.extensions["pdr"].processing, max_attempts=3).recover()  # as create_app runs it
        with engine.connect() as conn:
            statuses.append(conn.execute(select(db.batches.c.status, db.batches.c.error)
                                         .where(db.batches.c.session_id == sid)).one())
    assert [s.status for s in statuses] == ["pending", "pending", "dead"]
    assert "interrupted 3 times" in statuses[-1].error


# -- 7. hostile uploads ----------------------------------------------------------------------------------------------
def test_safe_filename():
    assert safe_filename("..") == "upload"
    assert safe_filename("../../etc/passwd") == "passwd"
    long = safe_filename("a" * 300 + ".csv.gz")
    assert len(long) <= 120 and long.endswith(".csv.gz")
    assert safe_filename("walk 1 (copy).json") == "walk_1__copy_.json"


@pytest.mark.parametrize("name", ["..", "a" * 300 + ".csv", "../../x.csv", ""])
def test_hostile_upload_names_are_4xx(client, tokens, name):
    body, ctype = multipart({"file": (b"not a log at all\n", name)})
    r = client.post("/api/v1/sessions", data=body, content_type=ctype, headers=bearer(tokens["alice"]))
    assert 400 <= r.status_code < 500, r.get_data()[:300]


def test_deep_processing_field_and_large_form_field(tmp_path):
    app = make_app(tmp_path, max_batch_mb=0.5)
    try:
        with app.extensions["pdr"].store.engine.begin() as conn:
            h = bearer(auth.add_user(conn, "zoe"))
        c = app.test_client()
        body, ctype = multipart({"file": (b"t,x\n1,2\n", "a.csv"), "processing": "[" * 100_000})
        r = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
        assert 400 <= r.status_code < 500, r.get_data()[:300]
        # (the field before the file: werkzeug leaves a file it spooled unclosed when a later field is refused)
        body, ctype = multipart({"processing": "x" * (600 * 1024), "file": (b"t,x\n1,2\n", "a.csv")})
        r = c.post("/api/v1/sessions", data=body, content_type=ctype, headers=h)
        assert r.status_code == 413
        assert "form field too large: the limit of this route is 524288 bytes" in r.get_json()["error"]["message"]
    finally:
        app.extensions["pdr"].worker.stop()


# -- 8. idempotency on decoded content -------------------------------------------------------------------------------
def test_replay_in_other_whitespace_is_a_duplicate(app, client, tokens):
    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", json={"session_id": "ws"}, headers=h).get_json()["id"]
    batch = phone_batch("b0", 0.0)
    first = client.post(f"/api/v1/sessions/{sid}/batches", data=json.dumps(batch), headers=h,
                        content_type="application/json")
    again = client.post(f"/api/v1/sessions/{sid}/batches", data=json.dumps(batch, indent=2, sort_keys=True),
                        headers=h, content_type="application/json")
    assert first.status_code == 201 and again.status_code == 200 and again.get_json()["duplicate"] is True
    msg = {"messageId": 7, "sessionId": "s", "deviceId": "d",
           "payload": [{"name": "accelerometer", "time": 1_700_000_000_000_000_000,
                        "values": {"x": 0.0, "y": 0.0, "z": 9.81}}]}
    url = f"/api/v1/ingest/sensor-logger?token={tokens['alice']}"
    one = client.post(url, data=json.dumps(msg), content_type="application/json")
    two = client.post(url, data=json.dumps(msg, indent=4), content_type="application/json")
    assert one.status_code == 200 and two.status_code == 200 and two.get_json()["duplicate"] is True
    changed = dict(batch, streams={k: dict(v, values=[[1.0, 2.0, 3.0]] * len(v["values"]))
                                   for k, v in batch["streams"].items()})
    assert client.post(f"/api/v1/sessions/{sid}/batches", json=changed, headers=h).status_code == 409


# -- 9. deletion and retention ---------------------------------------------------------------------------------------
def test_delete_session_and_report_and_user(tmp_path):
    with running_server(tmp_path) as (url, env, _):
        token = add_user(env, "abel")
        other = add_user(env, "cain")
        c = Client(url, token)
        sid = c.request("POST", "/api/v1/sessions", {"session_id": "gone"}).json()["id"]
        for i in range(3):
            assert c.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch(f"b{i}", float(i))).status == 201
        deadline = time.monotonic() + 200  # a cold kernel cache compiles first (item 11), slower on a busy machine
        while c.request("GET", f"/api/v1/sessions/{sid}").json()["status"] not in ("done", "failed"):
            assert time.monotonic() < deadline
            time.sleep(0.2)
        o = Client(url, other)
        assert o.request("DELETE", f"/api/v1/sessions/{sid}").status == 404  # not theirs
        assert c.request("DELETE", f"/api/v1/sessions/{sid}").status == 204
        assert c.request("GET", f"/api/v1/sessions/{sid}").status == 404
        assert c.request("DELETE", f"/api/v1/sessions/{sid}").status == 404
        assert c.request("DELETE", "/api/v1/reports/nope").status == 404
        c.close()
        from server.db import make_engine

        engine = make_engine(f"sqlite:///{tmp_path / 'pdr.sqlite3'}")
        with engine.connect() as conn:
            for table in (db.batches, db.track_points, db.events, db.processor_states, db.devices):
                assert conn.execute(select(table).where(table.c.session_id == sid)).first() is None, table.name
        assert _cli(env, "delete", "cain").returncode == 2  # needs --yes
        assert _cli(env, "delete", "cain", "--yes").returncode == 0
        assert o.request("GET", "/api/v1/sessions").status == 401
        o.close()
        engine.dispose()


def test_retention_drops_raw_batches_of_finished_sessions_only(app, client, tokens):
    from server.jobs import RetentionSweeper

    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", json={"session_id": "old"}, headers=h).get_json()["id"]
    client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b0", 0.0), headers=h)
    live = client.post("/api/v1/sessions", json={"session_id": "live"}, headers=h).get_json()["id"]
    app.extensions["pdr"].worker.wait_idle()
    track_before = client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
    store = app.extensions["pdr"].store
    with store.engine.begin() as conn:
        conn.execute(update(db.batches).values(received_at=db.utcnow() - timedelta(days=40)))
    client.post(f"/api/v1/sessions/{live}/batches", json=phone_batch("b0", 0.0), headers=h)  # arrives now
    app.extensions["pdr"].worker.wait_idle()
    assert RetentionSweeper(store, days=30).sweep() == 1
    detail = client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()
    assert [b["status"] for b in detail["batch_list"]] == ["purged"] and detail["status"] == "done"
    assert client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"] == track_before
    r = client.post(f"/api/v1/sessions/{sid}/reprocess", headers=h)
    assert r.status_code == 409 and "retention" in r.get_json()["error"]["message"]
    r = client.put(f"/api/v1/sessions/{sid}/processing", json={"foot": {"zaru": True}}, headers=h)
    assert r.status_code == 409 and "retention" in r.get_json()["error"]["message"]
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["processing"] == {}   # options not changed
    assert [b["status"] for b in client.get(f"/api/v1/sessions/{live}", headers=h).get_json()["batch_list"]] == [
        "done"]


def test_openapi_describes_deletion_and_token_scopes(client):
    doc = client.get("/api/v1/openapi.json").get_json()
    paths = doc["paths"]
    assert "204" in paths["/api/v1/sessions/{session_id}"]["delete"]["responses"]
    assert "204" in paths["/api/v1/reports/{report_id}"]["delete"]["responses"]
    assert paths["/api/v1/sessions/{session_id}/batches"]["post"]["x-token-scope"] == "ingest"
    assert paths["/api/v1/ingest/sensor-logger"]["post"]["x-token-scope"] == "ingest"
    assert paths["/api/v1/sessions/{session_id}/track"]["get"]["x-token-scope"] == "read"
    assert paths["/api/v1/sessions/{session_id}"]["delete"]["x-token-scope"] == "full"
    assert "x-token-scope" not in paths["/api/v1/health"]["get"]


def test_postgres_delete_session_and_user(tmp_path, pg_database):  # noqa: F811
    app = make_app(tmp_path, database_url=pg_database)
    try:
        store = app.extensions["pdr"].store
        with store.engine.begin() as conn:
            h = bearer(auth.add_user(conn, "pgdel"))
            auth.add_user(conn, "pgother")
        c = app.test_client()
        sid = c.post("/api/v1/sessions", json={"session_id": "pg"}, headers=h).get_json()["id"]
        for i in range(2):
            assert c.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)),
                          headers=h).status_code == 201
        app.extensions["pdr"].worker.wait_idle()
        assert c.delete(f"/api/v1/sessions/{sid}", headers=h).status_code == 204
        with store.engine.connect() as conn:
            for table in (db.batches, db.track_points, db.events, db.processor_states, db.devices):
                assert conn.execute(select(table).where(table.c.session_id == sid)).first() is None, table.name
        c.post("/api/v1/sessions", json={"session_id": "pg2"}, headers=h)
        with store.engine.begin() as conn:
            auth.delete_user(conn, "pgdel")
            assert conn.execute(select(db.sessions)).first() is None
            assert [r.name for r in conn.execute(select(db.users.c.name))] == ["pgother"]
    finally:
        app.extensions["pdr"].worker.stop()
        app.extensions["pdr"].store.engine.dispose()


@pytest.mark.slow
def test_deletion_and_retention_on_postgres_with_redis_workers(tmp_path, pg_database,  # noqa: F811
                                                               redis_namespace):  # noqa: F811
    """PDR_WORKER=redis on PostgreSQL: a session deleted while its job waits in Redis, a processed session and a
    report are deleted with all their rows; the worker takes the orphan job without an error; retention purges raw
    batches there too; ``pdr users delete`` removes the user."""
    from server.bench.cluster import running_cluster
    from server.config import REPO_ROOT
    from server.db import make_engine
    from server.jobs import RetentionSweeper
    from server.store import Store
    from tests.server.test_models_reports import _static_npz

    redis_url, ns = redis_namespace
    env = {"PDR_PROCESSOR": "tests.server.conftest:CountingProcessor", "PYTHONPATH": str(REPO_ROOT)}
    engine = make_engine(pg_database.replace("postgresql://", "postgresql+psycopg://", 1))

    def rows_of(sid: str) -> dict[str, int]:
        with engine.connect() as conn:
            return {t.name: len(conn.execute(select(t).where(t.c.session_id == sid)).all())
                    for t in (db.batches, db.track_points, db.events, db.processor_states,
                              db.devices, db.session_leases)}

    with running_cluster(tmp_path, pg_database, redis_url, ns, webs=1, workers=0, extra_env=env,
                         worker_args=["--reconcile-s", "1", "-v"]) as cluster:
        token = add_user(cluster.env, "dora")
        c = Client(cluster.urls[0], token)
        sids = {}
        for name, n in (("kept", 3), ("queued", 2), ("old", 1)):
            sids[name] = c.request("POST", "/api/v1/sessions", {"session_id": name}).json()["id"]
            for i in range(n):
                assert c.request("POST", f"/api/v1/sessions/{sids[name]}/batches",
                                 phone_batch(f"b{i}", float(i))).status == 201
        body, ctype = multipart({"file": (_static_npz(seconds=60.0), "static.npz")})
        rid = c.request("POST", "/api/v1/reports/allan", raw=body, content_type=ctype).json()["id"]
        assert c.request("DELETE", f"/api/v1/sessions/{sids['queued']}").status == 204  # its job waits in Redis
        assert all(v == 0 for v in rows_of(sids["queued"]).values())
        cluster.start_worker(f"{ns}-w0")
        deadline = time.monotonic() + 240
        while (c.request("GET", f"/api/v1/reports/{rid}").json()["status"] == "pending"
               or {c.request("GET", f"/api/v1/sessions/{sids[k]}").json()["status"] for k in ("kept", "old")}
               != {"done"}):
            assert time.monotonic() < deadline
            time.sleep(0.5)
        assert rows_of(sids["kept"])["track_points"] == 3
        assert c.request("DELETE", f"/api/v1/sessions/{sids['kept']}").status == 204
        assert c.request("GET", f"/api/v1/sessions/{sids['kept']}").status == 404
        assert all(v == 0 for v in rows_of(sids["kept"]).values()), rows_of(sids["kept"])
        assert c.request("DELETE", f"/api/v1/reports/{rid}").status == 204
        assert c.request("GET", f"/api/v1/reports/{rid}").status == 404
        with engine.connect() as conn:
            for t in (db.reports, db.report_files, db.report_uploads):
                assert conn.execute(select(t)).first() is None, t.name
        # retention: the old session's raw batch goes, its results stay
        track = c.request("GET", f"/api/v1/sessions/{sids['old']}/track").json()["points"]
        with engine.begin() as conn:
            conn.execute(update(db.batches).values(received_at=db.utcnow() - timedelta(days=40)))
        assert RetentionSweeper(Store(engine), days=30).sweep() == 1
        detail = c.request("GET", f"/api/v1/sessions/{sids['old']}").json()
        assert [b["status"] for b in detail["batch_list"]] == ["purged"]
        assert c.request("GET", f"/api/v1/sessions/{sids['old']}/track").json()["points"] == track
        with engine.connect() as conn:
            purged = conn.execute(select(db.batches.c.payload, db.batches.c.decoded)).one()
        assert purged.decoded is None and len(purged.payload) < 20  # the empty payload, compressed
        assert _cli(cluster.env, "delete", "dora", "--yes").returncode == 0
        assert c.request("GET", "/api/v1/sessions").status == 401
        c.close()
        worker_log = (tmp_path / f"{ns}-w0.log").read_text()
    with engine.connect() as conn:
        assert conn.execute(select(db.sessions)).first() is None and conn.execute(select(db.users)).first() is None
    engine.dispose()
    assert "Traceback" not in worker_log and "Job OK" in worker_log


# -- 10. Allan reports survive a restart -----------------------------------------------------------------------------
def test_allan_report_interrupted_by_a_restart_is_finished_after_it(tmp_path):
    from server.report_jobs import ReportRunner
    from tests.server.test_models_reports import _static_npz

    app = make_app(tmp_path)
    store = app.extensions["pdr"].store
    with store.engine.begin() as conn:
        h = bearer(auth.add_user(conn, "rita"))
        uid = auth.user_id(conn, "rita")
    app.extensions["pdr"].worker.stop()
    # As a crash leaves it: stored with its upload, started, never finished.
    idle = ReportRunner(store, enqueue=lambda report_id: None)
    raw = _static_npz()
    idle.create("r-crashed", uid, "static.npz", raw, "static_npz/static.npz", _read(raw, "static.npz"))
    assert idle._claim("r-crashed") is not None
    # After the restart (create_app recovers), the report completes.
    again = make_app(tmp_path)
    c = again.test_client()
    deadline = time.monotonic() + 90
    while (rep := c.get("/api/v1/reports/r-crashed", headers=h).get_json())["status"] == "pending":
        assert time.monotonic() < deadline
        time.sleep(0.2)
    assert rep["status"] == "done", rep["error"]
    with store.engine.connect() as conn:
        assert conn.execute(select(db.report_uploads)).first() is None  # the upload is dropped once done
    again.extensions["pdr"].worker.stop()
    again.extensions["pdr"].reports.stop()


def test_report_interrupted_too_often_fails_with_the_reason(app, tokens):
    from server.report_jobs import MAX_ATTEMPTS, ReportRunner

    store = app.extensions["pdr"].store
    with store.engine.begin() as conn:
        uid = auth.user_id(conn, "alice")
    runner = ReportRunner(store, enqueue=lambda report_id: None)
    from pdr.io.native import batch_from_json

    runner.create("r-poison", uid, "x.npz", b"anything", "/x.npz", batch_from_json(phone_batch("b0", 0.0)))
    assert runner._claim("r-poison") is not None
    assert runner._claim("r-poison") is None  # a fresh claim (heartbeat) is another process's run: left alone
    for _ in range(MAX_ATTEMPTS - 1):
        assert runner._claim("r-poison", take_over=True) is not None  # each claim is an attempt a crash interrupted
    assert runner._claim("r-poison", take_over=True) is None
    with store.engine.connect() as conn:
        row = conn.execute(select(db.reports).where(db.reports.c.id == "r-poison")).one()
    assert row.status == "failed" and f"interrupted {MAX_ATTEMPTS} times" in row.error


def test_a_second_run_of_one_report_is_harmless_whichever_finishes_first(app, tokens):
    """A report's job thought lost is queued again while its first run still goes on (or a run is taken over after
    its heartbeat stalled): two runs hold claims. Only the latest claim stores a result, once; the other run's
    result is dropped without an error, and its heartbeat no longer refreshes the report."""
    from server.report_jobs import ReportRunner, _Heartbeat
    from tests.server.test_models_reports import _static_npz

    store = app.extensions["pdr"].store
    with store.engine.begin() as conn:
        uid = auth.user_id(conn, "alice")
    runner = ReportRunner(store, enqueue=lambda report_id: None)
    raw = _static_npz()
    recording = _read(raw, "static.npz")

    def files_and_row(report_id: str) -> tuple[list[str], Any]:
        with store.engine.connect() as conn:
            names = [r.name for r in conn.execute(select(db.report_files.c.name)
                                                   .where(db.report_files.c.report_id == report_id))]
            return names, conn.execute(select(db.reports).where(db.reports.c.id == report_id)).one()

    for first_to_finish in ("superseded", "latest"):
        rid = f"r-twice-{first_to_finish}"
        runner.create(rid, uid, "static.npz", raw, "static_npz/static.npz", recording)
        old = runner._claim(rid)
        new = runner._claim(rid, take_over=True)
        assert old is not None and new is not None and (old.attempt, new.attempt) == (1, 2)
        order = (old, new) if first_to_finish == "superseded" else (new, old)
        for claim in order:
            runner._characterise(rid, claim)  # raises nothing (a duplicate file row would)
        names, row = files_and_row(rid)
        assert row.status == "done" and row.attempts == 2 and row.error is None
        assert sorted(names) == sorted(set(names)) and "report.json" in names
        with store.engine.connect() as conn:
            assert conn.execute(select(db.report_uploads).where(db.report_uploads.c.report_id == rid)).first() is None
    # the superseded run's heartbeat leaves the report alone; the latest run's keeps it fresh
    rid = "r-beat"
    runner.create(rid, uid, "static.npz", raw, "static_npz/static.npz", recording)
    old, new = runner._claim(rid), runner._claim(rid, take_over=True)
    assert old is not None and new is not None
    long_ago = db.utcnow() - timedelta(hours=1)
    for claim, refreshed in ((old, False), (new, True)):
        with store.engine.begin() as conn:
            conn.execute(update(db.reports).where(db.reports.c.id == rid).values(started_at=long_ago))
        assert _Heartbeat(store, rid, claim.attempt, period_s=1.0).beat() is refreshed
        _, row = files_and_row(rid)
        assert (row.started_at.replace(tzinfo=None) > long_ago.replace(tzinfo=None)) is refreshed, claim.attempt


def _read(payload: bytes, name: str):
    """The recording the upload ``payload`` named ``name`` holds, read as the service reads it."""
    from server.sandbox import read_isolated

    return read_isolated(payload, name)[1]


@pytest.mark.slow
def test_allan_reports_run_as_worker_jobs_and_recover_on_the_redis_back_end(tmp_path, pg_database,  # noqa: F811
                                                                             redis_namespace):  # noqa: F811
    """PDR_WORKER=redis: a report is a job of ``pdr worker``, not of the web process; a report whose job was lost
    (Redis emptied before any worker ran) and one whose run was interrupted (a worker killed mid-run leaves it
    started, with no heartbeat) are both finished by the worker's reconciler."""
    from server.bench.cluster import running_cluster
    from server.db import make_engine
    from server.queue import purge_namespace, redis_client
    from tests.server.test_models_reports import _static_npz

    redis_url, ns = redis_namespace
    body, ctype = multipart({"file": (_static_npz(seconds=60.0), "static.npz")})
    engine = make_engine(pg_database.replace("postgresql://", "postgresql+psycopg://", 1))
    with running_cluster(tmp_path, pg_database, redis_url, ns, webs=1, workers=0,
                         worker_args=["--reconcile-s", "1", "-v"]) as cluster:
        c = Client(cluster.urls[0], add_user(cluster.env, "ada"))
        ids = []
        for _ in range(3):
            r = c.request("POST", "/api/v1/reports/allan", raw=body, content_type=ctype)
            assert r.status == 202, r.body
            ids.append(r.json()["id"])
        time.sleep(1.0)
        assert {c.request("GET", f"/api/v1/reports/{i}").json()["status"] for i in ids} == {"pending"}  # no worker
        # ids[0]: its job is queued; ids[1]: its job is lost; ids[2]: a run started 5 min ago and was interrupted.
        conn_redis = redis_client(redis_url)
        for lost in ids[1:]:  # the flag holds the id of the report's queued job
            job_id = conn_redis.getdel(f"{ns}:report:{lost}")
            assert isinstance(job_id, bytes) and conn_redis.lrem(f"rq:queue:{ns}", 0, job_id.decode()) == 1
        with engine.begin() as conn:
            conn.execute(update(db.reports).where(db.reports.c.id == ids[2]).values(
                attempts=1, started_at=db.utcnow() - timedelta(minutes=5)))
        cluster.start_worker(f"{ns}-w0")
        deadline = time.monotonic() + 180
        while {(rep := c.request("GET", f"/api/v1/reports/{i}").json())["status"] for i in ids} != {"done"}:
            assert rep["status"] != "failed", rep
            assert time.monotonic() < deadline, [c.request("GET", f"/api/v1/reports/{i}").json() for i in ids]
            time.sleep(0.5)
        logs = (tmp_path / f"{ns}-w0.log").read_text()
        c.close()
        purge_namespace(conn_redis, ns)
        conn_redis.close()
    with engine.connect() as conn:
        rows = {r.id: r for r in conn.execute(select(db.reports.c.id, db.reports.c.attempts))}
        assert conn.execute(select(db.report_uploads)).first() is None  # uploads dropped once done
    engine.dispose()
    assert [rows[i].attempts for i in ids] == [1, 1, 2]  # each ran once more; the interrupted run counted
    assert "reconciler queued" in logs and logs.count("Successfully completed Allan report") >= 3  # the worker's jobs
    assert "Traceback" not in logs



def test_every_operations_documented_scope_is_the_one_the_service_enforces(app, client, tokens):
    """Each authenticated operation of the OpenAPI document, called with a token of each scope: refused for its scope
    (403; the Sensor Logger route answers the app's 499) exactly when its ``x-token-scope`` is not the token's (a
    full token may do all), whatever else the answer is (the path parameters name nothing, so allowed calls get 4xx
    of another kind)."""
    with app.extensions["pdr"].store.engine.begin() as conn:
        uid = auth.user_id(conn, "alice")
        scoped = {scope: auth.issue_token(conn, uid, scope) for scope in auth.SCOPES}
    doc = client.get("/api/v1/openapi.json").get_json()
    checked = 0
    for path, ops in doc["paths"].items():
        url = re.sub(r"\{(\w+)\}", lambda m: "left_foot" if m.group(1) == "role" else "nothing-here", path)
        for method, op in ops.items():
            if "x-token-scope" not in op:
                continue
            for scope, token in scoped.items():
                r = client.open(url, method=method.upper(), headers=bearer(token), json={})
                allowed = scope in ("full", op["x-token-scope"])
                refused = r.status_code in (403, 499) and b"does not allow this request" in r.get_data()
                assert refused is not allowed, (method, path, scope, r.status_code, r.get_data()[:200])
                assert r.status_code < 500, (method, path, scope, r.get_data()[:300])
            checked += 1
    assert checked > 30
