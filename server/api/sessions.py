"""Sessions: create (empty, or from an uploaded log file), list, detail, devices, native batches, reprocess."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from typing import Any

from flask import Blueprint, Response, jsonify, request

from pdr.errors import InputError
from pdr.recording import DEVICE_ROLES, FOOT_ROLES, Recording, geo_origin
from server import plausibility
from server.api import current_user, json_body, no_query_parameters, services, uploaded_log
from server.api.sites import give_session_site, named_site
from server.errors import APIError
from server.feet import pairs_itself, primary_role, session_feet
from server.ingest import store_batch
from server.processing import FILE_PREFIX, NATIVE_JSON
from server.processing_options import META_KEY, ProcessingOptions
from server.schemas import CLIENT_ID, CREATE_SESSION, PAIR_DEVICE, PROCESSING, validate
from server.session_clock import session_clock

bp = Blueprint("sessions", __name__, url_prefix="/api/v1/sessions")


def session_json(row: Any, detail: bool = False) -> dict[str, Any]:
    """Public representation of a session row."""
    svc = services()
    rebuilding = svc.store.rebuilding(row.id)   # the results from before it are served until it ends
    per_role = svc.store.track_summary(row.id, previous=rebuilding)
    primary = primary_role(per_role)
    main = per_role.get(primary, {"steps": 0, "distance_m": 0.0})
    # The session lasts from the first to the last step of any device (a short shoe walk does not shorten it).
    first = min((t["first_t_s"] for t in per_role.values()), default=0.0)
    last = max((t["last_t_s"] for t in per_role.values()), default=0.0)
    out: dict[str, Any] = {
        "id": row.id, "session_id": row.client_session_id, "name": row.name, "source": row.source,
        "placement": row.placement, "status": row.status, "rebuilding": rebuilding,
        "created_at": row.created_at.isoformat(), "updated_at": row.updated_at.isoformat(),
        "primary_track": primary, "steps": int(main["steps"]),
        "distance_m": round(main["distance_m"], 3), "duration_s": round(last - first, 3),
        "tracks": {role: {k: round(v, 3) for k, v in summary.items()} for role, summary in per_role.items()},
        "warnings": json.loads(row.warnings or "[]"),
        "batches": svc.store.batch_summary(row.id),
        "devices": [{"role": d.role, "device_id": d.device_id, "platform": d.platform, "model": d.model,
                     "placement": d.placement} for d in svc.store.devices(row.id)],
        "feet": session_feet(svc.store, row.id).to_json(),
        "origin": ({"lat_deg": row.origin_lat_deg, "lon_deg": row.origin_lon_deg}
                   if row.origin_lat_deg is not None else None),
        "processing": json.loads(row.meta or "{}").get(META_KEY, {}),
        "clock": session_clock(svc.store, row),
    }
    if detail:
        out["batch_list"] = [{"id": b.id, "batch_id": b.client_batch_id, "device_role": b.device_role,
                              "format": b.payload_format, "size_bytes": b.size_bytes, "status": b.status,
                              "error": b.error, "received_at": b.received_at.isoformat()}
                             for b in svc.store.batch_list(row.id)]
    return out


def time_span_ns(rec: Recording, field: str) -> tuple[int, int]:
    """The first and last sample time of ``rec`` (ns, its own clock); a 422 naming ``field`` (where the request
    carries the samples) when every stream is empty: nothing is stored.
    """
    firsts = [int(s.t_ns[0]) for s in rec.streams.values() if len(s)]
    lasts = [int(s.t_ns[-1]) for s in rec.streams.values() if len(s)]
    if not firsts:
        raise APIError(422, f"{rec.source or 'the upload'}: every stream is empty (no sensor sample); nothing stored",
                       details={"field": field})
    return min(firsts), max(lasts)


@bp.post("")
def create_session() -> tuple[Response, int]:
    """Create an empty session (JSON body) or a session from an uploaded log file (multipart ``file``)."""
    user = current_user(scope="ingest")
    svc = services()
    if request.files or request.mimetype == "multipart/form-data":
        return _create_from_file(user.id)
    body = json_body("session")
    validate(body, CREATE_SESSION, "session")
    device = body.get("device") or {}
    options = ProcessingOptions.from_json(body.get("processing"))
    site = named_site(options, user.id)
    sid, created = svc.store.create_session(user.id, source="native", client_session_id=body.get("session_id"),
                                            name=body.get("name", ""), placement=body.get("placement"),
                                            meta=_meta(options))
    if not created:
        _refuse_restated(svc.store.session_row(sid), body, options)
    if created and site is not None:
        give_session_site(sid, site)
    if device:
        svc.store.upsert_device(sid, device.get("role", "phone"), device_id=device.get("device_id", ""),
                                platform=device.get("platform", "unknown"), model=device.get("model", ""),
                                placement=device.get("placement"))
    if body.get("origin"):
        svc.store.set_session(sid, origin_lat_deg=body["origin"]["lat_deg"], origin_lon_deg=body["origin"]["lon_deg"])
    return jsonify(session_json(svc.store.session_row(sid, user.id))), 201 if created else 200


def _refuse_restated(row: Any, body: dict[str, Any], options: ProcessingOptions) -> None:
    """409 naming the first field of a create under an existing ``session_id`` that differs from the session (its
    ``name``, ``placement``, ``origin`` or ``processing``): re-sending a create is a no-op only when it states nothing
    new (as a re-sent batch is a no-op, different content under its ``batch_id`` a 409); a new ``name`` was ignored,
    a new ``origin`` moved the session's track.
    """
    stored = {"name": row.name, "placement": row.placement,
              "origin": None if row.origin_lat_deg is None else {"lat_deg": row.origin_lat_deg,
                                                                "lon_deg": row.origin_lon_deg},
              "processing": json.loads(row.meta or "{}").get(META_KEY, {})}
    given = {"name": body.get("name") or row.client_session_id, "placement": body.get("placement"),
             "origin": body.get("origin"), "processing": options.to_json()}
    field = next((f for f in stored if f in body and given[f] != stored[f]), None)
    if field is None:
        return
    how = (f"change it with PUT /api/v1/sessions/{row.id}/processing" if field == "processing"
           else "choose another session_id for another session")
    raise APIError(409, f"session_id '{row.client_session_id}' already names session {row.id}, whose {field} is "
                        f"{json.dumps(stored[field])[:200]}, not {json.dumps(given[field])[:200]}: a create under an "
                        f"existing session_id is answered 200 only when it states nothing new; {how}",
                   details={"field": field, "session": row.id})


def _meta(options: ProcessingOptions) -> dict[str, Any] | None:
    """Session ``meta`` holding the processing options (``None`` when there are none)."""
    d = options.to_json()
    return {META_KEY: d} if d else None


def _create_from_file(user_id: int) -> tuple[Response, int]:
    svc = services()
    key = request.form.get("session_id") or None   # the session's key, as a JSON create's (CREATE_SESSION)
    validate({"session_id": key} if key else {}, {"properties": {"session_id": CLIENT_ID}}, "upload")
    upload = uploaded_log()  # validated before accepting
    payload, filename, descriptor, recording = upload.payload, upload.filename, upload.descriptor, upload.recording
    t_first, t_last = time_span_ns(recording, "file")
    options = ProcessingOptions.from_text(request.form.get("processing"))
    site = named_site(options, user_id)
    placement = request.form.get("placement") or recording.device.placement
    plausibility.check_device(replace(recording.device, placement=placement))
    plausibility.check_units(recording)
    plausibility.check_location(recording)
    digest = hashlib.sha256(payload).hexdigest()
    sid, created = svc.store.create_session(user_id, source="upload",
                                            client_session_id=key or f"file-{digest[:24]}",
                                            name=filename, placement=placement, meta=_meta(options))
    if created and site is not None:
        give_session_site(sid, site)
    batch_id = f"file-{digest[:32]}"
    if not created and batch_id not in {b.client_batch_id for b in svc.store.batch_list(sid)}:
        raise APIError(409, f"session_id '{key}' already names session {sid} (a "
                            f"session_id is your key for one session): add this file to it with POST "
                            f"/api/v1/sessions/{sid}/devices/ROLE/upload, or choose another session_id",
                       details={"field": "session_id", "session": sid})
    dev = recording.device
    store_batch(svc, sid, client_batch_id=batch_id, payload_format=FILE_PREFIX + descriptor,
                payload=payload, t_first_ns=t_first, t_last_ns=t_last, device=replace(dev, placement=placement),
                recording=recording)
    svc.store.set_session(sid, t0_ns=recording.origin_ns)
    geo_reference(sid, recording)
    return jsonify(session_json(svc.store.session_row(sid, user_id))), 201 if created else 200


def geo_reference(session_id: str, recording: Recording) -> None:
    """Give a session without an origin the recording's (:func:`geo_origin`): its track, GeoJSON and map are then
    geo-referenced.
    """
    svc = services()
    origin = geo_origin(recording)
    if origin is not None and svc.store.session_row(session_id).origin_lat_deg is None:
        svc.store.set_session(session_id, origin_lat_deg=origin[0], origin_lon_deg=origin[1])


@bp.get("")
def list_sessions() -> Response:
    user = current_user()
    no_query_parameters()
    rows = services().store.list_sessions(user.id)
    return jsonify({"sessions": [session_json(r) for r in rows]})


@bp.get("/<session_id>")
def get_session(session_id: str) -> Response:
    """The session by its id, or by the client's ``session_id`` (a key unique per user)."""
    user = current_user()
    store = services().store
    try:
        row = store.session_row(session_id, user.id)
    except APIError:
        by_key = store.session_by_key(user.id, session_id)
        if by_key is None:
            raise
        row = by_key
    return jsonify(session_json(row, detail=True))


