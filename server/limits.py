"""Request body limits per route, enforced from the headers before any of the body is read.

Three limits (bytes):

- file uploads (``POST /api/v1/sessions`` as multipart, ``POST /api/v1/reports/allan``): ``PDR_MAX_UPLOAD_MB``;
- every other write (ingest, native batches, foot steps, group uploads, JSON bodies): ``PDR_MAX_BATCH_MB``;
- reads and deletes (``GET``, ``HEAD``, ``DELETE``, ``OPTIONS``): :data:`NO_BODY_LIMIT_BYTES`.

:func:`body_limit` is the one place that decides. It is applied twice, so that it holds under any WSGI server:

- :class:`BodyLimitMiddleware` (WSGI): a declared ``Content-Length`` over the limit is answered 413 without
  reading the body; a body without a length (chunked) is read through a counting stream that raises 413 as soon
  as the limit is passed.
- :func:`limited_channel` (waitress, ``pdr serve``): waitress buffers the whole body (to a temporary file past
  512 KB) before it calls the application, so the WSGI check alone comes too late. Its request parser is
  subclassed to apply the same limit when the headers arrive (and while a chunked body streams in); the refused
  body is never buffered.

A gzip-compressed body (``Content-Encoding: gzip``, as phones and apps send their uploads) is inflated by
:class:`BodyLimitMiddleware` as the application reads it, under the same limit: the limit applies to the compressed
body from the headers (above) and to the inflated body as it is read (413 once more is inflated: a zip bomb is
refused as an uncompressed body of its size would be); a corrupt stream is a 400 naming the header. The
application then sees the plain body, without the header; any other encoding reaches it and is refused 415 there
(:func:`server.api.plain_body`).

The 413 body is the service's JSON error envelope and names the limit; on the Sensor Logger push route, whose app
shows its user only the text body of a 499 answer, it is a 499 with a text body (:func:`too_large_response`).
"""

from __future__ import annotations

import gzip
import json
import logging
import zlib
from collections.abc import Callable, Iterable
from typing import IO, Any, cast

from werkzeug.exceptions import RequestEntityTooLarge
from werkzeug.wsgi import LimitedStream

from server.api_error import APIError

log = logging.getLogger(__name__)

#: Body limit of reads and deletes, bytes (they carry no body).
NO_BODY_LIMIT_BYTES = 64 * 1024
#: Routes whose body is a whole log file (multipart) rather than a batch.
UPLOAD_PATHS = frozenset({"/api/v1/reports/allan"})
#: WSGI environ key holding the limit that applied to the request (quoted by the 413 handler).
ENVIRON_KEY = "pdr.body_limit"

BodyLimit = Callable[[str, str, str], int]


def make_body_limit(upload_bytes: int, batch_bytes: int) -> BodyLimit:
    """The limit function ``(method, path, content_type) -> bytes`` for the given upload and batch limits."""

    def body_limit(method: str, path: str, content_type: str) -> int:
        if method.upper() in ("GET", "HEAD", "DELETE", "OPTIONS"):
            return NO_BODY_LIMIT_BYTES
        if path in UPLOAD_PATHS or (path.rstrip("/") == "/api/v1/sessions"
                                    and content_type.lower().startswith("multipart/")):
            return upload_bytes
        return batch_bytes

    return body_limit


def too_large_message(limit: int, what: str = "request body") -> str:
    return f"{what} too large: the limit of this route is {limit} bytes ({limit / 1024**2:.3g} MB)"


#: Routes whose client (the Sensor Logger app) shows its user only the text body of a 499 answer.
USER_VISIBLE_PATHS = frozenset({"/api/v1/ingest/sensor-logger"})
#: The status those clients display.
USER_VISIBLE_STATUS = 499


def user_visible(path: str) -> bool:
    """True for a route whose errors are answered 499 with a text body (:data:`USER_VISIBLE_PATHS`)."""
    return path.rstrip("/") in USER_VISIBLE_PATHS


