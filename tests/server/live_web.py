"""Shared helpers of the web page's browser tests: the app on a real loopback HTTP socket, signing in, screenshots.

The browser itself is the session-wide ``browser`` fixture of ``tests/server/conftest.py`` (one Playwright instance
for the whole run); this module holds no fixture. Screenshots go under the system's temporary folder
(``$TMPDIR/pdr-test-artifacts/web/``), or under ``$PDR_TEST_ARTIFACTS/web/`` when that is set (CI keeps them).
"""

from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path
from typing import Any

from server import auth
from server.app import create_app
from tests.server.web_seed import WebTestProcessor


def artifacts_dir() -> Path:
    """Where the screenshots go (created on use)."""
    root = os.environ.get("PDR_TEST_ARTIFACTS") or os.path.join(tempfile.gettempdir(), "pdr-test-artifacts")
    return Path(root) / "web"


def shot(page: Any, name: str) -> Path:
    """A full-page screenshot ``NAME.png`` of ``page``; returns its path."""
    out = artifacts_dir()
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    return path


class LiveApp:
    """The real application with the web test processor, served by werkzeug in a thread on 127.0.0.1, and its users.

    ``overrides``: more settings of :func:`server.app.create_app` (e.g. ``map_tile_url``).
    """

    def __init__(self, data_dir: Path, users: tuple[str, ...] = ("alice", "bob"), **overrides: Any) -> None:
        from werkzeug.serving import make_server

        self.app = create_app({"data_dir": str(data_dir), "processor_factory": WebTestProcessor, "settle_s": 0.0,
                               **overrides})
        self.store = self.app.extensions["pdr"].store
        with self.store.engine.begin() as conn:
            self.tokens = {name: auth.add_user(conn, name) for name in users}
        self.server = make_server("127.0.0.1", 0, self.app, threaded=True)
        self.url = f"http://127.0.0.1:{self.server.server_port}"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.thread.join(timeout=10)
        self.app.extensions["pdr"].worker.stop()


def sign_in(page: Any, live: LiveApp, user: str = "alice") -> None:
    """Open the page, sign in with ``user``'s token and wait for the sessions list."""
    page.goto(live.url + "/")
    page.fill("#token", live.tokens[user])
    page.click("#signin-form button[type=submit]")
    page.wait_for_selector("#sessions-table tbody tr")
