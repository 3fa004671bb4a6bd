"""Allan-variance sensor reports: upload a static log, then fetch the report as JSON, HTML and PNG plots.

``POST /api/v1/reports/allan`` (multipart ``file``, optional ``format``) reads the log once (422 if it cannot
be read), stores the report with the upload and the recording read, and answers 202 with the report id; the
characterisation runs as a recoverable job (:mod:`server.report_jobs`; a 2.8 h 100 Hz record takes seconds),
resumed after a restart. ``GET /api/v1/reports/{id}`` gives the status
and, when done, every number; ``/report.html``, ``/files/{name}`` (``gyro.png``, ``acc.png``, ``imu.yaml``,
``filter_params.json``).
"""

from __future__ import annotations

import json
import logging
import uuid
from typing import Any

from flask import Blueprint, Response, jsonify
from sqlalchemy import delete, select

from server import db
from server.api import current_user, no_query_parameters, services, uploaded_log
from server.errors import APIError

log = logging.getLogger(__name__)
bp = Blueprint("reports", __name__, url_prefix="/api/v1/reports")

@bp.post("/allan")
def create_allan_report() -> tuple[Response, int]:
    user = current_user()
    svc = services()
    upload = uploaded_log("static log")  # read once, here: the job characterises what was read
    report_id = str(uuid.uuid4())
    svc.reports.create(report_id, user.id, upload.filename, upload.payload, upload.descriptor, upload.recording)
    return jsonify({"id": report_id, "status": "pending"}), 202


def _report(report_id: str) -> Any:
    user = current_user()
    with services().store.engine.connect() as conn:
        row = conn.execute(select(db.reports).where(db.reports.c.id == report_id)).first()
    if row is None or row.user_id != user.id:
        raise APIError(404, f"no report '{report_id[:64]}'")
    return row


@bp.get("")
def list_reports() -> Response:
    user = current_user()
    no_query_parameters()
    with services().store.engine.connect() as conn:
        rows = conn.execute(select(db.reports.c.id, db.reports.c.kind, db.reports.c.status, db.reports.c.source_name,
                                   db.reports.c.created_at, db.reports.c.error)
                            .where(db.reports.c.user_id == user.id).order_by(db.reports.c.created_at))
        return jsonify({"reports": [{"id": r.id, "kind": r.kind, "status": r.status, "source": r.source_name,
                                     "created_at": r.created_at.isoformat(), "error": r.error} for r in rows]})


@bp.get("/<report_id>")
def get_report(report_id: str) -> Response:
    row = _report(report_id)
    with services().store.engine.connect() as conn:
        names = [r.name for r in conn.execute(select(db.report_files.c.name)
                                              .where(db.report_files.c.report_id == report_id))]
    return jsonify({"id": row.id, "kind": row.kind, "status": row.status, "source": row.source_name,
                    "created_at": row.created_at.isoformat(), "error": row.error, "files": sorted(names),
                    "report": json.loads(row.result) if row.result else None})


@bp.delete("/<report_id>")
def delete_report(report_id: str) -> tuple[str, int]:
    """Delete the report and its files."""
    _report(report_id)
    with services().store.engine.begin() as conn:
        conn.execute(delete(db.reports).where(db.reports.c.id == report_id))
    return "", 204


@bp.get("/<report_id>/files/<name>")
def report_file(report_id: str, name: str) -> Response:
    _report(report_id)
    with services().store.engine.connect() as conn:
        f = conn.execute(select(db.report_files).where(db.report_files.c.report_id == report_id,
                                                       db.report_files.c.name == name)).first()
    if f is None:
        raise APIError(404, f"report '{report_id[:64]}' has no file '{name[:64]}'")
    return Response(f.content, mimetype=f.media_type.split(";")[0],
                    headers={"Content-Disposition": f'inline; filename="{f.name}"'})


@bp.get("/<report_id>/report.html")
def report_html(report_id: str) -> Response:
    return report_file(report_id, "report.html")
