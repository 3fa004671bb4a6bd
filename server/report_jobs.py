"""Allan-variance reports as recoverable jobs.

``POST /api/v1/reports/allan`` stores the report (status ``pending``) and its upload (``report_uploads``) in one
transaction before answering 202, then queues it here. A job *claims* the report (sets ``started_at`` and counts
an attempt) so that only one process runs it, characterises the log, stores the files and drops the upload.
On start-up, :meth:`ReportRunner.recover` queues every pending report again: those never started, and those
whose run was interrupted (in the embedded default every interrupted run; with several web processes, those
started more than ``stale_s`` ago). A report interrupted :data:`MAX_ATTEMPTS` times fails with that reason
instead of crashing the service again.
"""

from __future__ import annotations

import dataclasses
import logging
import tempfile
import zlib
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta
from pathlib import Path

from sqlalchemy import delete, insert, or_, select, update

from pdr.errors import InputError
from server import db
from server.store import Store

log = logging.getLogger(__name__)

MEDIA_TYPES = {".png": "image/png", ".html": "text/html; charset=utf-8", ".yaml": "text/yaml",
               ".json": "application/json"}
#: Interrupted runs of one report before it is failed.
MAX_ATTEMPTS = 3


class ReportRunner:
    """Runs report jobs on one background thread of this process."""

    def __init__(self, store: Store, stale_s: float = 900.0) -> None:
        self.store = store
        self.stale_s = stale_s
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="pdr-reports")

    def create(self, report_id: str, user_id: int, source_name: str, payload: bytes, descriptor: str) -> None:
        """Store a pending Allan report with its upload (committed before the client is answered), and queue it."""
        with self.store.engine.begin() as conn:
            conn.execute(insert(db.reports).values(id=report_id, user_id=user_id, kind="allan", status="pending",
                                                   source_name=source_name[:300], created_at=db.utcnow()))
            conn.execute(insert(db.report_uploads).values(report_id=report_id, descriptor=descriptor[:300],
                                                          payload=zlib.compress(payload, 6)))
        self.submit(report_id)

    def submit(self, report_id: str) -> None:
        self._executor.submit(self.run, report_id)

    def recover(self, every_interrupted: bool) -> list[str]:
        """Queue the pending reports again; ``every_interrupted``: also those started by a process that is gone
        (true when this is the only process). Returns their ids.
        """
        r = db.reports
        started_before = db.utcnow() - timedelta(seconds=0 if every_interrupted else self.stale_s)
        with self.store.engine.connect() as conn:
            ids = [str(row.id) for row in conn.execute(select(r.c.id).where(
                r.c.status == "pending", or_(r.c.started_at.is_(None), r.c.started_at <= started_before)))]
        for report_id in ids:
            self.submit(report_id)
        return ids

    def stop(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)

    def _claim(self, report_id: str) -> tuple[bytes, str] | None:
        """Take the report (one more attempt) and return its upload; None if it is done, gone or failed now."""
        r, u = db.reports, db.report_uploads
        with self.store.engine.begin() as conn:
            row = conn.execute(select(r.c.status, r.c.attempts, u.c.payload, u.c.descriptor)
                               .select_from(r.outerjoin(u, u.c.report_id == r.c.id)).where(r.c.id == report_id)
                               ).first()
            if row is None or row.status != "pending":
                return None
            if row.payload is None or row.attempts >= MAX_ATTEMPTS:
                why = ("its upload is missing" if row.payload is None
                       else f"its processing was interrupted {row.attempts} times (a crash or a restart)")
                conn.execute(update(r).where(r.c.id == report_id).values(status="failed",
                                                                         error=f"report failed: {why}"))
                conn.execute(delete(u).where(u.c.report_id == report_id))
                return None
            conn.execute(update(r).where(r.c.id == report_id).values(attempts=row.attempts + 1,
                                                                      started_at=db.utcnow()))
            return zlib.decompress(row.payload), str(row.descriptor)

    def run(self, report_id: str) -> None:
        """Run one report job; failures are stored on the report, never raised."""
        try:
            claimed = self._claim(report_id)
            if claimed is not None:
                self._characterise(report_id, *claimed)
        except Exception:  # the thread must survive; the report stays pending and is recovered on restart
            log.exception("Allan report %s could not be run", report_id)

    def _characterise(self, report_id: str, payload: bytes, descriptor: str) -> None:
        from pdr.allan.characterise import characterise_recording
        from pdr.allan.report import write_report
        from server.processing import read_uploaded_file

        try:
            recording = read_uploaded_file(payload, descriptor)
            # The report names the uploaded file, never the server's temporary copy that the reader was given.
            result = dataclasses.replace(characterise_recording(recording),
                                         source=descriptor.partition("/")[2] or "upload")
            with tempfile.TemporaryDirectory(prefix="pdr-report-") as tmp:
                paths = write_report(result, tmp)
                files = {p.name: p.read_bytes() for p in paths.values()}
        except InputError as exc:
            self._finish(report_id, error=str(exc))
            return
        except Exception as exc:  # keep the failure visible through the API, not only in the log
            log.exception("Allan report %s failed", report_id)
            self._finish(report_id, error=f"internal error: {type(exc).__name__}: {exc}")
            return
        self._finish(report_id, files=files)

    def _finish(self, report_id: str, files: dict[str, bytes] | None = None, error: str | None = None) -> None:
        with self.store.engine.begin() as conn:
            if files is not None:
                for name, content in files.items():
                    conn.execute(insert(db.report_files).values(
                        report_id=report_id, name=name, content=content,
                        media_type=MEDIA_TYPES.get(Path(name).suffix, "application/octet-stream")))
                conn.execute(update(db.reports).where(db.reports.c.id == report_id).values(
                    status="done", result=files["report.json"].decode("utf-8")))
            else:
                conn.execute(update(db.reports).where(db.reports.c.id == report_id).values(status="failed",
                                                                                          error=error))
            conn.execute(delete(db.report_uploads).where(db.report_uploads.c.report_id == report_id))
