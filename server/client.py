"""A small HTTP client of the API (standard library only), for replay tools, benchmarks and tests."""

from __future__ import annotations

import http.client
import json
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit


@dataclass
class Reply:
    status: int
    body: bytes
    seconds: float

    def json(self) -> Any:
        return json.loads(self.body)


class Client:
    """Keeps one HTTP/1.1 connection to the service (not thread-safe: one per thread)."""

    def __init__(self, base_url: str, token: str | None = None, timeout_s: float = 60.0) -> None:
        parts = urlsplit(base_url)
        self.host = parts.hostname or "127.0.0.1"
        self.port = parts.port or 80
        self.token = token
        self.timeout_s = timeout_s
        self._conn: http.client.HTTPConnection | None = None

    def request(self, method: str, path: str, body: Any = None, raw: bytes | None = None,
                content_type: str = "application/json") -> Reply:
        data = raw if raw is not None else (json.dumps(body).encode() if body is not None else None)
        headers = {"Content-Type": content_type} if data is not None else {}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        for attempt in (0, 1):
            if self._conn is None:
                self._conn = http.client.HTTPConnection(self.host, self.port, timeout=self.timeout_s)
            t0 = time.perf_counter()
            try:
                self._conn.request(method, path, body=data, headers=headers)
                resp = self._conn.getresponse()
                payload = resp.read()
                return Reply(resp.status, payload, time.perf_counter() - t0)
            except (ConnectionError, http.client.HTTPException, OSError):
                self.close()
                if attempt:
                    raise
        raise AssertionError("unreachable")

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def pdr_command() -> list[str]:
    """How to run the ``pdr`` CLI of this installation."""
    return [sys.executable, "-c", "import sys; from pdr.cli import main; sys.exit(main())"]


def add_user(env: dict[str, str], name: str) -> str:
    """Create a user through ``pdr users add`` with the given environment; returns its token."""
    out = subprocess.run([*pdr_command(), "users", "add", name], env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip().splitlines()[-1]


def start_server(data_dir: Path, extra_env: dict[str, str] | None = None, port: int | None = None
                 ) -> tuple[subprocess.Popen[bytes], str, dict[str, str]]:
    """Start ``pdr serve`` on a loopback port with its data in ``data_dir`` (log in ``server.log``) without waiting
    for it; returns (process, url, environment).
    """
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "PDR_DATABASE_URL")}
    env.update({"PDR_DATA_DIR": str(data_dir), **(extra_env or {})})
    port = port or free_port()
    data_dir.mkdir(parents=True, exist_ok=True)
    with (data_dir / "server.log").open("ab") as log:
        proc = subprocess.Popen([*pdr_command(), "serve", "--port", str(port)], env=env,
                                stdout=log, stderr=subprocess.STDOUT)
    return proc, f"http://127.0.0.1:{port}", env


def stop_server(proc: subprocess.Popen[bytes], timeout_s: float = 10.0) -> None:
    """Terminate a server process, killing it when it does not exit within ``timeout_s`` (s)."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextmanager
def running_server(data_dir: Path, extra_env: dict[str, str] | None = None,
                   port: int | None = None) -> Iterator[tuple[str, dict[str, str], subprocess.Popen[bytes]]]:
    """Start ``pdr serve`` on a free loopback port with its data in ``data_dir``; yields (url, env, process)."""
    proc, url, env = start_server(data_dir, extra_env, port)
    try:
        wait_healthy(url, proc, log_path=data_dir / "server.log")
        yield url, env, proc
    finally:
        stop_server(proc)


def wait_healthy(url: str, proc: subprocess.Popen[bytes] | None = None, timeout_s: float = 60.0,
                 log_path: Path | None = None) -> None:
    """Poll ``/api/v1/health`` until it answers 200 (the server's log is quoted if it exits first)."""
    client = Client(url, timeout_s=2.0)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            err = log_path.read_text(errors="replace")[-2000:] if log_path and log_path.exists() else ""
            raise RuntimeError(f"server exited with {proc.returncode}: {err}")
        try:
            if client.request("GET", "/api/v1/health").status == 200:
                client.close()
                return
        except OSError:
            pass
        time.sleep(0.2)
    raise TimeoutError(f"server at {url} did not become healthy in {timeout_s} s")
