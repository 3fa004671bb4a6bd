"""`pdr serve` compiles the kernels in the background into a cache under its data directory (issue 26 item 11), in two
processes when the cache is fresh (server.warmup)."""

from __future__ import annotations

import time

import pytest

from server.client import Client, running_server


@pytest.mark.slow
def test_serve_warms_the_kernels_into_the_data_directory_and_health_says_so(tmp_path, monkeypatch) -> None:
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)     # the service picks its cache: the data directory's
    data = tmp_path / "data"
    with running_server(data) as (url, _, _):
        client = Client(url, timeout_s=10.0)
        body = first = client.request("GET", "/api/v1/health").json()
        states = [first["status"]]
        deadline = time.monotonic() + 550
        while body["kernels"]["state"] != "ready" and time.monotonic() < deadline:
            time.sleep(1.0)
            body = client.request("GET", "/api/v1/health").json()
            states.append(body["status"])
        client.close()
    assert first["kernels"]["state"] == "warming up" and first["status"] == "warming up"
    assert body["kernels"]["state"] == "ready" and body["kernels"]["error"] is None, body
    assert body["status"] == "ok"
    assert set(states) <= {"warming up", "ok"}
    assert any((data / "numba-cache").rglob("*.nbi")), "no numba index files in the data directory's cache"
    # A fresh cache: a second process compiled the kernels after the attitude filter's meanwhile (server.warmup).
    assert body["kernels"]["helper"]["exit"] == 0 and body["kernels"]["helper"]["seconds"] > 0, body
    # Started again on that cache, the service needs no second process.
    with running_server(data) as (url, _, _):
        client = Client(url, timeout_s=10.0)
        deadline = time.monotonic() + 120
        while (body := client.request("GET", "/api/v1/health").json())["kernels"]["state"] != "ready" and (
                time.monotonic() < deadline):
            time.sleep(0.5)
        client.close()
    assert body["kernels"]["state"] == "ready" and body["kernels"]["helper"] is None, body
