"""Processing jobs on Redis with RQ: web processes enqueue sessions, ``pdr worker`` processes run them.

Why RQ rather than Celery: a job here is one Python call, ``process_session_job(session_id)``, on one
queue; RQ does exactly that with Redis alone, in a few hundred lines we can read, and is the queue the
Flask documentation points to for background work. Celery's broker abstraction, result backends, beat
scheduler and canvas add configuration and moving parts that this service does not use, and its
retry/ack semantics would still not give per-session ordering across workers, which we need anyway.

Reliability does not rest on Redis. The database is the source of truth: a batch is committed as
``pending`` before the upload is acknowledged, and a job only says "look at this session". Hence:

- Enqueueing is deduplicated per session by a flag key (``{ns}:queued:{session}`` holding the job id),
  cleared when the job starts, so a burst of uploads queues one job and a backlog coalesces.
- Per-session ordering across workers comes from the database lease of :mod:`server.leases`, not from
  Redis; a job that finds the session leased by a live worker ends (the holder re-enqueues the session
  when it sees new pending batches after releasing it).
- Transient failures (lost database or Redis connection, lease expired) are retried inside the job with
  exponential backoff; a batch interrupted too often becomes a dead letter (:mod:`server.leases`).
- Every worker runs a *reconciler* that periodically enqueues sessions with pending or interrupted batches
  and no live lease: jobs lost with a Redis restart, a failed enqueue while Redis was down, or a worker
  killed mid-job are all recovered from the database.

Workers are RQ simple workers (jobs run in the worker process, no fork per job): the processor's
compiled kernels and model files stay loaded between jobs, and the database pool is not shared across
a fork. A crash of a job therefore ends the worker process; run workers under a supervisor (systemd,
``Restart=always``) and the lease/reconciler recover its session.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import redis
from rq import Queue, get_current_job
from rq.exceptions import NoSuchJobError
from rq.job import Job, JobStatus
from sqlalchemy import exc as sa_exc

from server.config import Settings
from server.jobs import NoWorker
from server.leases import LeaseLost, Leases
from server.processing import SessionProcessing
from server.store import Store

log = logging.getLogger(__name__)

#: Errors that are not the data's fault: lost or refused connections to the database or Redis, a pool
#: timeout, a lease taken over. Retried with backoff; never mark a batch failed.
TRANSIENT_ERRORS: tuple[type[BaseException], ...] = (
    sa_exc.OperationalError, sa_exc.InterfaceError, sa_exc.DisconnectionError, sa_exc.TimeoutError,
    redis.exceptions.ConnectionError, redis.exceptions.TimeoutError, LeaseLost,
)

#: Longest a job may run before RQ stops it, s (a rebuild of a long session from raw batches).
JOB_TIMEOUT_S = 3600
#: How long a queued-flag lives at most, s (a safety net; the job or the reconciler clears it).
FLAG_TTL_S = 3600
ACTIVE_JOB_STATES = {JobStatus.QUEUED, JobStatus.STARTED, JobStatus.SCHEDULED, JobStatus.DEFERRED,
                     JobStatus.CREATED}


def redis_client(url: str) -> redis.Redis:
    """A Redis client with short timeouts, so that an unreachable Redis fails a call instead of hanging it."""
    return redis.Redis.from_url(url, socket_connect_timeout=2.0, socket_timeout=10.0, health_check_interval=30)


class SessionQueue:
    """The RQ queue of session jobs, with per-session deduplication.

    Parameters
    ----------
    connection
        Redis client.
    namespace
        Queue name and key prefix (``PDR_REDIS_NAMESPACE``), so several deployments can share a Redis.
    """

    def __init__(self, connection: redis.Redis, namespace: str = "pdr") -> None:
        self.redis = connection
        self.namespace = namespace
        self.queue = Queue(namespace, connection=connection)

    def flag_key(self, session_id: str) -> str:
        return f"{self.namespace}:queued:{session_id}"

    def report_flag_key(self, report_id: str) -> str:
        return f"{self.namespace}:report:{report_id}"

    def enqueue(self, session_id: str, verify: bool = False) -> bool:
        """Queue a job for the session unless one is already waiting; True if a job was queued.

        With ``verify`` (the reconciler), an existing flag is trusted only if its job is still queued or
        running in RQ; a flag whose job was lost (Redis restart, failed enqueue) is replaced.
        """
        return self._enqueue(self.flag_key(session_id), process_session_job, session_id,
                             f"process session {session_id}", verify)

    def enqueue_report(self, report_id: str, verify: bool = False) -> bool:
        """Queue a job running the Allan report (:mod:`server.report_jobs`) unless one waits, as :meth:`enqueue`."""
        return self._enqueue(self.report_flag_key(report_id), run_report_job, report_id,
                             f"Allan report {report_id}", verify)

    def _enqueue(self, key: str, job: Callable[[str], str], arg: str, description: str, verify: bool) -> bool:
        job_id = f"{self.namespace}-{uuid.uuid4().hex}"
        if not self.redis.set(key, job_id, nx=True, ex=FLAG_TTL_S):
            if not verify or self._flag_job_active(key):
                return False
            self.redis.set(key, job_id, ex=FLAG_TTL_S)
        try:
            self.queue.enqueue_call(job, args=(arg,), job_id=job_id, timeout=JOB_TIMEOUT_S,
                                    result_ttl=0, failure_ttl=7 * 86400, description=description)
        except Exception:
            try:
                self.redis.delete(key)
            except redis.exceptions.RedisError:
                pass
            raise
        return True

    def _flag_job_active(self, key: str) -> bool:
        raw = self.redis.get(key)
        if raw is None:
            return False
        try:
            status = Job.fetch(raw.decode() if isinstance(raw, bytes) else str(raw), connection=self.redis).get_status()
        except NoSuchJobError:
            return False
        return status in ACTIVE_JOB_STATES

    def started(self, session_id: str, job_id: str, key: str | None = None) -> None:
        """Clear the session's queued-flag (or ``key``) if it is this job's: uploads from now on queue a new job."""
        key = key or self.flag_key(session_id)
        raw = self.redis.get(key)
        if raw is not None and (raw.decode() if isinstance(raw, bytes) else str(raw)) == job_id:
            self.redis.delete(key)


class RedisEnqueuer(NoWorker):
    """The web side of ``PDR_WORKER=redis``: ``submit`` queues a job; processing happens in ``pdr worker``.

    An upload is acknowledged once its batch is committed to the database; if Redis is unreachable the
    job is not queued, which is logged and repaired by the workers' reconciler.
    """

    def __init__(self, settings: Settings) -> None:
        self.queue = SessionQueue(redis_client(settings.redis_url), settings.redis_namespace)

    def submit(self, session_id: str) -> None:
        try:
            self.queue.enqueue(session_id)
        except redis.exceptions.RedisError as exc:
            log.warning("could not queue session %s (%s); a worker's reconciler will pick it up", session_id, exc)

    def submit_report(self, report_id: str) -> None:
        """Queue an Allan report's job (stored before: a failed enqueue is repaired by the reconciler)."""
        try:
            self.queue.enqueue_report(report_id)
        except redis.exceptions.RedisError as exc:
            log.warning("could not queue report %s (%s); a worker's reconciler will pick it up", report_id, exc)

    def stop(self) -> None:
        self.queue.redis.close()


