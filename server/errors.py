"""JSON error bodies for every failure: ``{"error": {"status", "code", "message", "details"}}``, never a traceback."""

from __future__ import annotations

import logging
from typing import Any

from flask import Flask, Response, jsonify, request
from werkzeug.exceptions import HTTPException

from pdr.errors import InputError
from server.api_error import CODES, APIError

__all__ = ["APIError", "error_response", "register_error_handlers"]

log = logging.getLogger(__name__)


def error_response(status: int, message: str, code: str | None = None,
                   details: dict[str, Any] | None = None) -> Response:
    body = {"error": {"status": status, "code": code or CODES.get(status, "error"), "message": message,
                      "details": details or {}}}
    resp = jsonify(body)
    resp.status_code = status
    return resp


def _too_large(app: Flask, description: str) -> tuple[str, dict[str, Any]]:
    """Message and details of a 413: the route's body limit, or the form-field limit when a field was too big."""
    from server.limits import ENVIRON_KEY, too_large_message

    limit = int(request.environ.get(ENVIRON_KEY) or app.config.get("MAX_CONTENT_LENGTH") or 0)
    if description.startswith("request body too large"):  # an unsized body passed the route's limit
        return description, {"limit_bytes": limit}
    field_limit = app.config.get("MAX_FORM_MEMORY_SIZE")
    if field_limit and (request.content_length or 0) <= limit:
        return (too_large_message(int(field_limit), "form field") + "; send large content as a file",
                {"limit_bytes": int(field_limit)})
    return too_large_message(limit), {"limit_bytes": limit}


def register_error_handlers(app: Flask) -> None:
    """Install the handlers on the app (a blueprint cannot see routing 404s)."""

    @app.errorhandler(APIError)
    def _api_error(exc: APIError) -> Response:
        return error_response(exc.status, exc.message, exc.code, exc.details)

    @app.errorhandler(InputError)
    def _input_error(exc: InputError) -> Response:
        return error_response(422, str(exc), exc.code, exc.details())

    @app.errorhandler(HTTPException)
    def _http_error(exc: HTTPException) -> Response:
        status = exc.code or 500
        message = exc.description or exc.name
        details: dict[str, Any] = {}
        if status == 413:
            from server.limits import too_large_text, user_visible

            message, details = _too_large(app, message)
            if user_visible(request.path):  # the Sensor Logger app shows only a 499's text
                return Response(too_large_text(int(details.get("limit_bytes") or 0)), status=499,
                                mimetype="text/plain")
        resp = error_response(status, message, details=details)
        if status == 405 and exc.valid_methods:  # type: ignore[attr-defined]
            resp.headers["Allow"] = ", ".join(exc.valid_methods)  # type: ignore[attr-defined]
        return resp

    @app.errorhandler(RecursionError)
    def _too_deep(exc: RecursionError) -> Response:
        return error_response(400, "input nested too deeply")

    @app.errorhandler(Exception)
    def _unexpected(exc: Exception) -> Response:
        log.exception("unhandled error")
        return error_response(500, "internal server error; the incident was logged")
