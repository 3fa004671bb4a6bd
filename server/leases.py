"""Session leases in the database: at most one worker processes a session at a time, across machines.

A worker *claims* a session by writing a row ``(session_id, owner, expires_at)`` in ``session_leases``;
the claim succeeds when there is no row, the row's lease has expired (its owner died or stalled), or the
worker already owns it. While it processes, a keep-alive thread extends the lease every third of its
time-to-live, and every commit of results re-checks ownership *in the same transaction*
(:meth:`Leases.check`, a fencing check): a worker that lost its lease (it stalled longer than the TTL
and another worker took over) cannot write results any more. The claim lives in the database, not in
Redis, so ordering stays correct if Redis loses its data or restarts; it is plain SQL (an ``UPDATE ...
WHERE`` and an ``INSERT`` under the primary key), so the same code runs on PostgreSQL and SQLite.

Dead letters: a batch found in status ``processing`` when its session is claimed was interrupted (the
worker crashed, was killed, or hit a transient database or Redis error). Each interruption counts as an
attempt in ``batch_attempts``; after ``max_attempts`` the batch is set to status ``dead`` with the last
error instead of being retried again, so one poisonous batch cannot stall its session or kill workers
forever. ``POST /api/v1/sessions/{id}/reprocess`` clears the counts and retries everything.

Clocks: expiry times are written by the workers' clocks (UTC); machines must be NTP-synchronised to far
better than the TTL (30 s by default).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import timedelta

from sqlalchemy import Connection, Engine, delete, insert, or_, select, update
from sqlalchemy.exc import IntegrityError

from server import db

log = logging.getLogger(__name__)

#: Status of a batch whose processing was interrupted too often (dead letter).
DEAD = "dead"


class LeaseLost(RuntimeError):
    """The worker no longer holds the session's lease: another worker took over; stop quietly."""


