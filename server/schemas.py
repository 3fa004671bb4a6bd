"""JSON Schemas of request bodies (validated with ``jsonschema``; also published in the OpenAPI document)."""

from __future__ import annotations

import math
import re
import sys
from typing import Any

import jsonschema

from pdr.recording import DEVICE_ROLES, PLACEMENTS, PLATFORMS
from server.errors import APIError

CLIENT_ID = {"type": "string", "minLength": 1, "maxLength": 200, "pattern": r"^[A-Za-z0-9._:\-]+$"}

DEVICE = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "role": {"enum": list(DEVICE_ROLES)},
        "device_id": {"type": "string", "maxLength": 200},
        "platform": {"enum": list(PLATFORMS)},
        "model": {"type": "string", "maxLength": 200},
        "placement": {"enum": [*PLACEMENTS, None]},
    },
}

#: Processing options of a session (server.processing_options), at creation or replaced later.
PROCESSING = {
    "type": "object", "additionalProperties": False,
    "description": "processing options (server.processing_options)",
    "properties": {
        "site": {"type": "object", "description": "site description, as `pdr track --site`"},
        "site_id": {"type": "string", "maxLength": 64,
                    "description": "a site uploaded with POST /api/v1/sites: its floor altitudes and landmarks"},
        "start": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 3,
                  "description": "[E, N] or [E, N, FLOOR]: the walk's start in the site's frame (m) and its floor "
                                 "(default: the site's only floor); with site_id, the track is map-matched on the "
                                 "site's floor plans online and is in the site's frame"},
        "calibration": {"type": "object", "description": "step-length calibration `pdr calibrate` wrote"},
        "foot": {"type": "object", "additionalProperties": False, "properties": {
            "zaru": {"type": "boolean"}, "imu_samples": {"enum": ["instant", "interval"]}}},
    },
}

#: WGS-84 latitude and longitude, degrees.
LAT_DEG = {"type": "number", "minimum": -90, "maximum": 90}
LON_DEG = {"type": "number", "minimum": -180, "maximum": 180}
#: Latest ``unix_time_s`` of a location fix, s since 1970 (2**32: year 2106); a time in ms or ns lies far beyond.
MAX_UNIX_TIME_S = 2**32

#: A batch's location fix, ``meta.location`` (:data:`pdr.recording.LOCATION_META`): where (it geo-references an
#: uploaded log) and, with its date, the earth's magnetic field there (:func:`pdr.geomagnetic.field_at_fix`). Other
#: keys (a reader's ``t_ns``, ``horizontal_accuracy_m``, ``fixes``) are kept as they are.
LOCATION_FIX: dict[str, Any] = {
    "type": "object", "required": ["lat_deg", "lon_deg"],
    "description": "location fix: lat_deg, lon_deg (WGS-84, deg); optional unix_time_s (s since 1970, UTC: without "
                   "it the earth's field there is not known, and the session's origin gives it if the session has "
                   "one) and alt_m (m)",
    "properties": {"lat_deg": LAT_DEG, "lon_deg": LON_DEG,
                   "unix_time_s": {"type": ["number", "null"], "minimum": 0, "maximum": MAX_UNIX_TIME_S},
                   "alt_m": {"type": ["number", "null"]}},
}

CREATE_SESSION = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "session_id": CLIENT_ID,
        "name": {"type": "string", "maxLength": 200},
        "placement": {"enum": [*PLACEMENTS, None]},
        "device": DEVICE,
        "origin": {
            "type": "object", "additionalProperties": False, "required": ["lat_deg", "lon_deg"],
            "properties": {"lat_deg": LAT_DEG, "lon_deg": LON_DEG},
        },
        "processing": PROCESSING,
    },
}

PAIR_DEVICE = {**DEVICE, "required": ["role"]}

SENSOR_LOGGER_MESSAGE = {
    "type": "object",
    "required": ["messageId", "sessionId", "deviceId", "payload"],
    "properties": {
        # stored as the batch id "msg-<messageId>", at most 200 characters (a VARCHAR(200) in PostgreSQL)
        "messageId": {"type": ["integer", "string"], "minLength": 1, "maxLength": 196,
                      "minimum": -(2**63), "maximum": 2**63 - 1},
        "sessionId": {"type": "string", "minLength": 1, "maxLength": 200},
        "deviceId": {"type": "string", "minLength": 1, "maxLength": 200},
        "payload": {"type": "array", "items": {
            "type": "object", "required": ["name", "time", "values"],
            "properties": {"name": {"type": "string"},
                           # epoch ns as a number or, as some app versions send it, a string of digits
                           "time": {"anyOf": [{"type": ["integer", "number"]},
                                              {"type": "string", "pattern": r"^\s*-?\d+\s*$"}]},
                           "values": {"type": "object"}}}},
    },
}

CLASSIFY_WINDOW = {
    "type": "object",
    "required": ["batch"],
    "additionalProperties": False,
    "properties": {
        "model": {"type": "string", "maxLength": 100, "pattern": r"^[A-Za-z0-9._\-]+$"},
        "batch": {"type": "object", "description": "a native batch (pdr-batch/1) covering one window or more"},
    },
}