@bp.delete("/<session_id>")
def delete_session(session_id: str) -> tuple[str, int]:
    """Delete the session: its raw batches, results, processing state and queued work. Not reversible; at once, a pass
    processing it meanwhile writes nothing more (:meth:`server.store.Store.fenced`).
    """
    user = current_user()
    svc = services()
    svc.store.session_row(session_id, user.id)
    svc.store.delete_session(session_id)
    return "", 204


def refuse_file(session_id: str) -> None:
    """415 naming the upload route when a log file (multipart) is sent to a route that takes JSON."""
    if request.mimetype == "multipart/form-data":
        raise APIError(415, f"this route takes JSON; a log file of a paired device goes to POST "
                            f"/api/v1/sessions/{session_id}/devices/ROLE/upload (multipart field 'file'), a log "
                            "file for a new session to POST /api/v1/sessions", details={"field": "file"})


@bp.post("/<session_id>/devices")
def pair_device(session_id: str) -> tuple[Response, int]:
    """Pair a device (e.g. shoe IMUs with roles left_foot / right_foot) with a session."""
    user = current_user()
    svc = services()
    svc.store.session_row(session_id, user.id)
    refuse_file(session_id)
    body = json_body("device")
    validate(body, PAIR_DEVICE, "device")
    svc.store.upsert_device(session_id, body["role"], device_id=body.get("device_id", ""),
                            platform=body.get("platform", "imu" if body["role"] != "phone" else "unknown"),
                            model=body.get("model", ""), placement=body.get("placement"))
    return jsonify(session_json(svc.store.session_row(session_id, user.id))), 201


