"""Shoe units' low-rate interface: ``POST /api/v1/sessions/{id}/steps`` with step-wise dead-reckoning summaries.

The body is a ``pdr-foot-steps/1`` payload (:mod:`pdr.foot.summaries`, JSON Schema ``FootSteps`` in the OpenAPI
document). Like native batches it is stored raw before processing and is idempotent by its ``batch_id``
(a re-sent identical payload is a no-op, different content under the same id a 409); it is parsed and validated
once, here, and the decoded summaries are stored with it (:mod:`pdr.foot.summaries_codec`); the session's
``left_foot`` / ``right_foot`` processor (:class:`server.foot_processor.FootProcessor`) composes the summaries.
The payload's foot must be paired with the session first (``POST .../devices``), 409 otherwise.
"""

from __future__ import annotations

from flask import Blueprint, Response, jsonify, request

from pdr.errors import InputError
from pdr.foot.summaries import SCHEMA, steps_from_json
from pdr.recording import DeviceInfo
from server.api import current_user, json_body, services
from server.api.sessions import refuse_file, require_paired
from server.errors import APIError
from server.ingest import store_batch
from server.processing import FOOT_STEPS_JSON
from server.schemas import validate

bp = Blueprint("foot", __name__, url_prefix="/api/v1/sessions")


@bp.post("/<session_id>/steps")
def add_step_summaries(session_id: str) -> tuple[Response, int]:
    """Ingest step summaries of one shoe unit; re-sending the same ``batch_id`` is a no-op."""
    user = current_user(allow_query_token=True, scope="ingest")
    svc = services()
    svc.store.session_row(session_id, user.id)
    refuse_file(session_id)
    body = json_body("step summaries")
    validate(body, SCHEMA, "step summaries")
    batch_id = body["batch_id"]
    try:
        summaries = steps_from_json(body, source=f"batch '{batch_id}'")
    except InputError as exc:
        raise APIError(422, str(exc), details=exc.details()) from None
    require_paired(session_id, summaries.role)
    dev = body["device"]
    accepted = store_batch(svc, session_id, client_batch_id=batch_id, payload_format=FOOT_STEPS_JSON,
                           payload=request.get_data(), t_first_ns=summaries.t_first_ns,
                           t_last_ns=summaries.t_last_ns, content=body, recording=summaries,
                           device=DeviceInfo(platform="imu", model=dev.get("model", ""), role=summaries.role,
                                             placement="foot", device_id=dev.get("device_id", "")))
    return (jsonify({"batch_id": batch_id, "id": accepted.id, "duplicate": not accepted.created,
                     "steps": len(summaries.steps)}), 201 if accepted.created else 200)
