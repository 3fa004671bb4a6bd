"""An uploaded file is read from a temporary folder: nothing the service answers names that folder."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pdr.recording import DeviceInfo, Recording, SensorStream
from server.sandbox import TEMP_PREFIX, without_temp_names
from tests.server.conftest import bearer
from tests.server.helpers import multipart


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