@bp.post("/<session_id>/devices/<role>/upload")
def upload_device_file(session_id: str, role: str) -> tuple[Response, int]:
    """Add a log file of one paired device to an existing session (multipart ``file``, optional ``format``).

    Any format the readers know (a shoe IMU: PyShoe ``.mat``, SensorConnect CSV, x-io CSV, native JSON); the
    pairing decides the device, not the file (a reader's default ``right_foot`` becomes the paired
    ``left_foot``). 409 when ``role`` is not paired with the session, 422 when the file is not that kind of
    device's (a phone log for a foot). Re-sending the same file is a no-op (200).
    """
    user = current_user(scope="ingest")
    svc = services()
    svc.store.session_row(session_id, user.id)
    require_paired(session_id, role)
    upload = uploaded_log()
    recording = upload.recording
    if (role in FOOT_ROLES) != recording.device.is_foot:
        kind = "a shoe IMU's" if recording.device.is_foot else "a phone's"
        raise APIError(422, f"'{upload.filename}' ({upload.format}) is {kind} log; the session's {role} needs "
                            f"{'a shoe IMU' if role in FOOT_ROLES else 'a phone'} log", details={"field": "file"})
    foot = role in FOOT_ROLES
    device = replace(recording.device, role=role, placement="foot" if foot else recording.device.placement)
    t_first, t_last = time_span_ns(recording, "file")
    fmt = FILE_PREFIX + upload.descriptor
    plausibility.check_units(recording)
    plausibility.check_location(recording)
    plausibility.check_time(svc.store.engine, session_id, role, fmt, t_first, t_last)
    digest = hashlib.sha256(upload.payload).hexdigest()
    accepted = store_batch(svc, session_id, client_batch_id=f"file-{role}-{digest[:32]}", payload_format=fmt,
                           payload=upload.payload, t_first_ns=t_first, t_last_ns=t_last, device=device,
                           recording=recording)
    return (jsonify({"id": accepted.id, "device_role": role, "format": upload.format, "file": upload.filename,
                     "duplicate": not accepted.created}), 201 if accepted.created else 200)


