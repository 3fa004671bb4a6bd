"""API blueprints under ``/api/v1`` and the helpers views share (services, authentication, JSON bodies)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from flask import current_app, request
from werkzeug.datastructures import FileStorage
from werkzeug.exceptions import BadRequest

from pdr.errors import InputError, UnknownFormatError
from pdr.io.registry import FORCE_FORMAT_HINT
from pdr.recording import Recording
from server.access_log import USER_KEY
from server.auth import PREFIX_CHARS, FailureLimiter, User, lookup, token_from_request
from server.config import Settings
from server.errors import APIError
from server.jobs import InProcessWorker, NoWorker
from server.processing import SessionProcessing
from server.report_jobs import ReportRunner
from server.schemas import check_representable
from server.store import Store


@dataclass
class Services:
    """Everything a view needs, attached to the app as ``app.extensions['pdr']``."""

    settings: Settings
    store: Store
    processing: SessionProcessing
    worker: InProcessWorker | NoWorker
    auth_failures: FailureLimiter
    reports: ReportRunner


def services() -> Services:
    svc: Services = current_app.extensions["pdr"]
    return svc


def current_user(allow_query_token: bool = False, scope: str | None = None) -> User:
    """The authenticated user, whose token must allow ``scope`` (default: ``read`` for GET/HEAD, else ``full``).

    401 without a valid token; 403 when the token's scope does not allow the request; 429 after too many failed
    authentications from this client address or with this token prefix. A valid token is looked up first and
    never refused by the failure limit (clients behind one proxy address are not locked out by another's errors).
    """
    svc = services()
    token = token_from_request(request, allow_query_token)
    if not token and not allow_query_token and "token" in request.args:
        raise APIError(403, "a token in the query string is accepted on ingest endpoints only; "
                            "send 'Authorization: Bearer <token>'")
    if not token:
        where = " or '?token=<token>' in the URL" if allow_query_token else ""  # for an app that sets no header
        raise APIError(401, f"authentication required: send 'Authorization: Bearer <token>'{where}")
    with svc.store.engine.connect() as conn:
        user = lookup(conn, token)
    if user is None:
        keys = (f"addr:{request.remote_addr or '?'}", f"prefix:{token[:PREFIX_CHARS]}")
        for key in keys:
            svc.auth_failures.check(key)
        for key in keys:
            svc.auth_failures.fail(key)
        raise APIError(401, "invalid, expired or revoked API token")
    need = scope or ("read" if request.method in ("GET", "HEAD") else "full")
    if not user.allows(need):
        raise APIError(403, f"this token's scope '{user.scope}' does not allow this request (it needs '{need}'); "
                            "ingest tokens may only push data, read tokens may only read",
                       details={"scope": user.scope, "needs": need})
    request.environ[USER_KEY] = user.id
    return user


def only_query_parameters(*names: str) -> None:
    """400 naming the first query parameter of the request that is not one of ``names`` (those the route takes),
    rather than ignoring it: a misspelt ``?sinse=``, or the groups' ``?since_s=`` on a session's track, would answer
    every row.
    """
    name = next((n for n in request.args if n not in names), None)
    if name is not None:
        takes = f"this route takes {', '.join(names)}" if names else "this list takes none (it answers every item)"
        raise APIError(400, f"unknown query parameter '{name[:40]}': {takes}", details={"field": name[:40]})


def refuse_nul_in_url() -> None:
    """400 naming the path segment or query parameter of the request that holds a NUL character (``%00``), before the
    view runs (the app's ``before_request``): no id or name holds one, and PostgreSQL refuses it in the text an id is
    compared with (a 500 before).
    """
    for name, value in [*(request.view_args or {}).items(), *request.args.items(multi=True)]:
        if "\x00" in name or (isinstance(value, str) and "\x00" in value):
            field = name.replace("\x00", "?")[:40]
            raise APIError(400, f"the URL's '{field}' holds a NUL character (%00), which no id or name holds",
                           details={"field": field})


def no_query_parameters() -> None:
    """400 naming the first query parameter of a request to a list that takes none (every item is listed: no
    paging or filter), rather than ignoring it (``?limit=5`` would answer them all).
    """
    only_query_parameters()


def plain_body() -> None:
    """415 naming the header when the request's body is compressed other than by gzip (``Content-Encoding: br``,
    say): such a body would otherwise be answered as not valid JSON or not a log. A gzip body reaches the views
    inflated, without the header (:class:`server.limits.BodyLimitMiddleware`).
    """
    encoding = request.content_encoding
    if encoding and encoding.strip().lower() != "identity":
        raise APIError(415, f"Content-Encoding '{encoding[:40]}' is not supported: send the body uncompressed or "
                            "gzip-compressed (Content-Encoding: gzip)",
                       details={"field": "Content-Encoding"})


def json_body(what: str) -> dict[str, Any]:
    """The request's JSON body, a JSON object (``what`` names it in errors): 415 if it is not declared JSON or is
    compressed other than by gzip, 400 if it does not parse, 422 naming the field of a value nothing can hold
    (:func:`server.schemas.check_representable`), 422 naming what was expected if it is not an object (``null``, an
    array, a number or a string).
    """
    plain_body()
    if not request.is_json:
        raise APIError(415, "expected a JSON body with 'Content-Type: application/json'")
    try:
        body = request.get_json()
    except BadRequest:  # the parser's failure (Flask's own message names none of the route's body)
        raise APIError(400, "request body is not valid JSON") from None
    except RecursionError:  # the JSON parser recurses per nesting level
        raise APIError(400, "request body is not valid JSON (nested too deeply)") from None
    check_representable(body, request.get_data(), what)
    return json_object(body, what)


#: The JSON names of the types a body can have that is not an object.
_JSON_TYPES = ((type(None), "null"), (bool, "a boolean"), (list, "an array"), (str, "a string"),
               ((int, float), "a number"))


def json_object(body: Any, what: str) -> dict[str, Any]:
    """``body`` when it is a JSON object; else a 422 saying the ``what`` is a JSON object and naming what came (the
    body's type in JSON's words: ``null``, not Python's ``None``).
    """
    if isinstance(body, dict):
        return body
    got = next((name for kind, name in _JSON_TYPES if isinstance(body, kind)), type(body).__name__)
    raise APIError(422, f"invalid {what}: the request body must be a JSON object {{...}}, got {got}",
                   details={"path": "", "validator": "type", "expected": "object"})


@dataclass(frozen=True)
class Upload:
    """A log file from a multipart request: its bytes, safe file name, detected (or given) format, and the
    recording read from it.
    """

    payload: bytes
    filename: str
    format: str
    recording: Recording

    @property
    def descriptor(self) -> str:
        """``FORMAT/FILENAME``, as :func:`server.processing.read_uploaded_file` takes it."""
        return f"{self.format}/{self.filename}"


def multipart_file(what: str) -> FileStorage:
    """The request's multipart ``file`` field; 400 naming it when there is none, which is also what Werkzeug leaves of
    a form with a part whose headers (a file name) are not UTF-8: it drops the whole form without a word.
    """
    upload = request.files.get("file")
    if upload is None:
        raise APIError(400, f"multipart upload needs a 'file' field with the {what} (a form whose file name is not "
                            "UTF-8 cannot be read)", details={"field": "file"})
    return upload


def uploaded_log(what: str = "log") -> Upload:
    """The multipart ``file`` field (400 if missing, 422 if empty), its format (field ``format`` or detected) and
    its recording, detected and read by one sandboxed reader (:mod:`server.sandbox`): the only read of the upload.
    """
    from server.sandbox import read_isolated, safe_filename

    plain_body()
    upload = multipart_file(what)
    payload = upload.read()
    upload.close()
    if not payload:
        raise APIError(422, "uploaded file is empty", details={"field": "file"})
    filename = safe_filename(upload.filename)
    try:
        fmt, recording = read_isolated(payload, filename, request.form.get("format") or None)
    except InputError as exc:
        if exc.code != UnknownFormatError.code or not exc.message.endswith(FORCE_FORMAT_HINT):
            raise
        # The reader's hint is the command line's (--format); this API forces a format with a form field.
        raise UnknownFormatError(exc.message.removesuffix(FORCE_FORMAT_HINT) + "send the multipart field 'format' "
                                 "to force one", source=exc.source, field="file") from None
    _check_device_text(recording, filename)
    return Upload(payload, filename, fmt, recording)


#: Most characters of a device's model and id (``devices.model``, ``devices.device_id``: VARCHAR(200), which PostgreSQL
#: enforces), as a native batch's ``device`` may have.
MAX_DEVICE_TEXT = 200


def _check_device_text(recording: Recording, filename: str) -> None:
    """422 naming the file and the device's field when the device model or id its log names (a header a reader took
    as it was) has more than :data:`MAX_DEVICE_TEXT` characters or a NUL character: the database cannot store it.
    """
    for field, text in (("model", recording.device.model), ("device_id", recording.device.device_id)):
        why = ("holds a NUL character" if "\x00" in text
               else f"is longer than {MAX_DEVICE_TEXT} characters" if len(text) > MAX_DEVICE_TEXT else None)
        if why is not None:
            raise APIError(422, f"'{filename}': the device {field} the log names {why}; nothing stored",
                           details={"field": "file", "device": field})
