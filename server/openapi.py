"""The OpenAPI 3.1 document of the API, served at ``/api/v1/openapi.json``.

Request body schemas are the ones the views validate with (:mod:`server.schemas`), so the document
cannot drift from what the server accepts.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import pdr
from pdr.foot.summaries import SCHEMA as FOOT_STEPS
from pdr.recording import DEVICE_ROLES, PLACEMENTS
from server import schemas
from server.api import groups, results

ERROR = {
    "type": "object", "required": ["error"],
    "properties": {"error": {"type": "object", "required": ["status", "code", "message", "details"],
                             "properties": {"status": {"type": "integer"}, "code": {"type": "string"},
                                            "message": {"type": "string"}, "details": {"type": "object"}}}},
}
SESSION_ID = {"name": "session_id", "in": "path", "required": True, "schema": {"type": "string"}}
NAME = {"name": "name", "in": "path", "required": True, "schema": {"type": "string"}}
REPORT_ID = {"name": "report_id", "in": "path", "required": True, "schema": {"type": "string"}}
AGENT = {"name": "agent", "in": "path", "required": True, "schema": {"type": "string"}}
GROUP_ID = {"name": "group_id", "in": "path", "required": True, "schema": {"type": "string"}}
AGENT_QUERY = {"name": "agent", "in": "query", "required": False, "schema": {"type": "string"},
               "description": "only these agents (repeatable)"}
SINCE_S_QUERY = {"name": "since_s", "in": "query", "required": False, "schema": {"type": "number"},
                 "description": "only rows after this time (s, the group's clock)"}
SITE_ID = {"name": "site_id", "in": "path", "required": True, "schema": {"type": "string"}}
#: A site description (``pdr track --site``, ``pdr site from-ms``): floor plans per floor, altitudes, landmarks.
SITE = {"type": "object", "required": ["floors"],
        "description": "site description with floor plans (pdr.site.plan): floors [{floor, altitude_m, frame, "
                       "walkable: GeoJSON Polygon/MultiPolygon/Feature(Collection), metres in the site frame or "
                       "lon/lat with the site's origin}], floor_height_m, origin, frame_bearing_deg, landmarks",
        "properties": {"name": {"type": "string"}, "floor_height_m": {"type": "number"},
                       "floors": {"type": "array", "items": {"type": "object"}},
                       "landmarks": {"type": "array", "items": {"type": "object"}}}}
SINCE = {"name": "since", "in": "query", "required": False, "schema": {"type": "number"},
         "description": "only rows with t_s greater than this (incremental polling)"}
TOKEN_QUERY = {"name": "token", "in": "query", "required": False, "schema": {"type": "string"},
               "description": "API token for clients that cannot set headers (ingest endpoints only; "
                              "query strings can end up in logs)"}
#: The push URL's platform and the app's "Standardise Units & Frames" setting (server.api.ingest).
PLATFORM_QUERY = [
    {"name": "platform", "in": "query", "required": False, "schema": {"enum": ["ios", "android"]},
     "description": "the phone's platform (the app's messages do not say); inferred from the data when absent"},
    {"name": "standardised", "in": "query", "required": False, "schema": {"enum": ["0", "1", "true", "false"]},
     "description": "the app's 'Standardise Units & Frames' setting (raw iOS data is read with Core Motion's signs)"},
]
PLACEMENT_QUERY = {"name": "placement", "in": "query", "required": False, "schema": {"enum": list(PLACEMENTS)},
                   "description": "how the phone is carried (the app does not say); without it the phone pipeline "
                                  "detects the carriage online"}


def _errors(*codes: int) -> dict[str, Any]:
    ref = {"$ref": "#/components/schemas/Error"}
    return {str(c): {"description": "error", "content": {"application/json": {"schema": ref}}} for c in codes}


def _json_body(schema: dict[str, Any] | str) -> dict[str, Any]:
    s = {"$ref": f"#/components/schemas/{schema}"} if isinstance(schema, str) else schema
    return {"required": True, "content": {"application/json": {"schema": s}}}


def _ok(description: str, media: str = "application/json") -> dict[str, Any]:
    return {"description": description, "content": {media: {"schema": {"type": "object"} if "json" in media
                                                              else {"type": "string"}}}}


def _op(summary: str, responses: dict[str, Any], **extra: Any) -> dict[str, Any]:
    return {"summary": summary, "responses": responses, **extra}


DEVICE = {"name": "device", "in": "query", "schema": {"enum": list(results.DEVICES)},
          "description": "only this device role, or 'primary': the session's primary track (two live feet: fused, "
                         "one: that foot, else the phone)"}
HEADING = {"name": "heading", "in": "query", "schema": {"enum": ["causal", "smoothed"]},
           "description": "smoothed: phone headings (hand-held, torso, trouser pocket) smoothed offline over the "
                          "session so far (pdr track's default; the answer lists the smoothed devices in "
                          "smoothed_devices and the smoother's notes in heading_notes); causal (default): the "
                          "track as streamed"}


AFTER = {"name": "after", "in": "query", "required": False,
         "schema": {"type": "integer", "minimum": 0, "maximum": results.MAX_SEQ},
         "description": "only entries stored after the one with this seq (incremental polling that also gets "
                        "entries stored with a time in the past: stops, rides, back-dated stairs, the steps of a "
                        "shoe's file uploaded later); the answer's next_after is the next value"}


def _results_path(what: str) -> dict[str, Any]:
    return {"get": _op(f"{what} of a session", {"200": _ok(what)} | _errors(400, 401, 404),
                       parameters=[SESSION_ID, SINCE, AFTER])}


#: Operations an ``ingest`` token may call (server.auth.SCOPES); every other write needs ``full``, reads ``read``.
INGEST_OPERATIONS = {("/api/v1/sessions", "post"), ("/api/v1/sessions/{session_id}/batches", "post"),
                     ("/api/v1/sessions/{session_id}/devices/{role}/upload", "post"),
                     ("/api/v1/sessions/{session_id}/steps", "post"), ("/api/v1/groups/{group_id}/uploads", "post"),
                     ("/api/v1/ingest/sensor-logger", "post")}
#: Writes that store nothing, allowed to ``read`` tokens.
READ_WRITES = {("/api/v1/classify", "post")}


def _scoped(paths: dict[str, Any]) -> dict[str, Any]:
    """Mark every authenticated operation with the token scope it needs (``x-token-scope``) and its 403."""
    for path, ops in paths.items():
        for method, op in ops.items():
            if op.get("security") == []:
                continue
            scope = ("ingest" if (path, method) in INGEST_OPERATIONS else
                     "read" if method in ("get", "head") or (path, method) in READ_WRITES else "full")
            op["x-token-scope"] = scope
            op["description"] = (f"Token scope: '{scope}' (or 'full')." if scope != "full"
                                 else "Token scope: 'full'.")
            op["responses"] |= _errors(403)
    return paths


@cache
def openapi_document() -> dict[str, Any]:
    batch_schema = json.loads((Path(pdr.__file__).parent / "io" / "schemas" / "batch.schema.json").read_text())
    batch_schema.pop("$schema", None)
    batch_schema.pop("$id", None)
    common = _errors(401, 404, 413, 415, 422, 429)
    return {
        "openapi": "3.1.0",
        "info": {"title": "pdr-backend API", "version": pdr.__version__,
                 "description": "Pedestrian navigation backend: ingest phone and shoe IMU data, get tracks, "
                                "motion context and sensor reports. Authenticate with 'Authorization: Bearer'. "
                                "Tokens have a scope (ingest, read, full; see each operation's x-token-scope). "
                                "Bodies over a route's limit are refused 413 from their headers: file uploads "
                                "PDR_MAX_UPLOAD_MB, every other write PDR_MAX_BATCH_MB. A body may be sent "
                                "gzip-compressed (Content-Encoding: gzip): the limit holds for it as sent and as "
                                "inflated (413), a corrupt gzip stream is a 400 naming the header, any other "
                                "Content-Encoding a 415. Every answer carrying times "
                                "states their clock in 'clock': t0_ns, where the session's recording starts, and "
                                "what t_s means (seconds on the log's own clock)."},
        "components": {
            "securitySchemes": {"bearer": {"type": "http", "scheme": "bearer"},
                                "queryToken": {"type": "apiKey", "in": "query", "name": "token"}},
            # Token scopes: each operation's x-token-scope names the one it needs ('full' tokens may do all).
            "x-token-scopes": {"ingest": "push data only (Sensor Logger, native batches, file uploads to a "
                                         "session or a paired device, foot steps, group uploads)",
                               "read": "read only", "full": "everything"},
            "schemas": {"Error": ERROR, "CreateSession": schemas.CREATE_SESSION, "Processing": schemas.PROCESSING,
                        "Device": schemas.PAIR_DEVICE,
                        "NativeBatch": batch_schema, "SensorLoggerMessage": schemas.SENSOR_LOGGER_MESSAGE,
                        "ClassifyWindow": schemas.CLASSIFY_WINDOW, "CreateGroup": groups.CREATE_GROUP,
                        "JoinGroup": groups.JOIN_GROUP, "GroupUpload": groups.UPLOAD,
                        "FootSteps": FOOT_STEPS, "Site": SITE, "LocationFix": schemas.LOCATION_FIX},
        },
        "security": [{"bearer": []}],
        "paths": _scoped({
            "/api/v1/health": {"get": _op("service health", {"200": _ok(
                "ok; status \"warming up\" while the compiled kernels load (kernels.state)")}, security=[])},
            "/api/v1/openapi.json": {"get": _op("this document", {"200": _ok("OpenAPI document")}, security=[])},
            "/api/v1/sessions": {
                "get": _op("list the user's sessions", {"200": _ok("sessions")} | _errors(401)),
                "post": _op("create a session (JSON) or upload a whole log file (multipart 'file'); a create under "
                            "an existing session_id is 200 when it states nothing new, 409 naming the field that "
                            "differs (name, placement, origin, processing), as another file under it is",
                            {"201": _ok("created"), "200": _ok("already existed")} | common | _errors(400, 409),
                            requestBody={"required": True, "content": {
                                "application/json": {"schema": {"$ref": "#/components/schemas/CreateSession"}},
                                "multipart/form-data": {"schema": {"type": "object", "required": ["file"],
                                                                   "properties": {
                                                                       "file": {"type": "string", "format": "binary"},
                                                                       "format": {"type": "string"},
                                                                       "placement": {"type": "string"},
                                                                       "processing": {
                                                                           "type": "string",
                                                                           "description": "JSON of the "
                                                                           "CreateSession 'processing' object"},
                                                                       "session_id": {"type": "string"}}}}}}),
            },
            "/api/v1/sessions/{session_id}": {
                "get": _op("session detail with processing status, batches, warnings, paired and live feet and the "
                           "primary track; {session_id} may also be the client's session_id (a key per user)",
                           {"200": _ok("session")} | _errors(401, 404), parameters=[SESSION_ID]),
                "delete": _op("delete the session: raw batches, results, processing state, queued work; at once, "
                              "also while it is being processed (that pass writes nothing more)",
                              {"204": {"description": "deleted"}} | _errors(401, 404), parameters=[SESSION_ID])},
            "/api/v1/sessions/{session_id}/devices": {
                "post": _op("pair a device (shoe IMUs: left_foot / right_foot); a session with a phone takes a "
                            "foot's raw batches only once the foot is paired (409 naming device.role), a session "
                            "without one pairs each foot by its batches", {"201": _ok("paired")} | common,
                            parameters=[SESSION_ID], requestBody=_json_body("Device"))},
            "/api/v1/sessions/{session_id}/devices/{role}/upload": {
                "post": _op("add a log file of a paired device (any shoe IMU format: PyShoe .mat, SensorConnect "
                            "CSV, x-io CSV, native JSON); the pairing decides the device, not the file",
                            {"201": _ok("stored"), "200": _ok("the same file again: ignored")} | common
                            | _errors(400, 409),
                            parameters=[SESSION_ID, {"name": "role", "in": "path", "required": True,
                                                     "schema": {"enum": list(DEVICE_ROLES)}}],
                            requestBody={"required": True, "content": {"multipart/form-data": {"schema": {
                                "type": "object", "required": ["file"],
                                "properties": {"file": {"type": "string", "format": "binary"},
                                               "format": {"type": "string"}}}}}})},
            "/api/v1/sessions/{session_id}/batches": {
                "post": _op("ingest a native JSON batch (idempotent by batch_id); its meta.location, when given, "
                            "must be a LocationFix (422 naming the field); a foot's batch to a session with a "
                            "phone needs the foot paired first (409 naming device.role)",
                            {"201": _ok("stored"), "200": _ok("duplicate ignored")} | common | _errors(400, 409),
                            parameters=[SESSION_ID, TOKEN_QUERY], requestBody=_json_body("NativeBatch"),
                            security=[{"bearer": []}, {"queryToken": []}])},
            "/api/v1/sessions/{session_id}/processing": {
                "put": _op("replace the processing options and rebuild all results with them: answered at once, "
                           "a pass running then writes nothing more, the next one rebuilds",
                           {"202": _ok("queued")} | common | _errors(409),
                           parameters=[SESSION_ID], requestBody=_json_body("Processing"))},
            "/api/v1/sessions/{session_id}/site": {
                "get": _op("the floor plans (metric frame, per floor) and start of the uploaded site the session is "
                           "processed with (its own copy); 404 when it names none",
                           {"200": _ok("floor plans")} | _errors(401, 404), parameters=[SESSION_ID])},
            "/api/v1/sessions/{session_id}/reprocess": {
                "post": _op("rebuild all results from the raw batches: answered at once, a pass running then writes "
                            "nothing more, the next one rebuilds; 409 when the retention policy deleted raw batches",
                            {"202": _ok("queued")} | _errors(401, 404, 409),
                            parameters=[SESSION_ID])},
            "/api/v1/sessions/{session_id}/track": {
                "get": _op("track, one row per step", {"200": {"description": "track", "content": {
                    "application/json": {"schema": {"type": "object"}}, "text/csv": {"schema": {"type": "string"}},
                    "application/geo+json": {"schema": {"type": "object"}}}}} | _errors(400, 401, 404, 409),
                    parameters=[SESSION_ID, SINCE,
                                {"name": "format", "in": "query", "schema": {"enum": ["json", "csv", "geojson"]},
                                 "description": "geojson: RFC 7946 lon/lat, for a geo-referenced session only (409 "
                                                "otherwise)"},
                                DEVICE, HEADING, AFTER])},
            "/api/v1/sessions/{session_id}/steps": _results_path("steps") | {
                "post": _op("ingest a shoe unit's step-wise dead-reckoning summaries (idempotent by batch_id)",
                            {"201": _ok("stored"), "200": _ok("duplicate ignored")} | common | _errors(400, 409),
                            parameters=[SESSION_ID, TOKEN_QUERY], requestBody=_json_body("FootSteps"),
                            security=[{"bearer": []}, {"queryToken": []}])},
            "/api/v1/sessions/{session_id}/modes": _results_path("motion modes"),
            "/api/v1/sessions/{session_id}/landmarks": _results_path("landmarks"),
            "/api/v1/sessions/{session_id}/floors": _results_path("floors"),
            "/api/v1/sessions/{session_id}/track/columns": {"get": _op(
                "track as one array per column", {"200": _ok("track columns")} | _errors(400, 401, 404),
                parameters=[SESSION_ID, SINCE, DEVICE, HEADING, AFTER])},
            "/api/v1/sessions/{session_id}/truth": {
                "get": _op("ground truth positions of uploaded logs", {"200": _ok("truth")} | _errors(401, 404),
                           parameters=[SESSION_ID])},
            "/api/v1/sites": {
                "get": _op("the user's sites (summaries: floors, altitudes, polygons, bounds)",
                           {"200": _ok("sites")} | _errors(401)),
                "post": _op("upload a site (JSON body, or multipart 'file' with an optional 'name'); checked as "
                            "`pdr site check` checks it: 422 naming the floor, polygon, ring and field",
                            {"201": _ok("created")} | common | _errors(400),
                            requestBody={"required": True, "content": {
                                "application/json": {"schema": {"$ref": "#/components/schemas/Site"}},
                                "multipart/form-data": {"schema": {"type": "object", "required": ["file"],
                                                                   "properties": {
                                                                       "file": {"type": "string", "format": "binary"},
                                                                       "name": {"type": "string"}}}}}})},
            "/api/v1/sites/{site_id}": {
                "get": _op("the site: summary, its floor plans in the metric frame ('plan') and the document as "
                           "uploaded ('site')", {"200": _ok("site")} | _errors(401, 404), parameters=[SITE_ID]),
                "delete": _op("delete the site (sessions that name it keep their copy)",
                              {"204": {"description": "deleted"}} | _errors(401, 404), parameters=[SITE_ID])},
            "/api/v1/models": {"get": _op("classifier models", {"200": _ok("models")} | _errors(401))},
            "/api/v1/models/{name}": {
                "get": _op("model card", {"200": _ok("card")} | _errors(401, 404), parameters=[NAME])},
            "/api/v1/models/{name}/model.json": {
                "get": _op("the raw model artifact (download)", {"200": _ok("model.json")} | _errors(401, 404),
                           parameters=[NAME])},
            "/api/v1/classify": {
                "post": _op("classify the windows of a native batch", {"200": _ok("one decision per window")}
                            | common, requestBody=_json_body("ClassifyWindow"))},
            "/api/v1/reports": {"get": _op("the user's reports", {"200": _ok("reports")} | _errors(401))},
            "/api/v1/reports/allan": {
                "post": _op("Allan-variance report of a static log (multipart 'file'): the log is read in the request "
                            "(422 if it cannot be), then characterised by a recoverable job (the embedded worker, "
                            "or pdr worker with PDR_WORKER=redis)",
                            {"202": _ok("queued")} | common | _errors(400),
                            requestBody={"required": True, "content": {"multipart/form-data": {"schema": {
                                "type": "object", "required": ["file"],
                                "properties": {"file": {"type": "string", "format": "binary"},
                                               "format": {"type": "string"}}}}}})},
            "/api/v1/reports/{report_id}": {
                "get": _op("report status and every number", {"200": _ok("report")} | _errors(401, 404),
                           parameters=[REPORT_ID]),
                "delete": _op("delete the report and its files", {"204": {"description": "deleted"}}
                              | _errors(401, 404), parameters=[REPORT_ID])},
            "/api/v1/reports/{report_id}/report.html": {
                "get": _op("self-contained HTML report", {"200": _ok("page", "text/html")} | _errors(401, 404),
                           parameters=[REPORT_ID])},
            "/api/v1/reports/{report_id}/files/{name}": {
                "get": _op("a report file (PNG plot, imu.yaml, JSON)", {"200": _ok("file", "application/octet-stream")}
                           | _errors(401, 404), parameters=[REPORT_ID, NAME])},
            "/api/v1/groups": {
                "get": _op("the user's cooperative groups", {"200": _ok("groups")} | _errors(401)),
                "post": _op("create a group", {"201": _ok("created")} | common, requestBody=_json_body("CreateGroup"))},
            "/api/v1/groups/{group_id}": {
                "get": _op("group detail", {"200": _ok("group")} | _errors(401, 404), parameters=[GROUP_ID]),
                "delete": _op("delete the group: members, uploads, fused state and tracks (its agents' sessions "
                              "stay)", {"204": {"description": "deleted"}} | _errors(401, 404),
                              parameters=[GROUP_ID])},
            "/api/v1/groups/{group_id}/agents": {
                "post": _op("join an agent", {"201": _ok("joined")} | common, parameters=[GROUP_ID],
                            requestBody=_json_body("JoinGroup"))},
            "/api/v1/groups/{group_id}/uploads": {
                "post": _op("step summaries and ranges of an agent (idempotent: 200 for a batch_id already taken); "
                            "422 code stale_range when ranges are older than the fusion horizon (details.events, "
                            "details.reasons), 409 for steps of an agent fed from a session",
                            {"201": _ok("applied: accepted, applied, stale_ranges, pending, dropped, correction"),
                             "200": _ok("stored")} | common | _errors(409), parameters=[GROUP_ID],
                            requestBody=_json_body("GroupUpload"))},
            "/api/v1/groups/{group_id}/flush": {
                "post": _op("apply everything buffered", {"200": _ok("applied")} | _errors(401, 404),
                            parameters=[GROUP_ID])},
            "/api/v1/groups/{group_id}/tracks": {
                "get": _op("fused tracks of every agent: {agents: {AGENT: {left_foot|right_foot: [[t_s, east_m, "
                           "north_m, up_m, heading_deg]]}}}, t_s on the group's clock", {"200": _ok("tracks")}
                           | _errors(401, 404, 422), parameters=[GROUP_ID, AGENT_QUERY, SINCE_S_QUERY])},
            "/api/v1/groups/{group_id}/agents/{agent}/correction": {
                "get": _op("correction for an agent's local estimate: feet (left_foot/right_foot), steps, t_s, mean "
                           "(x, y, z m ENU and yaw rad per foot), cov, heading_deg", {"200": _ok("correction")}
                           | _errors(401, 404), parameters=[GROUP_ID, AGENT])},
            "/api/v1/ingest/sensor-logger": {
                "post": _op("Sensor Logger HTTP push; errors the app shows its user are answered 499 (text)",
                            {"200": _ok("accepted"),
                             "499": _ok("error shown to the user, an oversized message included", "text/plain")},
                            parameters=[TOKEN_QUERY, PLACEMENT_QUERY, *PLATFORM_QUERY],
                            requestBody=_json_body("SensorLoggerMessage"),
                            security=[{"bearer": []}, {"queryToken": []}])},
        }),
    }
