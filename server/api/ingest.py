"""Sensor Logger HTTP push: ``POST /api/v1/ingest/sensor-logger``.

The app shows the body of a 499 answer to its user, so every error the user must see (bad token, bad
data) is answered 499 with a short text; everything else 200. Sessions are created from the message's
``sessionId``/``deviceId``; a re-sent ``messageId`` is ignored; messages may arrive out of order (they
are processed in time order). The token may be passed as ``?token=`` because the app cannot set headers.

The app's messages do not say how the phone is carried, so the push URL may: ``?placement=hand`` (one of
:data:`pdr.recording.PLACEMENTS`) is the session's and the phone's placement, which the phone pipeline takes as
``pdr track`` takes a log's placement; without it the pipeline detects the carriage online
(:mod:`pdr.phone.placement_detect`), and its first steps then differ from a log whose reader knew the placement.
Nor do they say the platform: ``?platform=ios|android&standardised=0|1`` (the app's "Standardise Units & Frames"
setting) say how to read raw iOS data, which is otherwise inferred from the data (:mod:`pdr.io.sensor_logger`).
``location`` readings geo-reference the session (its origin is the first fix). ``time`` may be a string of digits.
A message over the route's body limit is answered 499 with a text body too (:mod:`server.limits`).
"""

from __future__ import annotations

import json
from dataclasses import replace

from flask import Blueprint, Response, jsonify, request

from pdr.errors import InputError
from pdr.recording import PLACEMENTS
from server import plausibility
from server.api import current_user, json_object, plain_body, services
from server.api.sessions import geo_reference, time_span_ns
from server.errors import APIError
from server.ingest import store_batch
from server.limits import USER_VISIBLE_STATUS
from server.processing import SENSOR_LOGGER_JSON
from server.schemas import SENSOR_LOGGER_MESSAGE, check_representable, validate

bp = Blueprint("ingest", __name__, url_prefix="/api/v1/ingest")

#: Status the Sensor Logger app displays to its user (one definition: :data:`server.limits.USER_VISIBLE_STATUS`).
USER_VISIBLE_ERROR = USER_VISIBLE_STATUS


def _user_error(message: str) -> Response:
    return Response(message[:300], status=USER_VISIBLE_ERROR, mimetype="text/plain")


@bp.post("/sensor-logger")
def sensor_logger() -> Response:
    try:
        return _ingest()
    except APIError as exc:
        return _user_error(f"pdr: {exc.message}")
    except InputError as exc:
        return _user_error(f"pdr: {exc}")


def _ingest() -> Response:
    from pdr.io.sensor_logger import parse_push_message

    user = current_user(allow_query_token=True, scope="ingest")
    svc = services()
    plain_body()
    raw = request.get_data()
    try:
        message = json.loads(raw)
    except (ValueError, UnicodeDecodeError, RecursionError):
        raise APIError(400, "message is not valid JSON") from None
    check_representable(message, raw, "Sensor Logger message")
    json_object(message, "Sensor Logger message")
    validate(message, SENSOR_LOGGER_MESSAGE, "Sensor Logger message")
    message_id = str(message["messageId"])
    if not message["payload"]:
        return jsonify({"status": "ok", "stored": False, "reason": "empty payload"})
    placement = _placement()
    platform, standardised = _platform()
    recording = parse_push_message(message, source=f"message {message_id}", platform=platform,
                                   standardised=standardised)
    plausibility.check_units(recording)
    t_first, t_last = time_span_ns(recording, "payload")
    sid, created = svc.store.create_session(user.id, source="sensor_logger",
                                            client_session_id=str(message["sessionId"]),
                                            name=f"Sensor Logger {message['sessionId']}"[:MAX_NAME_CHARS],
                                            placement=placement)
    known = None if created else svc.store.session_row(sid).placement
    if not created and known != placement:
        raise APIError(422, f"placement '{placement}' differs from the session's ('{known}'): use one push URL "
                            f"for the whole session",
                       details={"field": "placement"})
    plausibility.check_time(svc.store.engine, sid, "phone", SENSOR_LOGGER_JSON, t_first, t_last)
    accepted = store_batch(svc, sid, client_batch_id=f"msg-{message_id}", payload_format=SENSOR_LOGGER_JSON,
                           payload=raw, t_first_ns=t_first, t_last_ns=t_last,
                           device=replace(recording.device, role="phone", device_id=str(message["deviceId"]),
                                          placement=placement),
                           content=message, recording=recording)
    geo_reference(sid, recording)
    return jsonify({"status": "ok", "session": sid, "duplicate": not accepted.created})


#: Longest session name (``sessions.name``, a VARCHAR(200) that PostgreSQL enforces); a sessionId may have 200
#: characters, and the name adds 'Sensor Logger ' to it.
MAX_NAME_CHARS = 200

#: ``?standardised=`` spellings of the app's "Standardise Units & Frames" setting.
STANDARDISED = {"1": True, "true": True, "0": False, "false": False}


def _platform() -> tuple[str | None, bool | None]:
    """The phone's platform and standardisation setting named by the push URL (``?platform=ios|android``,
    ``?standardised=0|1``); ``None`` for what it does not name (then inferred from the data).
    """
    platform = request.args.get("platform") or None
    if platform is not None and platform not in ("ios", "android"):
        raise APIError(422, f"unknown platform '{platform[:20]}' in the push URL; expected ios or android",
                       details={"field": "platform"})
    flag = request.args.get("standardised")
    if flag is not None and flag.lower() not in STANDARDISED:
        raise APIError(422, f"standardised must be 0 or 1 in the push URL, got '{flag[:20]}'",
                       details={"field": "standardised"})
    return platform, None if flag is None else STANDARDISED[flag.lower()]


def _placement() -> str | None:
    """The phone's placement named by the push URL (``?placement=``), ``None`` when not given."""
    placement = request.args.get("placement") or None
    if placement is not None and placement not in PLACEMENTS:
        raise APIError(422, f"unknown placement '{placement}' in the push URL; expected one of {', '.join(PLACEMENTS)}",
                       details={"field": "placement"})
    return placement