class LeasedStore(Store):
    """A :class:`Store` whose result commits are fenced by the worker's session lease."""

    def __init__(self, store: Store, leases: Leases) -> None:
        super().__init__(store.engine)
        self.leases = leases

    def commit_results(self, session_id: str, *args: Any, **kwargs: Any) -> None:
        kwargs["guard"] = lambda conn: self.leases.check(session_id, conn)
        super().commit_results(session_id, *args, **kwargs)


@dataclass
class RetryPolicy:
    """Exponential backoff of a job's transient failures: ``first_s``, doubled, at most ``max_s``."""

    retries: int = 6
    first_s: float = 0.5
    max_s: float = 30.0

    def delays(self) -> list[float]:
        return [min(self.first_s * 2.0 ** i, self.max_s) for i in range(self.retries)]


class WorkerRuntime:
    """What a ``pdr worker`` process needs to run session jobs: store, processing, leases, queue."""

    def __init__(self, processing: SessionProcessing, leases: Leases, queue: SessionQueue,
                 retry: RetryPolicy | None = None, sleep: Callable[[float], None] = time.sleep) -> None:
        from server.report_jobs import ReportRunner

        self.reports = ReportRunner(processing.store, enqueue=queue.enqueue_report)
        self.leases = leases
        self.queue = queue
        self.retry = retry or RetryPolicy()
        self.sleep = sleep
        self.store = LeasedStore(processing.store, leases)
        self.processing = SessionProcessing(self.store, processing.factory)
        self.processing.transient = TRANSIENT_ERRORS

    def run_session(self, session_id: str) -> str:
        """Process the session's pending batches under its lease, retrying transient failures.

        Returns ``done``, ``busy`` (another worker holds the lease) or ``lease lost``; re-raises the
        transient error after the last retry (the reconciler queues the session again later).
        """
        delays = self.retry.delays()
        for attempt in range(len(delays) + 1):
            try:
                return self._run_once(session_id)
            except LeaseLost:
                log.warning("session %s: lease lost to another worker; stopping", session_id)
                return "lease lost"
            except TRANSIENT_ERRORS as exc:
                message = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                try:
                    self.leases.note_error(session_id, message)
                except Exception:  # the database itself may be what failed
                    pass
                if attempt == len(delays):
                    log.error("session %s: giving up after %d retries: %s", session_id, attempt, message)
                    raise
                log.warning("session %s: transient failure (%s); retry %d in %.1f s", session_id, message,
                            attempt + 1, delays[attempt])
                self.sleep(delays[attempt])
        raise AssertionError("unreachable")

    def _run_once(self, session_id: str) -> str:
        if not self.leases.claim(session_id):
            return "busy"
        try:
            with self.leases.kept_alive(session_id):
                self.leases.recover_interrupted(session_id)
                self.processing.process_session(session_id)
        finally:
            try:
                self.leases.release(session_id)
            except Exception as exc:  # unreachable database: the lease expires by itself
                log.warning("could not release the lease of session %s: %s", session_id, exc)
        if self.store.batches(session_id, ["pending"], with_payload=False):
            # Uploads that arrived while we held the lease: their jobs found it busy. Back of the queue.
            try:
                self.queue.enqueue(session_id)
            except redis.exceptions.RedisError as exc:
                log.warning("could not requeue session %s (%s); the reconciler will", session_id, exc)
        return "done"

    def reconcile(self) -> int:
        """Queue every session with pending or interrupted batches and no live lease, and every Allan report never
        started or whose run stopped (:meth:`server.report_jobs.ReportRunner.interrupted`); returns how many.
        """
        queued = 0
        for session_id in self.leases.orphaned_sessions():
            if self.queue.enqueue(session_id, verify=True):
                queued += 1
        reports = sum(self.queue.enqueue_report(report_id, verify=True) for report_id in self.reports.interrupted())
        if queued or reports:
            log.info("reconciler queued %d session(s) with unprocessed batches and %d report(s)", queued, reports)
        return queued + reports

    def start_reconciler(self, period_s: float) -> threading.Event:
        """Run :meth:`reconcile` now and every ``period_s`` on a daemon thread; set the event to stop."""
        stop = threading.Event()

        def loop() -> None:
            while True:
                try:
                    self.reconcile()
                except Exception as exc:  # database or Redis down: try again next period
                    log.warning("reconciler: %s: %s", type(exc).__name__, str(exc).splitlines()[0] if str(exc) else "")
                if stop.wait(period_s):
                    return

        threading.Thread(target=loop, name="pdr-reconciler", daemon=True).start()
        return stop


