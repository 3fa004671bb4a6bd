"""Access log: one INFO line per request on the ``pdr.access`` logger.

``METHOD PATH STATUS DURATION_ms user=ID``: the path without its query string (Sensor Logger puts its token
there), the status the application answered, the time until the response was complete, and the id of the
authenticated user (``-`` when the request was not authenticated). Never a token, a header or a body.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

log = logging.getLogger("pdr.access")

#: WSGI environ key where authentication leaves the user id for this log.
USER_KEY = "pdr.user_id"


def access_line(method: str, path: str, status: str, duration_s: float, user_id: object) -> str:
    """The log line of one request (``path`` must already be free of its query string)."""
    code = status.split(" ", 1)[0] if status else "-"
    return f"{method} {path} {code} {duration_s * 1e3:.1f}ms user={user_id if user_id is not None else '-'}"


class AccessLogMiddleware:
    """WSGI middleware writing :func:`access_line` once the response body has been sent."""

    def __init__(self, app: Any) -> None:
        self.app = app

    def __call__(self, environ: dict[str, Any], start_response: Callable[..., Any]) -> Iterable[bytes]:
        t0 = time.perf_counter()
        seen: dict[str, str] = {}

        def recording_start_response(status: str, headers: list[tuple[str, str]], exc_info: Any = None) -> Any:
            seen["status"] = status
            return start_response(status, headers, exc_info) if exc_info else start_response(status, headers)

        body = self.app(environ, recording_start_response)
        return self._logged(body, environ, seen, t0)

    def _logged(self, body: Iterable[bytes], environ: dict[str, Any], seen: dict[str, str],
                t0: float) -> Iterator[bytes]:
        try:
            yield from body
        finally:
            close = getattr(body, "close", None)
            if close is not None:
                close()
            log.info(access_line(environ.get("REQUEST_METHOD", "-"), environ.get("PATH_INFO", "-"),
                                 seen.get("status", "-"), time.perf_counter() - t0, environ.get(USER_KEY)))
