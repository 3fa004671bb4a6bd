"""An uploaded file is read from a temporary folder: nothing the service answers names that folder."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from pdr.recording import DeviceInfo, Recording, SensorStream
from server.sandbox import TEMP_PREFIX, without_temp_names
from tests.server.conftest import bearer
from tests.server.helpers import multipart, phone_batch


def test_without_temp_names_keeps_the_uploaded_name_only(tmp_path):
    folder = tmp_path / f"{TEMP_PREFIX}rpfql2fy"
    rec = Recording({"acc": SensorStream("acc", np.arange(3) * 10_000_000, np.zeros((3, 3)))},
                    device=DeviceInfo(model=folder.name, device_id="phone-7"), source=str(folder / "walk.csv"),
                    warnings=(f"{folder}/walk.csv: dropped 1 of 4 samples", f"{folder.name}: read alone"),
                    meta={"trial": folder.name, "files": [str(folder / "walk.csv")], "n": 3})
    out = without_temp_names(rec, folder, "walk.csv")
    assert out.source == "walk.csv" and out.device.model == "" and out.device.device_id == "phone-7"
    assert out.warnings == ("walk.csv: dropped 1 of 4 samples", "walk.csv: read alone")
    assert dict(out.meta) == {"trial": "", "files": ["walk.csv"], "n": 3}
    assert out.stream("acc") == rec.stream("acc")


def test_uploaded_log_names_no_temporary_folder(client, tokens):
    """A lone accelerometer file (Oxford layout) once took its device model from the server's temp folder."""
    lines = [f"{25468484780100 + i * 5_000_000},3,0.1,0.2,9.8" for i in range(400)]
    body, ctype = multipart({"file": ("\n".join(lines).encode() + b"\n", "accelerometer.csv")})
    h = bearer(tokens["alice"])
    r = client.post("/api/v1/sessions", data=body, headers=h, content_type=ctype)
    assert r.status_code == 201, r.get_json()
    session = client.get(f"/api/v1/sessions/{r.get_json()['id']}", headers=h).get_json()
    assert TEMP_PREFIX not in json.dumps(session) and "/tmp" not in json.dumps(session)
    (device,) = session["devices"]
    assert device["model"] == ""
    assert Path(session["name"]).name == "accelerometer.csv"


def test_every_answer_with_times_states_the_sessions_clock(client, tokens):
    """An Oxford upload's track is on its phone's time since boot (25 468 s here), an IPIN one's near 0: each answer
    says so (t0_ns, the recording's start on the log's clock, and what t_s means)."""
    t0 = 25468484780100
    lines = [f"{t0 + i * 5_000_000},3,0.1,0.2,9.8" for i in range(400)]
    body, ctype = multipart({"file": ("\n".join(lines).encode() + b"\n", "accelerometer.csv")})
    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", data=body, headers=h, content_type=ctype).get_json()["id"]
    for path in ("", "/track", "/steps", "/modes", "/landmarks", "/floors", "/truth"):
        clock = client.get(f"/api/v1/sessions/{sid}{path}", headers=h).get_json()["clock"]
        assert clock["t0_ns"] == t0 and clock["t0_s"] == t0 / 1e9, path
        assert "log's own clock" in clock["t_s"], path


MS_TRACE = Path(__file__).parents[2] / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz"


def _ms_trace(model: bytes) -> bytes:
    """The start of a real Microsoft indoor trace whose header names the phone ``model``."""
    text = gzip.decompress(MS_TRACE.read_bytes())
    return b"\n".join(text.split(b"\n")[:1500]).replace(b"Model:PBCM10", b"Model:" + model)


def _native_file(**device: str) -> bytes:
    batch = phone_batch("f", 0.0, duration_s=2.0)
    return json.dumps(batch | {"device": batch["device"] | device}).encode()


@pytest.mark.parametrize(("data", "name", "field", "why"), [
    (_ms_trace(b"M" * 201), "trace.txt", "model", "longer than 200"),
    (_native_file(device_id="phone\x00"), "walk.json", "device_id", "NUL"),
    (_native_file(model="a\x00b"), "walk.json", "model", "NUL")])
def test_a_log_file_naming_a_device_the_database_cannot_hold_is_a_422_and_stores_nothing(client, tokens, data, name,
                                                                                        field, why):
    """A log whose device model or id has more than the 200 characters of devices.model (a Microsoft trace's 'Model'
    header) or holds a NUL character (a native file's device) was a 500 in PostgreSQL after its batch was stored: a
    retry answered 200 and the session had no device (tests/server/test_postgres.py). It is a 422 naming the file
    and the device's field, with nothing stored, on every database."""
    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", json={"session_id": "paired"}, headers=h).get_json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "phone"}, headers=h).status_code == 201
    for route in ("/api/v1/sessions", f"/api/v1/sessions/{sid}/devices/phone/upload"):
        body, ctype = multipart({"file": (data, name)})
        resp = client.post(route, data=body, content_type=ctype, headers=h)
        assert resp.status_code == 422, resp.get_data()[:300]
        error = resp.get_json()["error"]
        assert error["details"] == {"field": "file", "device": field} and why in error["message"], error
    assert [s["id"] for s in client.get("/api/v1/sessions", headers=h).get_json()["sessions"]] == [sid]
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).get_json()["batch_list"] == []


@pytest.mark.parametrize("route", ["/api/v1/sessions", "/api/v1/sessions/{sid}/devices/phone/upload",
                                   "/api/v1/reports/allan", "/api/v1/sites"])
def test_a_file_whose_name_is_not_utf8_is_a_400_naming_the_field_file(client, tokens, route):
    """A multipart part whose file name is not UTF-8 (b'walk\\xff.json') makes Werkzeug drop the whole form without a
    word: POST /api/v1/sessions answered 415 'expected a JSON body', the other upload routes a 400 that named no field
    and said the file was missing. Each is a 400 naming the field 'file' and saying why it was not read."""
    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", json={"session_id": "paired"}, headers=h).get_json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/devices", json={"role": "phone"}, headers=h).status_code == 201
    raw = (b'--B\r\nContent-Disposition: form-data; name="file"; filename="walk\xff.json"\r\n'
           b"Content-Type: application/octet-stream\r\n\r\n" + _native_file() + b"\r\n--B--\r\n")
    resp = client.post(route.format(sid=sid), data=raw, content_type="multipart/form-data; boundary=B", headers=h)
    assert resp.status_code == 400, resp.get_data()[:300]
    error = resp.get_json()["error"]
    assert error["details"]["field"] == "file" and "UTF-8" in error["message"], error
    assert [s["id"] for s in client.get("/api/v1/sessions", headers=h).get_json()["sessions"]] == [sid]