_runtime: WorkerRuntime | None = None


def set_runtime(runtime: WorkerRuntime | None) -> None:
    """Install the runtime that :func:`process_session_job` uses in this worker process."""
    global _runtime
    _runtime = runtime


def process_session_job(session_id: str) -> str:
    """The RQ job: process a session's pending batches (runs in a ``pdr worker`` process)."""
    if _runtime is None:
        raise RuntimeError("no worker runtime in this process; start workers with 'pdr worker'")
    job = get_current_job()
    if job is not None:
        try:
            _runtime.queue.started(session_id, job.id)
        except redis.exceptions.RedisError:
            pass
    return _runtime.run_session(session_id)


def run_report_job(report_id: str) -> str:
    """The RQ job of an Allan report (runs in a ``pdr worker`` process): claim it, characterise, store the files."""
    if _runtime is None:
        raise RuntimeError("no worker runtime in this process; start workers with 'pdr worker'")
    job = get_current_job()
    if job is not None:
        try:  # from now on the reconciler watches the report's heartbeat, not the flag
            _runtime.queue.started(report_id, job.id, key=_runtime.queue.report_flag_key(report_id))
        except redis.exceptions.RedisError:
            pass
    _runtime.reports.run(report_id)
    return "done"


def purge_namespace(connection: redis.Redis, namespace: str) -> int:
    """Delete every Redis key of a namespace (its queue, registries, jobs, flags, workers); returns how many.

    For tests and for decommissioning a deployment; never touches other namespaces' keys.
    """
    keys = {k for pattern in (f"{namespace}:*", f"rq:*{namespace}*") for k in connection.scan_iter(match=pattern)}
    for set_key in ("rq:queues", "rq:workers"):
        for member in connection.smembers(set_key):
            text = member.decode() if isinstance(member, bytes) else str(member)
            if namespace in text:
                connection.srem(set_key, member)
    if keys:
        connection.delete(*keys)
    return len(keys)