def too_large_text(limit: int) -> str:
    """The 499 text of an oversized Sensor Logger message."""
    return (f"pdr: {too_large_message(limit, 'message')}; lower the HTTP push batch period in Sensor Logger's "
            "settings")


def too_large_response(path: str, limit: int) -> tuple[str, list[tuple[str, str]], bytes]:
    """(status line, headers, body) refusing a body over ``limit`` on ``path``: 413 with the JSON error envelope, or
    499 with a text body on a route whose app shows only that (:data:`USER_VISIBLE_PATHS`).
    """
    if user_visible(path):
        return (f"{USER_VISIBLE_STATUS} Message Too Large", [("Content-Type", "text/plain; charset=utf-8")],
                too_large_text(limit).encode())
    return "413 Request Entity Too Large", [("Content-Type", "application/json")], too_large_body(limit)


def too_large_body(limit: int) -> bytes:
    """The JSON error envelope of a 413 naming ``limit``."""
    return json.dumps({"error": {"status": 413, "code": "payload_too_large", "message": too_large_message(limit),
                                 "details": {"limit_bytes": limit}}}).encode()


class _CountingInput:
    """A ``wsgi.input`` wrapper for bodies without a declared length: 413 once more than ``limit`` bytes arrive."""

    def __init__(self, stream: IO[bytes], limit: int) -> None:
        self.stream = stream
        self.limit = limit
        self.seen = 0

    def _count(self, data: bytes) -> bytes:
        self.seen += len(data)
        if self.seen > self.limit:
            raise RequestEntityTooLarge(too_large_message(self.limit))
        return data

    def read(self, size: int = -1) -> bytes:
        return self._count(self.stream.read(size))

    def readline(self, size: int = -1) -> bytes:
        return self._count(self.stream.readline(size))

    def __iter__(self) -> Any:
        return iter(self.readline, b"")


#: The ``Content-Encoding`` values of a body the service inflates (:class:`_GzipInput`).
GZIP_ENCODINGS = frozenset({"gzip", "x-gzip"})


class _GzipInput(_CountingInput):
    """A ``wsgi.input`` inflating a gzip body as it is read: 413 once more than ``limit`` bytes are inflated (never
    more than that is inflated at once, whatever the size asked), 400 naming ``Content-Encoding`` when the body is
    not a gzip stream or ends inside one.
    """

    def __init__(self, stream: IO[bytes], limit: int) -> None:
        super().__init__(cast(IO[bytes], gzip.GzipFile(fileobj=stream, mode="rb")), limit)

    def _bounded(self, size: int | None) -> int:
        room = self.limit - self.seen + 1  # one byte past the limit tells that it was passed
        return room if size is None or size < 0 else min(size, room)

    def read(self, size: int | None = -1) -> bytes:
        return self._inflated(self.stream.read, self._bounded(size))

    def readline(self, size: int | None = -1) -> bytes:
        return self._inflated(self.stream.readline, self._bounded(size))

    def _inflated(self, read: Callable[[int], bytes], size: int) -> bytes:
        try:
            return self._count(read(size))
        except (OSError, EOFError, zlib.error) as exc:
            raise APIError(400, f"the body is not the gzip stream its 'Content-Encoding: gzip' says ({exc})",
                           details={"field": "Content-Encoding"}) from None


def _inflate(environ: dict[str, Any], length: int | None, limit: int) -> None:
    """Make a gzip-encoded request's body the inflated one (:class:`_GzipInput`), as if sent plain and unsized."""
    if environ.get("HTTP_CONTENT_ENCODING", "").strip().lower() not in GZIP_ENCODINGS or "wsgi.input" not in environ:
        return
    raw = environ["wsgi.input"]
    if length is not None:
        raw = LimitedStream(raw, length)  # read no further than the body (the connection may hold the next request)
    environ["wsgi.input"] = _GzipInput(raw, limit)
    environ["wsgi.input_terminated"] = True
    environ.pop("CONTENT_LENGTH", None)
    environ.pop("HTTP_CONTENT_ENCODING", None)


