"""Issue 26 item 2: every upload is decoded once, at ingest, and processing reads what was decoded then.

A native batch is JSON-parsed and validated once, a Sensor Logger message likewise, an uploaded file is read by one
sandboxed reader (detection and reading in one child); the worker and the truth endpoint read the stored decoded
recording, never the raw payload again.
"""

from __future__ import annotations

import io
import json
import zlib
from collections import Counter
from pathlib import Path
from typing import Any

from sqlalchemy import select

from pdr import recording_codec
from pdr.io import read_recording
from server import db
from tests.server.conftest import bearer
from tests.server.helpers import multipart, phone_batch

SIM = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim"


def _count(monkeypatch: Any, calls: Counter[str], module: Any, name: str) -> None:
    real = getattr(module, name)

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls[name] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)


def _stored(app: Any, sid: str) -> list[Any]:
    with app.extensions["pdr"].store.engine.connect() as conn:
        return list(conn.execute(select(db.batches).where(db.batches.c.session_id == sid).order_by(db.batches.c.id)))


def test_native_batches_and_push_messages_are_parsed_once(app, client, tokens, monkeypatch):
    import pdr.io.native
    import pdr.io.sensor_logger

    calls: Counter[str] = Counter()
    _count(monkeypatch, calls, pdr.io.native, "batch_from_json")
    _count(monkeypatch, calls, pdr.io.sensor_logger, "parse_push_message")
    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", json={"session_id": "once"}, headers=h).get_json()["id"]
    for i in range(3):
        assert client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)),
                           headers=h).status_code == 201
    msg = {"messageId": 1, "sessionId": "push", "deviceId": "d",
           "payload": [{"name": "accelerometer", "time": 1_700_000_000_000_000_000 + k * 20_000_000,
                        "values": {"x": 0.0, "y": 0.0, "z": 9.81}} for k in range(50)]}
    r = client.post(f"/api/v1/ingest/sensor-logger?token={tokens['alice']}", data=json.dumps(msg),
                    content_type="application/json")
    assert r.status_code == 200, r.data
    app.extensions["pdr"].worker.wait_idle()
    assert calls == {"batch_from_json": 3, "parse_push_message": 1}  # in the views; the worker parsed none
    rows = _stored(app, sid) + _stored(app, r.get_json()["session"])
    assert [row.status for row in rows] == ["done"] * 4 and all(row.decoded is not None for row in rows)
    track = client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
    assert [p["east_m"] for p in track] == [1.0, 2.0, 3.0]


def test_uploaded_file_is_read_by_one_child_and_never_again(app, client, tokens, monkeypatch):
    import server.sandbox

    calls: Counter[str] = Counter()
    _count(monkeypatch, calls, server.sandbox, "read_isolated")
    h = bearer(tokens["alice"])
    raw = (SIM / "hand_escalator.zip").read_bytes()
    body, ctype = multipart({"file": (raw, "hand_escalator.zip")})
    r = client.post("/api/v1/sessions", data=body, headers=h, content_type=ctype)
    assert r.status_code == 201, r.get_json()
    sid = r.get_json()["id"]
    app.extensions["pdr"].worker.wait_idle()
    truth = client.get(f"/api/v1/sessions/{sid}/truth", headers=h).get_json()
    assert calls == {"read_isolated": 1}  # detection and reading in one child; processing and truth read none
    (row,) = _stored(app, sid)
    assert row.status == "done", row.error
    stored = recording_codec.loads(zlib.decompress(row.decoded))
    direct = read_recording(SIM / "hand_escalator.zip")
    assert stored == direct  # what the reader returned, truth included
    assert direct.truth.positions is not None and truth["count"] == len(direct.truth.positions.t_s) > 0


def test_allan_upload_is_read_once_in_the_request(app, client, tokens, monkeypatch):
    import server.sandbox
    from tests.server.test_models_reports import _static_npz

    calls: Counter[str] = Counter()
    _count(monkeypatch, calls, server.sandbox, "read_isolated")
    h = bearer(tokens["alice"])
    bad = client.post("/api/v1/reports/allan", headers=h, content_type="multipart/form-data",
                      data={"file": (io.BytesIO(b"not a log at all"), "x.csv")})
    assert bad.status_code == 422  # refused in the request: nothing stored, no job
    assert client.get("/api/v1/reports", headers=h).get_json()["reports"] == []
    body, ctype = multipart({"file": (_static_npz(seconds=60.0), "static.npz")})
    r = client.post("/api/v1/reports/allan", data=body, headers=h, content_type=ctype)
    assert r.status_code == 202, r.get_json()
    app.extensions["pdr"].reports.stop()  # waits for the job
    rep = client.get(f"/api/v1/reports/{r.get_json()['id']}", headers=h).get_json()
    assert rep["status"] == "done", rep["error"]
    assert calls == {"read_isolated": 2}  # the bad upload and the good one, each once; the job read none


def _increments(n: int) -> list[Any]:
    """``n`` steps of 0.7 m straight ahead, 0.5 s apart, each with a small diagonal covariance (eq. 8)."""
    import numpy as np

    from pdr.step_increment import StepIncrement

    return [StepIncrement(1.0 + 0.5 * k, 50 * k, np.array([0.7, 0.0, 0.0]), 0.0, np.diag([1e-4, 1e-4, 1e-4, 1e-5]))
            for k in range(n)]


def test_step_summaries_are_parsed_once_and_stored_decoded(real_app, token, monkeypatch):
    import pdr.foot.summaries
    import server.api.foot
    from pdr.foot import summaries_codec
    from pdr.foot.summaries import steps_to_json

    calls: Counter[str] = Counter()
    _count(monkeypatch, calls, server.api.foot, "steps_from_json")     # the view's parse
    _count(monkeypatch, calls, pdr.foot.summaries, "steps_from_json")  # any other (the worker's, before)
    client = real_app.test_client()
    h = bearer(token)
    sid = client.post("/api/v1/sessions", json={"session_id": "shoe"}, headers=h).get_json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "left_foot"}, headers=h).status_code == 201
    steps = _increments(6)
    for i in (0, 1):
        payload = steps_to_json(steps[3 * i:3 * i + 3], "left_foot", f"s{i}")
        r = client.post(f"/api/v1/sessions/{sid}/steps", json=payload, headers=h)
        assert r.status_code == 201, r.get_json()
    assert real_app.extensions["pdr"].worker.wait_idle(120)
    assert calls == {"steps_from_json": 2}  # once per payload, in the view; the worker parsed none
    rows = _stored(real_app, sid)
    assert [row.status for row in rows] == ["done", "done"], [row.error for row in rows]
    stored = summaries_codec.loads(zlib.decompress(rows[0].decoded))
    assert stored.role == "left_foot" and [s.t_s for s in stored.steps] == [s.t_s for s in steps[:3]]
    assert all((a.dp == b.dp).all() and (a.cov == b.cov).all() for a, b in zip(stored.steps, steps[:3], strict=True))
    track = client.get(f"/api/v1/sessions/{sid}/track?device=left_foot", headers=h).get_json()["points"]
    assert len(track) == 6 and abs(track[-1]["east_m"] ** 2 + track[-1]["north_m"] ** 2 - 4.2 ** 2) < 1e-6
