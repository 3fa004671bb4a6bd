"""Allan-variance reports as recoverable jobs.

``POST /api/v1/reports/allan`` reads the upload once, then stores the report (status ``pending``), the upload and
the recording read (``report_uploads``) in one transaction before answering 202, and queues it: on a thread of
the web process in the embedded default, as an RQ job for ``pdr worker`` with ``PDR_WORKER=redis``
(:mod:`server.queue`). A job *claims* the report (sets ``started_at`` and counts an attempt) so that only one
process runs it, keeps ``started_at`` fresh while it runs (a heartbeat every ``stale_s / 3``), characterises the
recording, stores the files and drops the upload.

A second run of one report (its job thought lost and queued again while the first still ran, or a run taken over
after its heartbeat stalled) is harmless: the attempt number of the claim fences every later write, so only the
run holding the latest claim stores files or refreshes the heartbeat; a superseded run's result is dropped.

Recovery: :meth:`ReportRunner.interrupted` lists the pending reports never started and those whose heartbeat
stopped more than ``stale_s`` ago (their process is gone). The embedded service queues them all again on start-up
(it is the only process, so every started report was interrupted); ``pdr worker``'s reconciler queues them
periodically. A report interrupted :data:`MAX_ATTEMPTS` times fails with that reason instead of crashing the
service again.
"""

from __future__ import annotations

import dataclasses
import logging
import tempfile
import threading
import zlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime, timedelta
from pathlib import Path

from sqlalchemy import ColumnElement, and_, delete, insert, or_, select, true, update

from pdr import recording_codec
from pdr.errors import InputError
from pdr.recording import Recording
from server import db
from server.store import DECODED_ZLIB_LEVEL, Store

log = logging.getLogger(__name__)

MEDIA_TYPES = {".png": "image/png", ".html": "text/html; charset=utf-8", ".yaml": "text/yaml",
               ".json": "application/json"}
#: Interrupted runs of one report before it is failed.
MAX_ATTEMPTS = 3
#: Seconds without a heartbeat after which a started report counts as interrupted.
STALE_S = 60.0


