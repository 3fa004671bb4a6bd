"""``pdr phyphox URL --server S --token T`` against a fake phone (a real HTTP server speaking phyphox's remote-access
API, replaying an export) and a real service process: every sample arrives, once, on the export's clock."""

from __future__ import annotations

import argparse
import json
import threading
import time
import urllib.parse
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import phyphox
from pdr.io.phyphox_remote import PhyphoxRemote, get_path, streams_of_config
from pdr.recording import Recording
from tests.conftest import REPO_ROOT

#: A phyphox export (Android, 'multi-sensor': accelerometer with g, linear acceleration, gyroscope, magnetometer,
#: pressure, meta/time.csv). /work/shared/data holds no phyphox recording; this one is the readers' fixture.
EXPORT = REPO_ROOT / "tests" / "pdr" / "io" / "fixtures" / "phyphox" / "android_export"
#: kind -> (phyphox sensor source, axis buffers, time buffer), as phyphox's own experiments name them.
BUFFERS = {"acc": ("accelerometer", ("accX", "accY", "accZ"), "acc_time"),
           "lin_acc": ("linear_acceleration", ("linX", "linY", "linZ"), "lin_time"),
           "gyro": ("gyroscope", ("gyrX", "gyrY", "gyrZ"), "gyr_time"),
           "mag": ("magnetic_field", ("magX", "magY", "magZ"), "mag_time"),
           "baro": ("pressure", ("pressure",), "p_time")}


class FakePhone:
    """The export as phyphox serves it while measuring: each /get advances the experiment by ``step_s``."""

    def __init__(self, rec: Recording, step_s: float) -> None:
        self.start_ns = int(rec.meta["start_epoch_ns"])
        self.buffers: dict[str, np.ndarray] = {}
        self.time_of: dict[str, str] = {}
        for kind, s in rec.streams.items():
            _, axes, tname = BUFFERS[kind]
            self.buffers[tname] = (s.t_ns - self.start_ns) / 1e9
            for k, name in enumerate(axes):
                self.buffers[name] = s.values[:, k]
                self.time_of[name] = tname
        self.end_s = max(float(t[-1]) for n, t in self.buffers.items() if n.endswith("_time"))
        self.kinds = list(rec.streams)
        self.step_s = step_s
        self.now_s = 0.0
        self.measuring = False
        self.gets = 0

    def answer(self, path: str) -> Any:
        url = urllib.parse.urlsplit(path)
        if url.path == "/config":
            return {"title": "Multi sensor", "buffers": [{"name": n, "size": 0} for n in self.buffers],
                    "inputs": [{"source": BUFFERS[k][0], "outputs": [*({a: n} for a, n in zip(
                        ("x", "y", "z") if k != "baro" else ("x",), BUFFERS[k][1], strict=True)),
                        {"t": BUFFERS[k][2]}]} for k in self.kinds]}
        if url.path == "/meta":
            return {"deviceModel": "Pixel 7", "deviceBrand": "google"}
        if url.path == "/time":
            return [{"event": "START", "experimentTime": 0.0, "systemTime": self.start_ns / 1e9}]
        if url.path == "/control":
            self.measuring = urllib.parse.parse_qs(url.query)["cmd"] == ["start"]
            return {"result": True}
        if url.path == "/get":
            self.gets += 1
            if self.measuring:
                self.now_s += self.step_s
                self.measuring = self.now_s < self.end_s
            out = {}
            for name, spec in urllib.parse.parse_qs(url.query).items():
                bound, _, tname = spec[0].partition("|")
                t = self.buffers[tname or self.time_of.get(name, name)]
                keep = t <= self.now_s
                if bound != "full":
                    keep &= t > float(bound)
                out[name] = {"size": 0, "updateMode": "partial", "buffer": self.buffers[name][keep].tolist()}
            return {"buffer": out, "status": {"session": "5c2e6b", "measuring": self.measuring, "timedRun": False,
                                              "countDown": 0}}
        return None


@contextmanager
def serving(phone: FakePhone) -> Iterator[str]:
    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - the http.server protocol
            body = phone.answer(self.path)
            data = json.dumps(body).encode()
            self.send_response(404 if body is None else 200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def log_message(self, *args: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def _fetch(phone: FakePhone):  # noqa: ANN202
    return lambda path: json.dumps(phone.answer(path)).encode()


def test_remote_polls_give_the_export_once_on_its_clock():
    rec = phyphox.read(EXPORT)
    phone = FakePhone(rec, step_s=0.7)
    remote = PhyphoxRemote(_fetch(phone)).connect()
    assert remote.device.model == "Pixel 7" and {s.kind for s in remote.streams} == set(rec.streams)
    remote.control("start")
    got: dict[str, list[np.ndarray]] = {k: [] for k in rec.streams}
    while True:
        batch = remote.poll()
        if batch is not None:
            for k, s in batch.streams.items():
                got[k].append(s.t_ns)
        if not remote.measuring and batch is None:
            break
    assert phone.gets > 3
    for kind, s in rec.streams.items():
        t = np.concatenate(got[kind])
        # every sample once, in order, on the export's epoch clock (to the float precision of /time's seconds)
        assert t.size == len(s) and np.abs(t - s.t_ns).max() < 1000, kind


def test_config_without_sensors_and_partial_queries():
    with pytest.raises(InputError, match="records no accelerometer"):
        streams_of_config({"inputs": [{"source": "audio", "outputs": [{"out": "recording"}]}]})
    streams = streams_of_config({"inputs": [{"source": "gyroscope", "outputs": [
        {"x": "gyrX"}, {"y": "gyrY"}, {"z": "gyrZ"}, {"t": "gyr_time"}]}]})
    assert get_path(streams, {"gyro": None}) == "/get?gyrX=full&gyrY=full&gyrZ=full&gyr_time=full"
    assert get_path(streams, {"gyro": 1.5}) == ("/get?gyrX=1.5|gyr_time&gyrY=1.5|gyr_time&gyrZ=1.5|gyr_time"
                                                "&gyr_time=1.5")


def _run_cli(argv: list[str]) -> int:
    from pdr.cli.phyphox import register

    parser = argparse.ArgumentParser(prog="pdr")
    register(parser.add_subparsers())
    args = parser.parse_args(argv)
    return int(args.func(args))


def test_pdr_phyphox_streams_native_batches_into_a_live_session(tmp_path: Path, capsys):
    from server.client import Client, add_user, running_server

    rec = phyphox.read(EXPORT)
    phone = FakePhone(rec, step_s=0.25)
    with serving(phone) as phone_url, running_server(tmp_path / "srv") as (url, env, _):
        token = add_user(env, "pia")
        assert _run_cli(["phyphox", phone_url, "--server", url, "--token", token, "--start", "--interval", "0",
                         "--session-id", "walk-1", "--placement", "hand"]) == 0
        c = Client(url, token)
        for _ in range(600):  # until the worker has processed every batch
            session = c.request("GET", "/api/v1/sessions/walk-1").json()
            if set(session["batches"]) == {"done"}:
                break
            time.sleep(0.1)
        c.close()
    assert session["placement"] == "hand" and session["devices"][0]["model"] == "Pixel 7"
    assert set(session["batches"]) == {"done"} and session["batches"]["done"] >= 3   # several live batches
    assert abs(session["clock"]["t0_ns"] - min(int(s.t_ns[0]) for s in rec.streams.values())) < 1000
    out = capsys.readouterr().out
    total = sum(len(s) for s in rec.streams.values())
    assert f"{sum(session['batches'].values())} batches, {total} samples -> session {session['id']}" in out