def require_paired(session_id: str, role: str, field: str = "role", why: str = "") -> None:
    """409 unless a device of ``role`` is paired with the session (``POST .../devices``); 422 for no known role.
    ``field`` names where the request gives the role, ``why`` adds the reason to the 409's message.
    """
    if role not in DEVICE_ROLES:
        raise APIError(422, f"unknown device role '{role[:40]}'; expected one of {', '.join(DEVICE_ROLES)}",
                       details={"field": field})
    if role not in {d.role for d in services().store.devices(session_id)}:
        raise APIError(409, f"no {role} is paired with this session: pair it first with POST "
                            f"/api/v1/sessions/{session_id}/devices {{\"role\": \"{role}\"}}{why}",
                       details={"field": field})


@bp.post("/<session_id>/batches")
def add_native_batch(session_id: str) -> tuple[Response, int]:
    """Ingest a native JSON batch (``pdr-batch/1``); re-sending the same ``batch_id`` is a no-op."""
    from pdr.io.native import batch_from_json

    user = current_user(allow_query_token=True, scope="ingest")
    svc = services()
    svc.store.session_row(session_id, user.id)
    refuse_file(session_id)
    body = json_body("native batch")
    batch_id = body.get("batch_id")
    if not isinstance(batch_id, str) or not batch_id:
        raise APIError(422, "a native batch needs a non-empty string 'batch_id'", details={"field": "batch_id"})
    try:
        recording = batch_from_json(body, source=f"batch '{batch_id}'")
    except InputError as exc:
        raise APIError(422, str(exc), details=exc.details()) from None
    t_first, t_last = time_span_ns(recording, "streams")
    plausibility.check_identity(svc.store.engine, session_id, batch_id, body.get("session_id"), recording)
    plausibility.check_batch(svc.store.engine, session_id, NATIVE_JSON, recording, t_first, t_last)
    role = recording.device.role
    if not pairs_itself(svc.store, session_id, role):
        require_paired(session_id, role, field="device.role",
                       why="; a session with a phone takes a shoe IMU's batches once its foot is paired (a phone's "
                           "own batches have device.role 'phone'); batch not stored")
    accepted = store_batch(svc, session_id, client_batch_id=batch_id, payload_format=NATIVE_JSON,
                           payload=request.get_data(), t_first_ns=t_first, t_last_ns=t_last,
                           device=recording.device, content=body, recording=recording)
    return (jsonify({"batch_id": batch_id, "id": accepted.id, "duplicate": not accepted.created}),
            201 if accepted.created else 200)


@bp.post("/<session_id>/reprocess")
def reprocess(session_id: str) -> tuple[Response, int]:
    """Rebuild every result of the session from its stored raw batches: cleared at once (a pass running now writes
    nothing more), rebuilt by the worker's next pass.
    """
    user = current_user()
    svc = services()
    svc.store.session_row(session_id, user.id)
    svc.processing.clear(session_id)
    svc.worker.submit(session_id)
    return jsonify({"id": session_id, "status": "pending"}), 202


@bp.put("/<session_id>/processing")
def set_processing(session_id: str) -> tuple[Response, int]:
    """Replace the session's processing options (e.g. a calibration made after the walk) and rebuild its results with
    them, as :func:`reprocess`.
    """
    user = current_user()
    svc = services()
    row = svc.store.session_row(session_id, user.id)
    body = json_body("processing")
    validate(body, PROCESSING, "processing")
    options = ProcessingOptions.from_json(body)
    site = named_site(options, user.id)
    svc.processing.refuse_unrebuildable(session_id)     # before the options change: they would not be applied
    meta = {k: v for k, v in json.loads(row.meta or "{}").items() if k != META_KEY} | (_meta(options) or {})
    give_session_site(session_id, site)
    svc.store.set_session(session_id, meta=json.dumps(meta))
    svc.processing.clear(session_id)
    svc.worker.submit(session_id)
    return jsonify({"id": session_id, "status": "pending", "processing": options.to_json()}), 202
