"""Sensor Logger HTTP push: ``POST /api/v1/ingest/sensor-logger``.

The app shows the body of a 499 answer to its user, so every error the user must see (bad token, bad
data) is answered 499 with a short text; everything else 200. Sessions are created from the message's
``sessionId``/``deviceId``; a re-sent ``messageId`` is ignored; messages may arrive out of order (they
are processed in time order). The token may be passed as ``?token=`` because the app cannot set headers.
"""

from __future__ import annotations

import json
from dataclasses import replace

from flask import Blueprint, Response, jsonify, request

from pdr.errors import InputError
from server import plausibility
from server.api import current_user, services
from server.api.sessions import time_span_ns
from server.errors import APIError
from server.ingest import store_batch
from server.processing import SENSOR_LOGGER_JSON
from server.schemas import SENSOR_LOGGER_MESSAGE, validate

bp = Blueprint("ingest", __name__, url_prefix="/api/v1/ingest")

#: Status the Sensor Logger app displays to its user.
USER_VISIBLE_ERROR = 499


def _user_error(message: str) -> Response:
    return Response(message[:300], status=USER_VISIBLE_ERROR, mimetype="text/plain")


@bp.post("/sensor-logger")
def sensor_logger() -> Response:
    try:
        return _ingest()
    except APIError as exc:
        if exc.status == 413:
            raise
        return _user_error(f"pdr: {exc.message}")
    except InputError as exc:
        return _user_error(f"pdr: {exc}")


def _ingest() -> Response:
    from pdr.io.sensor_logger import parse_push_message

    user = current_user(allow_query_token=True, scope="ingest")
    svc = services()
    raw = request.get_data()
    try:
        message = json.loads(raw)
    except (ValueError, UnicodeDecodeError, RecursionError):
        raise APIError(400, "message is not valid JSON") from None
    validate(message, SENSOR_LOGGER_MESSAGE, "Sensor Logger message")
    message_id = str(message["messageId"])
    if not message["payload"]:
        return jsonify({"status": "ok", "stored": False, "reason": "empty payload"})
    recording = parse_push_message(message, source=f"message {message_id}")
    plausibility.check_units(recording)
    sid, _ = svc.store.create_session(user.id, source="sensor_logger", client_session_id=str(message["sessionId"]),
                                      name=f"Sensor Logger {message['sessionId']}")
    t_first, t_last = time_span_ns(recording)
    plausibility.check_time(svc.store.engine, sid, "phone", SENSOR_LOGGER_JSON, t_first, t_last)
    accepted = store_batch(svc, sid, client_batch_id=f"msg-{message_id}", payload_format=SENSOR_LOGGER_JSON,
                           payload=raw, t_first_ns=t_first, t_last_ns=t_last,
                           device=replace(recording.device, role="phone", device_id=str(message["deviceId"])),
                           content=message)
    return jsonify({"status": "ok", "session": sid, "duplicate": not accepted.created})