def _finite_number(checker: Any, instance: Any) -> bool:
    """JSON Schema's ``number``, less NaN and the infinities: JSON bodies may carry them (Python's parser takes
    ``NaN`` and ``Infinity``), and they pass every ``minimum`` and ``maximum``.
    """
    return bool(jsonschema.Draft202012Validator.TYPE_CHECKER.is_type(instance, "number") and math.isfinite(instance))


#: The request bodies' validator: Draft 2020-12 whose ``number`` is finite.
_VALIDATOR = jsonschema.validators.extend(
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("number", _finite_number))


def validate(body: Any, schema: dict[str, Any], what: str) -> None:
    """Raise a 422 naming the offending JSON path when ``body`` does not match ``schema`` (a ``number`` must be
    finite).

    The details give it as ``field`` (as every error body does; for a missing or unexpected property, that
    property) and as ``path`` (the object or value that failed, as before ``field`` was added).
    """
    validator = _VALIDATOR(schema)
    error = next(iter(sorted(validator.iter_errors(body), key=lambda e: list(e.absolute_path))), None)
    if error is not None:
        path = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in error.absolute_path).lstrip(".")
        field = ".".join(p for p in (path, _property(error)) if p)
        message = error.message
        if isinstance(error.instance, float) and not math.isfinite(error.instance):
            message = f"{error.instance} is not a finite number"
        raise APIError(422, f"invalid {what}: {path or '(body)'}: {message}",
                       details={"path": path, "validator": error.validator} | ({"field": field} if field else {}))


def _property(error: jsonschema.ValidationError) -> str:
    """The property a ``required`` or ``additionalProperties`` error is about (the first missing or unexpected
    one), else ``""``.
    """
    if not isinstance(error.instance, dict):
        return ""
    if error.validator == "required":
        required = error.validator_value if isinstance(error.validator_value, list) else []
        return next((str(k) for k in required if k not in error.instance), "")
    if error.validator == "additionalProperties":
        known = error.schema.get("properties", {}) if isinstance(error.schema, dict) else {}
        return next((str(k) for k in error.instance if k not in known), "")
    return ""


#: How a value that the JSON parser takes but nothing after it can hold appears in a body: an integer literal of 309
#: digits or more (beyond any float64, 1.8e308: ``float()`` and numpy raise OverflowError on it), a ``\\u`` escape
#: of a UTF-16 surrogate (alone, it is no character: text holding one cannot be encoded as UTF-8, nor stored), or the
#: ``\\u0000`` of a NUL character (PostgreSQL refuses it in text). A body with none, nearly every one, is not walked
#: (:func:`check_representable`).
_SUSPECT = re.compile(rb"\d{309}|\\u[dD][89a-fA-F]|\\u0000")
_UNSTORABLE = re.compile("[\x00\ud800-\udfff]")


def _unstorable(text: str) -> str | None:
    """Why ``text`` cannot be stored (a NUL character, a lone surrogate), or None."""
    found = _UNSTORABLE.search(text)
    if found is None:
        return None
    if found.group() == "\x00":
        return "a NUL character (\\u0000), which PostgreSQL cannot store in text"
    return "a lone UTF-16 surrogate (a \\ud800-\\udfff escape that is not half of a pair)"


def check_representable(body: Any, raw: bytes, what: str, prefix: str = "") -> None:
    r"""Raise a 422 naming the field (its JSON path, after ``prefix``) of the first value of ``body``, parsed from
    ``raw``, that nothing after the parser can hold: an integer beyond any float64 (``1`` and 400 zeros), or text with
    a lone UTF-16 surrogate (``"\ud800"``) or a NUL character (``"\u0000"``), as a value or a key. Python's parser
    takes them all; the first overflowed where it was made a float, the others failed to be stored (a NUL in
    PostgreSQL only).
    """
    if _SUSPECT.search(raw) is None:
        return
    stack: list[tuple[str, Any]] = [(prefix, body)]
    while stack:
        path, value = stack.pop()
        why = None
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) > sys.float_info.max:
            why = f"an integer of {len(str(abs(value)))} digits is beyond any number (at most 1.8e308)"
        elif isinstance(value, str) and (fault := _unstorable(value)):
            why = f"the text holds {fault}"
        elif isinstance(value, dict):
            items = [(".".join(p for p in (path, _UNSTORABLE.sub("?", k)) if p), k, v) for k, v in value.items()]
            bad = next(((field, _unstorable(k)) for field, k, _ in items if _unstorable(k)), None)
            if bad is not None:
                path, why = bad[0], f"the key holds {bad[1]}"
            stack += [(field, v) for field, _, v in reversed(items)]
        elif isinstance(value, list):
            stack += [(f"{path}[{i}]", v) for i, v in reversed(list(enumerate(value)))]
        if why is not None:
            raise APIError(422, f"invalid {what}: {path or '(body)'}: {why}", details={"field": path})
