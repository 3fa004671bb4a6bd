"""Clear answers while degraded: a data-directory quota (507) and an unreachable database (503).

- ``PDR_DATA_QUOTA_MB``: before a write request is read, the size of the data directory (the SQLite
  database, its WAL, report files) plus the declared body is compared with the quota; over it the
  request is refused with 507 Insufficient Storage and a message saying so. Batches accepted before
  stay stored and processed; reads keep working. The Sensor Logger endpoint answers 499 with the same
  message because that app shows only 499 bodies to its user.
- A database that refuses or drops connections (a PostgreSQL restart, a locked or full SQLite file)
  answers 503 with ``Retry-After`` instead of a 500: nothing of the request was stored, retrying is safe
  (uploads are idempotent by batch id). A full SQLite disk answers 507.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from flask import Flask, Response, request
from sqlalchemy import exc as sa_exc

from server.config import Settings
from server.errors import error_response

WRITE_METHODS = {"POST", "PUT", "PATCH"}
RETRY_AFTER_S = 5


def directory_bytes(path: Path) -> int:
    """Total size of the regular files under ``path``, bytes."""
    total = 0
    stack = [path]
    while stack:
        try:
            with os.scandir(stack.pop()) as it:
                for entry in it:
                    try:
                        if entry.is_dir(follow_symlinks=False):
                            stack.append(Path(entry.path))
                        elif entry.is_file(follow_symlinks=False):
                            total += entry.stat(follow_symlinks=False).st_size
                    except OSError:
                        continue
        except OSError:
            continue
    return total


class DataQuota:
    """The data directory's usage against its quota; usage is re-measured at most every ``refresh_s``."""

    def __init__(self, data_dir: Path, quota_bytes: int, refresh_s: float = 1.0) -> None:
        self.data_dir = data_dir
        self.quota_bytes = quota_bytes
        self.refresh_s = refresh_s
        self._measured = (-1e9, 0)
        self._lock = threading.Lock()

    def usage_bytes(self) -> int:
        with self._lock:
            t, used = self._measured
            now = time.monotonic()
            if now - t > self.refresh_s:
                used = directory_bytes(self.data_dir)
                self._measured = (now, used)
            return used

    def refusal(self, incoming_bytes: int) -> str | None:
        """Why a write of ``incoming_bytes`` must be refused, or None if it fits."""
        if self.quota_bytes <= 0:
            return None
        used = self.usage_bytes()
        if used + incoming_bytes <= self.quota_bytes:
            return None
        return ("server storage quota of the data directory reached: this upload was refused and not stored; "
                "data accepted earlier is kept. Retry after the operator frees space or raises PDR_DATA_QUOTA_MB")


def install(app: Flask, settings: Settings) -> None:
    """Register the quota check and the storage-failure handlers on ``app``."""
    quota = DataQuota(settings.data_dir, settings.data_quota_bytes)
    app.extensions["pdr_quota"] = quota

    @app.before_request
    def _check_quota() -> Response | None:
        if request.method not in WRITE_METHODS or not request.path.startswith("/api/"):
            return None
        reason = quota.refusal(request.content_length or 0)
        if reason is None:
            return None
        if request.blueprint == "ingest":
            return Response(f"pdr: {reason}"[:300], status=499, mimetype="text/plain")
        return error_response(507, reason, "insufficient_storage")

    def _storage_failure(exc: Exception) -> Response:
        text = str(exc).lower()
        if "database or disk is full" in text or "no space left" in text:
            return error_response(507, "server storage is full: the request was not stored; retry later",
                                  "insufficient_storage")
        resp = error_response(503, "storage temporarily unavailable (database connection failed): the request "
                                   "was not stored; retry later (uploads are idempotent by batch id)", "unavailable")
        resp.headers["Retry-After"] = str(RETRY_AFTER_S)
        return resp

    for cls in (sa_exc.OperationalError, sa_exc.InterfaceError, sa_exc.DisconnectionError, sa_exc.TimeoutError):
        app.register_error_handler(cls, _storage_failure)