class Leases:
    """Claims, renews and releases session leases for one worker (``owner``).

    Parameters
    ----------
    engine
        The service database.
    owner
        Unique name of this worker process (host, pid, random suffix).
    ttl_s
        Lease time-to-live, s: how long a crashed worker blocks its session before another takes over.
    max_attempts
        Interrupted processing attempts of one batch before it becomes a dead letter.
    """

    def __init__(self, engine: Engine, owner: str, ttl_s: float = 30.0, max_attempts: int = 5) -> None:
        if ttl_s <= 0 or max_attempts < 1:
            raise ValueError("lease ttl_s must be > 0 and max_attempts >= 1")
        self.engine = engine
        self.owner = owner
        self.ttl = timedelta(seconds=ttl_s)
        self.max_attempts = max_attempts

    # -- the lease ---------------------------------------------------------------------------------
    def claim(self, session_id: str) -> bool:
        """Take the session's lease if it is free, expired or already ours; True if we hold it now."""
        now = db.utcnow()
        t = db.session_leases
        with self.engine.begin() as conn:
            taken = conn.execute(update(t).where(t.c.session_id == session_id,
                                                 or_(t.c.expires_at < now, t.c.owner == self.owner))
                                 .values(owner=self.owner, expires_at=now + self.ttl))
            if taken.rowcount == 1:
                return True
            try:
                with conn.begin_nested():
                    conn.execute(insert(t).values(session_id=session_id, owner=self.owner, expires_at=now + self.ttl))
            except IntegrityError:  # held by a live worker (or the session is gone)
                return False
        return True

    def check(self, session_id: str, conn: Connection) -> None:
        """Fencing check inside a commit's transaction: extend our lease or raise :class:`LeaseLost`.

        The ``UPDATE`` locks the lease row until the commit, so no other worker can take the lease
        between this check and the results being written.
        """
        t = db.session_leases
        res = conn.execute(update(t).where(t.c.session_id == session_id, t.c.owner == self.owner)
                           .values(expires_at=db.utcnow() + self.ttl))
        if res.rowcount != 1:
            raise LeaseLost(f"lease of session {session_id} lost by {self.owner}")

    def renew(self, session_id: str) -> bool:
        """Extend our lease; False if another worker holds it now."""
        with self.engine.begin() as conn:
            try:
                self.check(session_id, conn)
            except LeaseLost:
                return False
        return True

    def release(self, session_id: str) -> None:
        """Give the lease up (only ours)."""
        t = db.session_leases
        with self.engine.begin() as conn:
            conn.execute(delete(t).where(t.c.session_id == session_id, t.c.owner == self.owner))

    @contextmanager
    def kept_alive(self, session_id: str) -> Iterator[None]:
        """Renew the lease every third of the TTL on a background thread while the block runs."""
        stop = threading.Event()
        period = self.ttl.total_seconds() / 3.0

        def keep() -> None:
            while not stop.wait(period):
                try:
                    if not self.renew(session_id):
                        log.warning("lease of session %s was taken over; results will not be committed",
                                    session_id)
                        return
                except Exception as exc:  # database unreachable: the commit's fencing check decides
                    log.warning("could not renew the lease of session %s: %s", session_id, exc)

        thread = threading.Thread(target=keep, name=f"lease-{session_id[:8]}", daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join(timeout=5)

    # -- interrupted batches and dead letters -------------------------------------------------------
    def recover_interrupted(self, session_id: str) -> list[int]:
        """Count an attempt for every batch left ``processing``; back to ``pending``, or ``dead`` after
        ``max_attempts``. Call while holding the lease. Returns the ids of batches declared dead.
        """
        b, a = db.batches, db.batch_attempts
        dead: list[int] = []
        now = db.utcnow()
        with self.engine.begin() as conn:
            rows = list(conn.execute(
                select(b.c.id, a.c.attempts, a.c.last_error).select_from(b.outerjoin(a, a.c.batch_id == b.c.id))
                .where(b.c.session_id == session_id, b.c.status == "processing")))
            for row in rows:
                attempts = int(row.attempts or 0) + 1
                if row.attempts is None:
                    conn.execute(insert(a).values(batch_id=row.id, attempts=attempts, updated_at=now,
                                                  last_error="processing was interrupted"))
                else:
                    conn.execute(update(a).where(a.c.batch_id == row.id).values(attempts=attempts, updated_at=now))
                if attempts >= self.max_attempts:
                    last = row.last_error or "processing was interrupted (worker crash or lost connection)"
                    conn.execute(update(b).where(b.c.id == row.id).values(
                        status=DEAD, processed_at=now,
                        error=f"dead letter: processing was interrupted {attempts} times; last error: {last}"))
                    dead.append(int(row.id))
                else:
                    conn.execute(update(b).where(b.c.id == row.id).values(status="pending"))
        for batch_id in dead:
            log.error("batch %s of session %s is a dead letter after %d attempts", batch_id, session_id,
                      self.max_attempts)
        return dead

    def note_error(self, session_id: str, error: str) -> None:
        """Remember ``error`` as the last error of the session's batches in ``processing`` (best effort)."""
        b, a = db.batches, db.batch_attempts
        now = db.utcnow()
        with self.engine.begin() as conn:
            ids = [int(r.id) for r in conn.execute(select(b.c.id).where(b.c.session_id == session_id,
                                                                         b.c.status == "processing"))]
            for batch_id in ids:
                res = conn.execute(update(a).where(a.c.batch_id == batch_id).values(last_error=error[:2000],
                                                                                    updated_at=now))
                if res.rowcount == 0:
                    conn.execute(insert(a).values(batch_id=batch_id, attempts=0, last_error=error[:2000],
                                                  updated_at=now))

    def orphaned_sessions(self, limit: int = 1000) -> list[str]:
        """Sessions with pending or interrupted batches and no live lease: work nobody is doing."""
        b, t = db.batches, db.session_leases
        q = (select(b.c.session_id).select_from(b.outerjoin(t, t.c.session_id == b.c.session_id))
             .where(b.c.status.in_(["pending", "processing"]),
                    or_(t.c.session_id.is_(None), t.c.expires_at < db.utcnow()))
             .group_by(b.c.session_id).limit(limit))
        with self.engine.connect() as conn:
            return [str(r[0]) for r in conn.execute(q)]