class BodyLimitMiddleware:
    """WSGI middleware applying :func:`body_limit` from the headers (and while an unsized body streams), and
    inflating a gzip body under the same limit.
    """

    def __init__(self, app: Any, body_limit: BodyLimit) -> None:
        self.app = app
        self.body_limit = body_limit

    def __call__(self, environ: dict[str, Any], start_response: Callable[..., Any]) -> Iterable[bytes]:
        limit = self.body_limit(environ.get("REQUEST_METHOD", "GET"), environ.get("PATH_INFO", ""),
                                environ.get("CONTENT_TYPE", ""))
        environ[ENVIRON_KEY] = limit
        raw = environ.get("CONTENT_LENGTH") or ""
        try:
            length = int(raw) if raw else None
        except ValueError:
            length = None
        if length is not None and length > limit:
            status, headers, body = too_large_response(environ.get("PATH_INFO", ""), limit)
            start_response(status, [*headers, ("Content-Length", str(len(body)))])
            return [body]
        if length is None and "wsgi.input" in environ and (
                environ.get("wsgi.input_terminated") or "chunked" in environ.get("HTTP_TRANSFER_ENCODING", "")):
            environ["wsgi.input"] = _CountingInput(environ["wsgi.input"], limit)
        _inflate(environ, length, limit)
        return self.app(environ, start_response)


def limited_channel(body_limit: BodyLimit) -> type:
    """A waitress channel class whose request parser refuses bodies over :func:`body_limit` from the headers."""
    from waitress.channel import HTTPChannel
    from waitress.parser import HTTPRequestParser
    from waitress.utilities import Error
    from waitress.utilities import RequestEntityTooLarge as WaitressTooLarge

    class TooLarge(Error):
        code = 413
        reason = "Request Entity Too Large"

        def __init__(self, limit: int, path: str) -> None:
            super().__init__(too_large_message(limit))
            self.limit = limit
            self.path = path

        def to_response(self, ident: str | None = None) -> tuple[str, list[tuple[str, str]], bytes]:
            return too_large_response(self.path, self.limit)

    class LimitedParser(HTTPRequestParser):
        limit: int | None = None

        def received(self, data: bytes) -> int:
            in_headers = not self.headers_finished
            consumed = int(super().received(data))
            if self.error is not None and not isinstance(self.error, WaitressTooLarge):
                return consumed  # a malformed request: waitress answers it
            if in_headers and self.headers_finished and not self.empty:
                self.limit = body_limit(self.command or "GET", self.path or "",
                                        self.headers.get("CONTENT_TYPE", ""))
                if self.content_length > self.limit or self.error is not None:
                    self._refuse(f"declared {self.content_length} bytes")
                    return len(data)  # the rest of this read is the refused body
            elif self.limit is not None and (self.body_bytes_received > self.limit or self.error is not None):
                self._refuse(f"{self.body_bytes_received} bytes streamed")
                return len(data)
            return consumed

        def _refuse(self, why: str) -> None:
            assert self.limit is not None
            log.info("%s %s: 413 before reading the body (%s, limit %d bytes)", self.command, self.path, why,
                     self.limit)
            self.error = TooLarge(self.limit, self.path or "")
            self.completed = True
            self.body_rcv = None  # drop whatever was buffered

    class LimitedChannel(HTTPChannel):
        """After a refusal the connection only sends the 413 and closes: later bytes of the body are dropped."""

        parser_class = LimitedParser
        discarding = False

        def received(self, data: bytes) -> bool:
            if self.discarding:
                return True
            result = bool(super().received(data))
            if any(isinstance(r.error, TooLarge) for r in self.requests):
                self.discarding = True
            return result

    return LimitedChannel
