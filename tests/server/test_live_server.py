"""The real service process: ``pdr users`` and ``pdr serve`` share configuration; a kill loses no accepted batch."""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time

import pytest

from server.client import Client, add_user, pdr_command, running_server
from tests.server.helpers import phone_batch

pytestmark = pytest.mark.timeout(180)


def test_users_cli_add_revoke(tmp_path):
    env = {"PDR_DATA_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    token = add_user(env, "erin")
    assert token.startswith("pdr_")
    dup = subprocess.run([*pdr_command(), "users", "add", "erin"], env=env, capture_output=True, text=True)
    assert dup.returncode == 2 and "already exists" in dup.stderr
    with running_server(tmp_path) as (url, _, _):
        c = Client(url, token)
        assert c.request("GET", "/api/v1/sessions").status == 200
        out = subprocess.run([*pdr_command(), "users", "revoke", "erin"], env=env, capture_output=True, text=True)
        assert "revoked 1 token" in out.stdout
        assert c.request("GET", "/api/v1/sessions").status == 401
        c.close()


def test_kill_during_upload_loses_no_accepted_batch(tmp_path):
    acknowledged: list[str] = []
    with running_server(tmp_path) as (url, env, proc):
        token = add_user(env, "frank")
        c = Client(url, token)
        sid = c.request("POST", "/api/v1/sessions", {"session_id": "killed"}).json()["id"]
        bodies = [json.dumps(phone_batch(f"b{i:04d}", float(i))).encode() for i in range(400)]

        def upload() -> None:
            uploader = Client(url, token, timeout_s=5.0)
            for i, body in enumerate(bodies):
                try:
                    r = uploader.request("POST", f"/api/v1/sessions/{sid}/batches", raw=body)
                except OSError:
                    break
                if r.status in (200, 201):
                    acknowledged.append(f"b{i:04d}")
            uploader.close()

        t = threading.Thread(target=upload)
        t.start()
        while len(acknowledged) < 40:
            time.sleep(0.01)
        c.close()
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        t.join()
    assert 40 <= len(acknowledged) < 400

    with running_server(tmp_path) as (url, _, _):
        c = Client(url, token)
        deadline = time.monotonic() + 60
        while True:
            detail = c.request("GET", f"/api/v1/sessions/{sid}").json()
            if detail["batches"].get("pending", 0) == 0 and detail["batches"].get("processing", 0) == 0:
                break
            assert time.monotonic() < deadline, detail["batches"]
            time.sleep(0.2)
        stored = {b["batch_id"] for b in detail["batch_list"]}
        c.close()
    assert set(acknowledged) <= stored
