"""The error a request handler raises to answer the client with a status and a JSON body (:mod:`server.errors`
renders it). Its own module, so that the request plumbing (:mod:`server.limits`) can raise it without importing
the error handlers, which import that plumbing.
"""

from __future__ import annotations

from typing import Any

#: Error code of each status in the JSON body.
CODES = {400: "bad_request", 401: "unauthorized", 403: "forbidden", 404: "not_found", 405: "method_not_allowed",
         409: "conflict", 413: "payload_too_large", 415: "unsupported_media_type", 422: "invalid_input",
         429: "too_many_requests", 500: "internal_error", 503: "unavailable"}


class APIError(Exception):
    """An error answered to the client with ``status`` and a JSON body."""

    def __init__(self, status: int, message: str, *, code: str | None = None,
                 details: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.code = code or CODES.get(status, "error")
        self.message = message
        self.details = details or {}
