"""Fixtures: an app on a temporary SQLite database with a deterministic test processor, and two users; an app
with the real processors (``real_app``) and its user's ``token``."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from flask import Flask
from flask.testing import FlaskClient

from pdr.recording import Recording
from server import auth
from server.app import create_app
from server.processing import ProcessorOutput, SessionContext
from server.store import TrackRow


class CountingProcessor:
    """Test double: one track row per batch at the batch's last sample; state = batches seen."""

    def __init__(self, ctx: SessionContext, state: bytes | None) -> None:
        self.count = json.loads(state)["count"] if state else 0

    def update(self, recording: Recording) -> ProcessorOutput:
        self.count += 1
        last_ns = max(int(s.t_ns[-1]) for s in recording.streams.values())
        t = last_ns / 1e9
        return ProcessorOutput(track=[TrackRow(t, float(self.count), 0.0, 0.0, 0.0, 90.0, 1.0, "walking")])

    def to_bytes(self) -> bytes:
        return json.dumps({"count": self.count}).encode()


def make_app(tmp_path: Any, **overrides: Any) -> Flask:
    cfg = {"data_dir": str(tmp_path), "processor_factory": CountingProcessor, "settle_s": 0.0, **overrides}
    return create_app(cfg)


@pytest.fixture
def app(tmp_path: Any) -> Iterator[Flask]:
    app = make_app(tmp_path)
    yield app
    app.extensions["pdr"].worker.stop()


@pytest.fixture
def client(app: Flask) -> FlaskClient:
    return app.test_client()


@pytest.fixture
def tokens(app: Flask) -> dict[str, str]:
    with app.extensions["pdr"].store.engine.begin() as conn:
        return {"alice": auth.add_user(conn, "alice"), "bob": auth.add_user(conn, "bob")}


@pytest.fixture
def real_app(tmp_path: Any) -> Iterator[Flask]:
    app = create_app({"data_dir": str(tmp_path), "settle_s": 0.0})   # the real processor factory
    yield app
    app.extensions["pdr"].worker.stop()


@pytest.fixture
def token(real_app: Flask) -> str:
    with real_app.extensions["pdr"].store.engine.begin() as conn:
        return auth.add_user(conn, "walker")


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


# -- a real headless browser for the web page's tests (Debian's chromium driven by Playwright) ---------------------
# One session fixture for every module: Playwright's sync API cannot run two instances in one thread.
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


#: Held while one test process installs chromium: the suite's xdist workers each start the browser fixture, and on a
#: machine without chromium the second one's apt-get found dpkg locked by the first's and skipped its browser tests.
CHROMIUM_INSTALL_LOCK = Path(tempfile.gettempdir()) / "pdr-tests-chromium-install.lock"


def _install_chromium() -> str | None:
    """Install Debian's chromium when missing; returns why it is unavailable, or None when it is there.

    One test process installs at a time (:data:`CHROMIUM_INSTALL_LOCK`), and apt-get waits for a dpkg lock held by
    another program (``DPkg::Lock::Timeout``) instead of failing at once.
    """
    if CHROMIUM.exists():
        return None
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("apt-get") is None:
        return f"{CHROMIUM} is missing and cannot be installed here (needs root and apt-get)"
    with CHROMIUM_INSTALL_LOCK.open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)          # released when the file closes
        return None if CHROMIUM.exists() else _apt_install_chromium()


def _apt_install_chromium() -> str | None:
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    wait = ["-o", "DPkg::Lock::Timeout=600"]
    for cmd in (["apt-get", *wait, "update"], ["apt-get", *wait, "install", "-y", "chromium"]):
        try:
            done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
        except (OSError, subprocess.TimeoutExpired) as exc:
            return f"'{' '.join(cmd)}' failed: {exc}"
        if done.returncode != 0:
            return f"'{' '.join(cmd)}' failed: {done.stderr.strip()[-300:]}"
    return None if CHROMIUM.exists() else f"apt-get installed no {CHROMIUM}"


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed (test extra)")
    reason = _install_chromium()
    if reason:
        pytest.skip(reason)
    with sync_api.sync_playwright() as pw:
        try:
            b = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        except sync_api.Error as exc:
            pytest.skip(f"chromium does not start: {str(exc)[:300]}")
        yield b
        b.close()
