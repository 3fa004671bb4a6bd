"""End to end: the real ``pdr serve`` process fed Sensor Logger push messages in 1 s batches (one sent twice,
two swapped) gives exactly the track of ``pdr track`` on the same log (the IPIN log the streamed causal track,
the Sensor Logger walk the offline-smoothed one, ``?heading=smoothed``).

Logs: a real IPIN logfile (hand-held, AppTimestamp clock; pushed with ``?placement=hand``, which its reader
knows and push messages cannot say) and a Sensor Logger recording (a JSON file of push
messages of a simulated hand-held walk on the epoch clock, as the app's HTTP push would send it).
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest

from pdr.cli import main as pdr_main
from pdr.io import read_recording
from pdr.io.sensor_logger_writer import to_push_messages
from pdr.sim import parse_scenario, simulate
from server.client import Client, add_user, running_server
from tests.conftest import data_path

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]
#: ``pdr track`` CSV precision per column; server values (full precision) are rounded the same way.
FORMATS = {"t_s": ".3f", "east_m": ".3f", "north_m": ".3f", "up_m": ".2f", "floor": "g", "heading_deg": ".1f",
           "step_length_m": ".3f"}


def _replay_order(n: int) -> list[int]:
    order = list(range(n))
    order[5], order[6] = order[6], order[5]  # reordered
    order.insert(12, 12)  # duplicated
    return order


def _pdr_track(log: Path, out: Path, smoother: str = "off") -> list[dict[str, str]]:
    # The service streams the causal track (`pdr track --smoother off`); ?heading=smoothed is pdr track's default.
    assert pdr_main(["track", str(log), "--out", str(out), "--smoother", smoother]) == 0
    with out.open() as f:
        return list(csv.DictReader(f))


def _server_track(messages: list[dict], data_dir: Path, heading: str = "causal", query: str = ""
                  ) -> tuple[list[dict[str, str]], dict]:
    with running_server(data_dir) as (url, env, _):
        token = add_user(env, "e2e")
        c = Client(url, token)
        for i in _replay_order(len(messages)):
            r = c.request("POST", f"/api/v1/ingest/sensor-logger?token={token}{query}", messages[i])
            assert r.status == 200, r.body[:300]
        deadline = time.monotonic() + 600
        while True:
            sessions = c.request("GET", "/api/v1/sessions").json()["sessions"]
            s = sessions[0]
            if s["status"] in ("done", "failed") and not s["batches"].get("pending"):
                break
            assert time.monotonic() < deadline, s
            time.sleep(0.5)
        text = c.request("GET", f"/api/v1/sessions/{s['id']}/track?format=csv&heading={heading}").body.decode()
        c.close()
    return list(csv.DictReader(text.splitlines())), s


def _assert_same(ours: list[dict[str, str]], server: list[dict[str, str]]) -> None:
    assert len(ours) > 20 and len(server) == len(ours)
    for a, b in zip(ours, server, strict=True):
        assert a["mode"] == b["mode"]
        for col, fmt in FORMATS.items():
            assert a[col] == format(float(b[col]), fmt), (col, a, b)


def test_ipin_logfile_replayed_as_push_messages(tmp_path):
    # Push messages carry the sensor streams, not the log's GNSS fix (the earth's field the magnetometer gate
    # checks, pdr.geomagnetic): pdr track gets the log without its GNSS records, as the server does.
    source = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt")
    log = tmp_path / source.name
    log.write_text("".join(ln for ln in source.read_text(encoding="ascii").splitlines(keepends=True)
                           if not ln.startswith("GNSS;")), encoding="ascii")
    rec = read_recording(log)
    assert "location" not in rec.meta
    messages = to_push_messages(rec, session_id="ipin-t01", device_id="SM-A520F")
    # Push messages do not carry the placement the IPIN reader knows (hand-held): the push URL says it.
    server, session = _server_track(messages, tmp_path / "srv", query=f"&placement={rec.device.placement}")
    assert session["batches"] == {"done": len(messages)} and session["status"] == "done"
    _assert_same(_pdr_track(log, tmp_path / "track.csv"), server)


def test_sensor_logger_recording_replayed(tmp_path):
    scenario = parse_scenario({"placement": "hand", "start_time_ns": 1_717_000_000_000_000_000,
                               "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "duration_s": 25},
                                            {"type": "turn", "angle_deg": 90}, {"type": "walk", "duration_s": 15}]})
    rec = simulate(scenario, seed=4)
    messages = to_push_messages(rec, session_id="sl-walk", device_id="pixel")
    log = tmp_path / "sensor_logger_push.json"
    log.write_text(json.dumps(messages))
    assert read_recording(log).format == "sensor_logger"
    server, _ = _server_track(messages, tmp_path / "srv", heading="smoothed")
    _assert_same(_pdr_track(log, tmp_path / "track.csv", smoother="on"), server)
