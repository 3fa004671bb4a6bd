"""Job execution: the embedded default runs processing on a background thread of the web process.

``InProcessWorker.submit(session_id)`` queues a session; the thread waits ``settle_s`` so that a burst of
uploads (and messages arriving slightly out of order) is processed together, then processes the session's
pending batches. At start-up, batches left pending or interrupted by a crash are queued again; each
interruption counts as an attempt of the batch, and a batch interrupted ``max_attempts`` times (one that
crashes the process every time it is processed) becomes a dead letter, as on the Redis path
(:meth:`server.leases.Leases.recover_interrupted`).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from datetime import timedelta

from server import db
from server.processing import SessionProcessing
from server.store import Store

log = logging.getLogger(__name__)


class InProcessWorker:
    """A daemon thread processing queued sessions one after another."""

    def __init__(self, processing: SessionProcessing, settle_s: float = 0.2, max_attempts: int = 5) -> None:
        self.processing = processing
        self.settle_s = settle_s
        self.max_attempts = max_attempts
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._queued: set[str] = set()
        self._guard = threading.Lock()
        self._thread: threading.Thread | None = None
        self._idle = threading.Event()
        self._idle.set()

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="pdr-worker", daemon=True)
            self._thread.start()

    def recover(self) -> None:
        """Requeue sessions with batches left pending or interrupted by a previous crash (counting the attempt,
        dead-lettering a batch interrupted ``max_attempts`` times).
        """
        from server.leases import Leases

        store = self.processing.store
        leases = Leases(store.engine, owner="embedded", max_attempts=self.max_attempts)
        for session_id in store.sessions_with_pending():
            dead = leases.recover_interrupted(session_id)
            if dead:
                self.processing.finish(session_id)
            self.submit(session_id)

    def submit(self, session_id: str) -> None:
        with self._guard:
            if session_id in self._queued:
                return
            self._queued.add(session_id)
            self._idle.clear()
        self._queue.put(session_id)

    def wait_idle(self, timeout_s: float = 60.0) -> bool:
        """Block until every queued session is processed (tests, benchmarks)."""
        return self._idle.wait(timeout_s)

    def stop(self) -> None:
        self._queue.put(None)
        if self._thread is not None:
            self._thread.join(timeout=10)
            self._thread = None

    def _run(self) -> None:
        while True:
            session_id = self._queue.get()
            if session_id is None:
                return
            if self.settle_s > 0:
                time.sleep(self.settle_s)
            with self._guard:
                self._queued.discard(session_id)
            try:
                self.processing.process_session(session_id)
            except Exception:  # keep the worker alive; the batch status says what failed
                log.exception("processing session %s failed", session_id)
            with self._guard:
                if not self._queued and self._queue.empty():
                    self._idle.set()


class NoWorker:
    """External workers process the queue (``PDR_WORKER=none``); the web process only stores batches."""

    def start(self) -> None:
        """Nothing to start."""

    def recover(self) -> None:
        """External workers recover on their own."""

    def submit(self, session_id: str) -> None:
        """Batches stay pending in the database until a worker takes them."""

    def wait_idle(self, timeout_s: float = 60.0) -> bool:
        return True

    def stop(self) -> None:
        """Nothing to stop."""


class RetentionSweeper:
    """``PDR_RETENTION_DAYS``: every ``period_s``, the raw batches of sessions finished more than ``days`` days ago
    lose their payload (:meth:`server.store.Store.purge_raw_batches`); results stay. A daemon thread.
    """

    def __init__(self, store: Store, days: float, period_s: float = 3600.0) -> None:
        if days <= 0:
            raise ValueError(f"PDR_RETENTION_DAYS must be > 0 to sweep, got {days}")
        self.store = store
        self.days = days
        self.period_s = period_s
        self._stop = threading.Event()

    def sweep(self) -> int:
        """Purge now; returns how many batches lost their raw payload."""
        n = self.store.purge_raw_batches(db.utcnow() - timedelta(days=self.days))
        if n:
            log.info("retention: deleted the raw data of %d batches older than %g days", n, self.days)
        return n

    def start(self) -> None:
        threading.Thread(target=self._run, name="pdr-retention", daemon=True).start()

    def stop(self) -> None:
        self._stop.set()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.sweep()
            except Exception:  # a failed sweep is retried next period; it must not end the thread
                log.exception("retention sweep failed")
            self._stop.wait(self.period_s)
