"""Allan-variance sensor reports: upload a static log, then fetch the report as JSON, HTML and PNG plots.

``POST /api/v1/reports/allan`` (multipart ``file``, optional ``format``) stores the request and answers
202 with the report id; the characterisation runs on a background thread of the web process (a 2.8 h
100 Hz record takes seconds). ``GET /api/v1/reports/{id}`` gives the status and, when done, every number;
``/report.html``, ``/files/{name}`` (``gyro.png``, ``acc.png``, ``imu.yaml``, ``filter_params.json``).
"""

from __future__ import annotations

import json
import logging
import tempfile
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, jsonify
from sqlalchemy import delete, insert, select, update

from pdr.errors import InputError
from server import db
from server.api import current_user, services, uploaded_log
from server.errors import APIError
from server.processing import read_uploaded_file
from server.store import Store

log = logging.getLogger(__name__)
bp = Blueprint("reports", __name__, url_prefix="/api/v1/reports")

MEDIA_TYPES = {".png": "image/png", ".html": "text/html; charset=utf-8", ".yaml": "text/yaml",
               ".json": "application/json"}
_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="pdr-reports")


def run_allan_report(store: Store, report_id: str, payload: bytes, descriptor: str) -> None:
    """Characterise the uploaded log and store the report files; failures are stored on the report."""
    from pdr.allan.characterise import characterise_recording
    from pdr.allan.report import write_report

    try:
        recording = read_uploaded_file(payload, descriptor)
        result = characterise_recording(recording)
        with tempfile.TemporaryDirectory(prefix="pdr-report-") as tmp:
            paths = write_report(result, tmp)
            files = {p.name: p.read_bytes() for p in paths.values()}
        with store.engine.begin() as conn:
            for name, content in files.items():
                conn.execute(insert(db.report_files).values(
                    report_id=report_id, name=name, content=content,
                    media_type=MEDIA_TYPES.get(Path(name).suffix, "application/octet-stream")))
            conn.execute(update(db.reports).where(db.reports.c.id == report_id).values(
                status="done", result=files["report.json"].decode("utf-8")))
    except InputError as exc:
        _fail(store, report_id, str(exc))
    except Exception as exc:  # keep the failure visible through the API, not only in the log
        log.exception("Allan report %s failed", report_id)
        _fail(store, report_id, f"internal error: {type(exc).__name__}: {exc}")


def _fail(store: Store, report_id: str, message: str) -> None:
    with store.engine.begin() as conn:
        conn.execute(update(db.reports).where(db.reports.c.id == report_id).values(status="failed", error=message))


@bp.post("/allan")
def create_allan_report() -> tuple[Response, int]:
    user = current_user()
    svc = services()
    upload = uploaded_log("static log")
    filename = upload.filename
    report_id = str(uuid.uuid4())
    with svc.store.engine.begin() as conn:
        conn.execute(insert(db.reports).values(id=report_id, user_id=user.id, kind="allan", status="pending",
                                               source_name=filename[:300], created_at=db.utcnow()))
    _executor.submit(run_allan_report, svc.store, report_id, upload.payload, upload.descriptor)
    return jsonify({"id": report_id, "status": "pending"}), 202


def _report(report_id: str) -> Any:
    user = current_user()
    with services().store.engine.connect() as conn:
        row = conn.execute(select(db.reports).where(db.reports.c.id == report_id)).first()
    if row is None or row.user_id != user.id:
        raise APIError(404, f"no report '{report_id}'")
    return row


@bp.get("")
def list_reports() -> Response:
    user = current_user()
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
        raise APIError(404, f"report '{report_id}' has no file '{name}'")
    return Response(f.content, mimetype=f.media_type.split(";")[0],
                    headers={"Content-Disposition": f'inline; filename="{f.name}"'})


@bp.get("/<report_id>/report.html")
def report_html(report_id: str) -> Response:
    return report_file(report_id, "report.html")
