"""Helpers of the server tests: native batches and multipart bodies to send, waiting for a real server."""

from __future__ import annotations

import io
import json
import time
from dataclasses import replace
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.io.native import batch_to_json
from pdr.recording import DeviceInfo, GroundTruth, Recording, SensorStream
from server.client import Client


def phone_batch(batch_id: str, start_s: float, duration_s: float = 1.0, rate_hz: float = 50.0,
                role: str = "phone") -> dict[str, Any]:
    """A native batch of a phone at rest: acc (0, 0, 9.81) and zero gyro, epoch-ns timestamps."""
    n = int(round(duration_s * rate_hz))
    t_ns = (1_700_000_000_000_000_000 + np.round((start_s + np.arange(n) / rate_hz) * 1e9)).astype(np.int64)
    rec = Recording({"acc": SensorStream("acc", t_ns, np.tile([0.0, 0.0, 9.81], (n, 1))),
                     "gyro": SensorStream("gyro", t_ns, np.zeros((n, 3)))},
                    DeviceInfo(platform="android", model="test", role=role), t0_ns=1_700_000_000_000_000_000)
    return batch_to_json(rec, session_id="s1", batch_id=batch_id)


def one_second_batches(rec: Recording, session_id: str) -> list[dict[str, Any]]:
    """``rec`` cut into native batches of 1 s, samples only (no reference truth): what a device sends."""
    t0, t1 = rec.time_span_s()
    out = []
    for i, a in enumerate(np.arange(t0, t1 + 1.0, 1.0)):
        try:
            part = rec.slice_time(float(a), float(a) + 1.0)
        except InputError:  # no sample in this second
            continue
        out.append(batch_to_json(replace(part, truth=GroundTruth()), session_id=session_id, batch_id=f"b{i:04d}"))
    return out


def as_bytes(obj: Any) -> bytes:
    return json.dumps(obj).encode()


def multipart(fields: dict[str, Any]) -> tuple[bytes, str]:
    """A multipart/form-data body built in memory (the test client spools large ones to a temp file it never
    closes); values are strings or ``(bytes, filename)`` pairs. Returns (body, content type)."""
    from werkzeug.datastructures import FileStorage
    from werkzeug.test import encode_multipart

    values = {k: FileStorage(io.BytesIO(v[0]), filename=v[1]) if isinstance(v, tuple) else v for k, v in fields.items()}
    boundary, body = encode_multipart(values)
    return body, f"multipart/form-data; boundary={boundary}"


def wait_processed(client: Client, session_id: str, timeout_s: float = 600.0) -> dict[str, Any]:
    """The session's detail once a real server has processed every batch of it (status done or failed, nothing
    pending); fails the test after ``timeout_s`` (a loaded machine compiles the foot kernels slowly)."""
    deadline = time.monotonic() + timeout_s
    while True:
        s = client.request("GET", f"/api/v1/sessions/{session_id}").json()
        if s["status"] in ("done", "failed") and not s["batches"].get("pending"):
            return s
        assert time.monotonic() < deadline, s
        time.sleep(0.3)


def legacy_session(url: str, revision: str) -> tuple[Any, Any, int, str]:
    """A database at the older migration ``revision`` with one user and one session, as a migration test starts:
    the Alembic configuration, the engine (dispose it), the user's id and the session's id.
    """
    import sqlalchemy as sa
    from alembic import command

    from server import auth, db, migrations
    from server.store import Store

    cfg = migrations.alembic_config(url)
    command.upgrade(cfg, revision)
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        auth.add_user(conn, "legacy")
    with engine.connect() as conn:
        user = int(conn.execute(sa.select(db.users.c.id)).scalar_one())
    sid, _ = Store(engine).create_session(user, source="native", client_session_id="walk")
    return cfg, engine, user, sid