class ReportRunner:
    """Claims and runs report jobs; ``enqueue`` queues one (default: a background thread of this process).

    Parameters
    ----------
    store
        The service's storage.
    enqueue
        Called with a report id to have :meth:`run` called on it somewhere (an RQ job); ``None``: on this process's
        own report thread.
    stale_s
        Heartbeat age, s, after which a started report is taken as interrupted.
    """

    def __init__(self, store: Store, enqueue: Callable[[str], object] | None = None, stale_s: float = STALE_S) -> None:
        self.store = store
        self.stale_s = stale_s
        self._enqueue = enqueue
        self._executor: ThreadPoolExecutor | None = (
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="pdr-reports") if enqueue is None else None)

    def create(self, report_id: str, user_id: int, source_name: str, payload: bytes, descriptor: str,
               recording: Recording) -> None:
        """Store a pending Allan report with its upload and the recording read from it (committed before the
        client is answered), and queue it.
        """
        with self.store.engine.begin() as conn:
            conn.execute(insert(db.reports).values(id=report_id, user_id=user_id, kind="allan", status="pending",
                                                   source_name=source_name[:300], created_at=db.utcnow()))
            conn.execute(insert(db.report_uploads).values(
                report_id=report_id, descriptor=descriptor[:300], payload=zlib.compress(payload, 6),
                decoded=zlib.compress(recording_codec.dumps(recording), DECODED_ZLIB_LEVEL)))
        self.submit(report_id)

    @property
    def runs_here(self) -> bool:
        """Whether reports run on this process's own thread (not as jobs of other processes)."""
        return self._executor is not None

    def submit(self, report_id: str, take_over: bool = False) -> None:
        """Queue a run of the report; ``take_over``: even if a run of it started recently (this process is the only
        one and has just started, so that run is gone).
        """
        if self._executor is not None:
            self._executor.submit(self.run, report_id, take_over)
        else:
            assert self._enqueue is not None
            self._enqueue(report_id)

    def interrupted(self, every_started: bool = False) -> list[str]:
        """Pending reports never started or whose heartbeat stopped ``stale_s`` ago (``every_started``: all)."""
        r = db.reports
        with self.store.engine.connect() as conn:
            return [str(row.id) for row in conn.execute(select(r.c.id).where(
                r.c.status == "pending", self._claimable(every_started)).order_by(r.c.created_at))]

    def recover(self, every_interrupted: bool) -> list[str]:
        """Queue the :meth:`interrupted` reports again (``every_interrupted``: every started one too, true when this
        is the only process and it has just started). Returns their ids.
        """
        ids = self.interrupted(every_started=every_interrupted)
        for report_id in ids:
            self.submit(report_id, take_over=every_interrupted)
        return ids

    def stop(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)

    def _claimable(self, take_over: bool) -> ColumnElement[bool]:
        if take_over:
            return true()
        started = db.reports.c.started_at
        return or_(started.is_(None), started <= self._stale_before())

    def _stale_before(self) -> datetime:
        return db.utcnow() - timedelta(seconds=self.stale_s)

    def _claim(self, report_id: str, take_over: bool = False) -> _Claim | None:
        """Take the report (one more attempt) and return its upload; ``None`` if it is done, gone, failed now, or run
        by another process (its heartbeat is fresh; ``take_over`` ignores it).
        """
        r, u = db.reports, db.report_uploads
        with self.store.engine.begin() as conn:
            row = conn.execute(select(r.c.status, r.c.attempts, u.c.descriptor, u.c.report_id.label("upload"))
                               .select_from(r.outerjoin(u, u.c.report_id == r.c.id)).where(r.c.id == report_id)
                               ).first()
            if row is None or row.status != "pending":
                return None
            if row.upload is None or row.attempts >= MAX_ATTEMPTS:
                why = ("its upload is missing" if row.upload is None
                       else f"its processing was interrupted {row.attempts} times (a crash or a restart)")
                conn.execute(update(r).where(r.c.id == report_id).values(status="failed",
                                                                         error=f"report failed: {why}"))
                conn.execute(delete(u).where(u.c.report_id == report_id))
                return None
            # One statement decides who runs it: another process's fresh claim makes this one match no row.
            claimed = conn.execute(update(r).where(and_(r.c.id == report_id, r.c.status == "pending",
                                                        r.c.attempts == row.attempts, self._claimable(take_over)))
                                   .values(attempts=row.attempts + 1, started_at=db.utcnow())).rowcount
            if not claimed:
                return None
            up = conn.execute(select(u.c.payload, u.c.decoded).where(u.c.report_id == report_id)).one()
            return _Claim(row.attempts + 1, zlib.decompress(up.payload), str(row.descriptor),
                          None if up.decoded is None else zlib.decompress(up.decoded))

    def run(self, report_id: str, take_over: bool = False) -> None:
        """Run one report job; failures are stored on the report, never raised."""
        try:
            claim = self._claim(report_id, take_over)
            if claim is not None:
                with self._heartbeat(report_id, claim.attempt):
                    self._characterise(report_id, claim)
        except Exception:  # the thread must survive; the report stays pending and is recovered on restart
            log.exception("Allan report %s could not be run", report_id)

    def _heartbeat(self, report_id: str, attempt: int) -> _Heartbeat:
        return _Heartbeat(self.store, report_id, attempt, self.stale_s / 3.0)

    def _characterise(self, report_id: str, claim: _Claim) -> None:
        from pdr.allan.characterise import characterise_recording
        from pdr.allan.report import write_report
        from server.processing import read_uploaded_file

        try:
            # What the upload's reader returned at ingest; reports stored before that was kept are read now.
            recording = (recording_codec.loads(claim.decoded) if claim.decoded is not None
                         else read_uploaded_file(claim.payload, claim.descriptor))
            # The report names the uploaded file, never the server's temporary copy that the reader was given.
            result = dataclasses.replace(characterise_recording(recording),
                                         source=claim.descriptor.partition("/")[2] or "upload")
            with tempfile.TemporaryDirectory(prefix="pdr-report-") as tmp:
                paths = write_report(result, tmp)
                files = {p.name: p.read_bytes() for p in paths.values()}
        except InputError as exc:
            self._finish(report_id, claim.attempt, error=str(exc))
            return
        except Exception as exc:  # keep the failure visible through the API, not only in the log
            log.exception("Allan report %s failed", report_id)
            self._finish(report_id, claim.attempt, error=f"internal error: {type(exc).__name__}: {exc}")
            return
        self._finish(report_id, claim.attempt, files=files)

    def _finish(self, report_id: str, attempt: int, files: dict[str, bytes] | None = None,
                error: str | None = None) -> bool:
        """Store the run's outcome if its claim (``attempt``) is still the report's latest and the report is still
        pending; otherwise (a later run took it over, or finished it) drop it. Returns whether it was stored.
        """
        r = db.reports
        mine = and_(r.c.id == report_id, r.c.status == "pending", r.c.attempts == attempt)
        with self.store.engine.begin() as conn:
            values = ({"status": "done", "result": files["report.json"].decode("utf-8")} if files is not None
                      else {"status": "failed", "error": error})
            if not conn.execute(update(r).where(mine).values(**values)).rowcount:  # settles a race: one row, once
                log.info("Allan report %s: the result of attempt %d is dropped (a later run took the report over or "
                         "finished it)", report_id, attempt)
                return False
            for name, content in (files or {}).items():
                conn.execute(insert(db.report_files).values(
                    report_id=report_id, name=name, content=content,
                    media_type=MEDIA_TYPES.get(Path(name).suffix, "application/octet-stream")))
            conn.execute(delete(db.report_uploads).where(db.report_uploads.c.report_id == report_id))
        return True


@dataclasses.dataclass(frozen=True)
class _Claim:
    """A run's claim on a report: its attempt number (fences the run's writes) and the stored upload (raw bytes,
    ``FORMAT/FILENAME`` descriptor, the recording read at ingest as :mod:`pdr.recording_codec` bytes or ``None``).
    """

    attempt: int
    payload: bytes
    descriptor: str
    decoded: bytes | None


class _Heartbeat:
    """Keeps a claimed report's ``started_at`` fresh every ``period_s`` while its run lasts (a context manager), as
    long as the claim (``attempt``) is the report's latest: a superseded run does not make the report look alive.
    """

    def __init__(self, store: Store, report_id: str, attempt: int, period_s: float) -> None:
        self.store = store
        self.report_id = report_id
        self.attempt = attempt
        self.period_s = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"pdr-report-heartbeat-{report_id[:8]}", daemon=True)

    def __enter__(self) -> _Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def beat(self) -> bool:
        """Refresh ``started_at`` once if the claim is still the latest; returns whether it was."""
        with self.store.engine.begin() as conn:
            return bool(conn.execute(update(db.reports).where(db.reports.c.id == self.report_id,
                                                              db.reports.c.status == "pending",
                                                              db.reports.c.attempts == self.attempt)
                                     .values(started_at=db.utcnow())).rowcount)

    def _beat(self) -> None:
        while not self._stop.wait(self.period_s):
            try:
                self.beat()
            except Exception as exc:  # the database may be down for a moment; the next beat tries again
                log.warning("heartbeat of report %s: %s", self.report_id, exc)
