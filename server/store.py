"""Persistence of sessions, devices, raw batches, processing state and results (SQLAlchemy Core).

Every write that acknowledges an upload commits before the HTTP answer, so an accepted batch survives a
crash. Raw payloads are zlib-compressed; their SHA-256 makes re-sent batches idempotent.

A processing pass writes through :meth:`Store.fenced`: each of its writes checks, in its own transaction, that the
session still exists at the results epoch the pass began with (:class:`SessionChanged` otherwise). So deleting a
session or clearing its results (:meth:`Store.clear_results`, which increments the epoch) never waits for a pass,
and a pass can neither write back a deleted session's results nor results computed before a clear.
"""

from __future__ import annotations

import copy
import hashlib
import json
import uuid
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, fields
from datetime import datetime
from typing import Any, Self

from sqlalchemy import ColumnElement, Connection, Engine, Row, case, delete, func, insert, null, select, update
from sqlalchemy.exc import IntegrityError

from pdr.phone.events import StepEvent
from pdr.phone.track_schema import TRACK_COLUMNS
from pdr.recording import FOOT_ROLES
from server import db
from server.errors import APIError
from server.foot_steps import FUSED, STAND_MODE

#: Status of a batch whose raw payload was deleted by the retention policy (its results stay).
PURGED = "purged"
#: zlib level of stored decoded recordings: float arrays barely compress further at higher levels (an IPIN log's
#: 2.0 MB decode to 1.01 MB at level 1 in 0.18 s, 0.96 MB at level 6 in 0.54 s).
DECODED_ZLIB_LEVEL = 1
#: Prefix of the device role under which a rebuild keeps the previous results until it ends (Store.clear_results).
PREVIOUS = "~"

SESSION_COLUMNS = ("id", "client_session_id", "source", "name", "placement", "status", "created_at", "updated_at",
                   "t0_ns", "origin_lat_deg", "origin_lon_deg")


def unpack_state(blob: bytes) -> bytes:
    """A stored processor state. States are stored as the processor wrote them: they are rewritten after every
    batch and hold float arrays that barely compress; rows of older versions were zlib-compressed (they start
    with the zlib header byte 0x78, which neither a JSON nor a :mod:`pdr.state_codec` state starts with).
    """
    return zlib.decompress(blob) if blob[:1] == b"\x78" else bytes(blob)


def content_digest(content: Any) -> str:
    """SHA-256 of decoded JSON content, independent of whitespace and key order."""
    canonical = json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True)
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class BatchRecord:
    """A stored raw batch, decompressed.

    ``decoded`` is what was decoded at ingest: the recording its reader returned (:mod:`pdr.recording_codec` bytes)
    or a shoe unit's step summaries (:mod:`pdr.foot.summaries_codec`); ``None`` for rows stored without one (older
    than migration 0007_decoded, or step summaries stored before they had a decoded form). ``payload`` is the raw
    payload as received, loaded only when there is no decoded form (what processing needs: read once).
    """

    id: int
    session_id: str
    device_role: str
    client_batch_id: str
    payload_format: str
    payload: bytes
    t_first_ns: int | None
    t_last_ns: int | None
    status: str
    decoded: bytes | None = None


@dataclass(frozen=True)
class TrackRow:
    """One step of a track, in the columns of ``pdr track`` (local metres, heading clockwise from north)."""

    t_s: float
    east_m: float
    north_m: float
    up_m: float
    floor: float | None
    heading_deg: float | None
    step_length_m: float | None
    mode: str | None


#: A stored step (a row of ``track_points``): a phone's typed step event, all its fields in columns, or the track row
#: of a foot or fused step. The store numbers each device role's steps 0, 1, ... (``step_index``).
StoredStep = StepEvent | TrackRow
#: The step event's fields stored beside the track's columns (null on foot and fused rows; migration 0009_typed_steps).
STEP_FIELDS = tuple(f.name for f in fields(StepEvent) if f.name not in TRACK_COLUMNS)
#: Of those, the vectors (stored as JSON arrays).
STEP_VECTORS = ("patterns", "up_time_s", "gyro_bias_dps")


def step_values(step: StoredStep) -> dict[str, Any]:
    """The column values of a stored step (the step event's vectors as JSON; a track row's step fields absent)."""
    if isinstance(step, TrackRow):
        return {c: getattr(step, c) for c in TRACK_COLUMNS}
    values = {name: getattr(step, name) for name in (*TRACK_COLUMNS, *STEP_FIELDS)}
    return values | {k: None if values[k] is None else json.dumps(values[k]) for k in STEP_VECTORS}


def step_fields(row: Any) -> dict[str, Any]:
    """The step event's fields of a stored ``track_points`` row that has them (non-null; vectors decoded): empty
    for foot and fused rows; a phone step stored before migration 0009_typed_steps has those the heading smoother
    needed.
    """
    out = {name: getattr(row, name) for name in STEP_FIELDS if getattr(row, name) is not None}
    return out | {k: json.loads(out[k]) for k in STEP_VECTORS if k in out}


@dataclass(frozen=True)
class EventRow:
    """A result event: ``kind`` is step (a foot step's increment), mode, landmark or floor; ``label``/``value`` per
    kind. ``step``: for a step event, the position of its step among the same output's track rows (the store
    gives the event that row's ``step_index``).
    """

    kind: str
    t_s: float
    t_end_s: float | None = None
    label: str | None = None
    value: float | None = None
    data: dict[str, Any] | None = None
    step: int | None = None


class SessionChanged(RuntimeError):
    """The session of a processing pass was deleted, or its results cleared, since the pass began
    (:meth:`Store.fenced`): what the pass computed is stale and was not written.
    """


class Store:
    """Repository over one database engine."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        #: (session id, results epoch) of a processing pass's store (:meth:`fenced`), None for every other.
        self.fence: tuple[str, int] | None = None

    def fenced(self, session_id: str, epoch: int) -> Self:
        """A view of this store for one processing pass over the session begun at results epoch ``epoch``
        (:meth:`results_epoch`): its writes (results, batch and session status, warnings, clearing and ending a
        rebuild) raise :class:`SessionChanged`, writing nothing, once the session is deleted or its epoch changed.

        The check is an ``UPDATE`` of the session's row at the start of the write's transaction, which holds the
        row's lock (PostgreSQL) or the database's write lock (SQLite) until the commit: a delete or a clear is
        ordered wholly before the write (which then fails) or wholly after it (which then deletes or clears it too).
        """
        view = copy.copy(self)
        view.fence = (session_id, epoch)
        return view

    def _check_fence(self, conn: Connection) -> None:
        """In a write's transaction of a :meth:`fenced` store: raise :class:`SessionChanged` unless its session is
        still at its epoch (and lock the session's row until the commit). Nothing for any other store.
        """
        if self.fence is None:
            return
        session_id, epoch = self.fence
        s = db.sessions
        res = conn.execute(update(s).where(s.c.id == session_id, s.c.results_epoch == epoch)
                           .values(results_epoch=epoch))
        if res.rowcount != 1:
            raise SessionChanged(f"session {session_id} was deleted or its results cleared during processing")

    def results_epoch(self, session_id: str) -> int | None:
        """How often the session's results were cleared (:meth:`clear_results`); None when there is no such session."""
        with self.engine.connect() as conn:
            epoch = conn.execute(select(db.sessions.c.results_epoch).where(db.sessions.c.id == session_id)).scalar()
        return None if epoch is None else int(epoch)

    # -- sessions --------------------------------------------------------------------------------
    def create_session(self, user_id: int, *, source: str, client_session_id: str | None = None, name: str = "",
                       placement: str | None = None, meta: dict[str, Any] | None = None) -> tuple[str, bool]:
        """Create (or find, by the client's id) a session; returns (id, created).

        The client's ``session_id`` is a key unique per user, whatever the source that created the session
        (a file upload, native batches, the Sensor Logger push): the same key finds the same session, also when two
        requests create it at once (the database's unique index ``uq_sessions_user_key`` refuses the second insert,
        which then finds the first).
        """
        client_id = client_session_id or uuid.uuid4().hex
        now = db.utcnow()
        with self.engine.begin() as conn:
            existing = conn.execute(select(db.sessions.c.id).where(
                db.sessions.c.user_id == user_id, db.sessions.c.client_session_id == client_id)
                .order_by(db.sessions.c.created_at)).first()
            if existing:
                return str(existing.id), False
            sid = str(uuid.uuid4())
            try:
                conn.execute(insert(db.sessions).values(
                    id=sid, user_id=user_id, client_session_id=client_id, source=source, name=name or client_id,
                    placement=placement, status="empty", created_at=now, updated_at=now, warnings="[]",
                    meta=json.dumps(meta or {})))
            except IntegrityError:  # the key stored meanwhile by another request, or the user deleted meanwhile
                conn.rollback()
                if self.session_by_key(user_id, client_id) is None and not self._user_exists(user_id):
                    raise APIError(401, "the account of this token was deleted while the request was served; "
                                        "nothing stored") from None
                return self.create_session(user_id, source=source, client_session_id=client_id, name=name,
                                           placement=placement, meta=meta)
        return sid, True

    def _user_exists(self, user_id: int) -> bool:
        with self.engine.connect() as conn:
            return conn.execute(select(db.users.c.id).where(db.users.c.id == user_id)).first() is not None

    def session_by_key(self, user_id: int, client_session_id: str) -> Row[Any] | None:
        """The user's session with that client ``session_id``."""
        with self.engine.connect() as conn:
            return conn.execute(select(db.sessions).where(
                db.sessions.c.user_id == user_id, db.sessions.c.client_session_id == client_session_id)
                .order_by(db.sessions.c.created_at)).first()

    def session_row(self, session_id: str, user_id: int | None = None) -> Row[Any]:
        """The session; 404 when absent or owned by another user (existence is not revealed)."""
        q = select(db.sessions).where(db.sessions.c.id == session_id)
        with self.engine.connect() as conn:
            row = conn.execute(q).first()
        if row is None or (user_id is not None and row.user_id != user_id):
            raise APIError(404, f"no session '{session_id[:64]}'")
        return row

    def delete_session(self, session_id: str) -> None:
        """Delete a session with its devices, raw batches, processor states, results, leases and attempt counts
        (``ON DELETE CASCADE`` in both back-ends); group agents that named it keep their data, unlinked.
        """
        with self.engine.begin() as conn:
            conn.execute(delete(db.sessions).where(db.sessions.c.id == session_id))

    def purge_raw_batches(self, older_than: datetime) -> int:
        """Drop the raw payloads of finished sessions (status ``done``) whose last batch arrived before
        ``older_than``; their results stay, the batches stay listed with status ``purged``. Returns how many.
        """
        b, s = db.batches, db.sessions
        last = (select(b.c.session_id).group_by(b.c.session_id)
                .having(func.max(b.c.received_at) < older_than))
        q = (update(b).where(b.c.status == "done", b.c.session_id.in_(last),
                             b.c.session_id.in_(select(s.c.id).where(s.c.status == "done")))
             .values(status=PURGED, payload=zlib.compress(b""), decoded=None,
                     error="raw data deleted by the retention policy"))
        with self.engine.begin() as conn:
            return int(conn.execute(q).rowcount or 0)

    def list_sessions(self, user_id: int) -> list[Row[Any]]:
        with self.engine.connect() as conn:
            return list(conn.execute(select(db.sessions).where(db.sessions.c.user_id == user_id)
                                     .order_by(db.sessions.c.created_at)))

    def set_session(self, session_id: str, **values: Any) -> None:
        values["updated_at"] = db.utcnow()
        with self.engine.begin() as conn:
            self._check_fence(conn)
            conn.execute(update(db.sessions).where(db.sessions.c.id == session_id).values(**values))

    def add_session_warnings(self, session_id: str, warnings: Iterable[str]) -> None:
        new = [w for w in warnings if w]
        if not new:
            return
        with self.engine.begin() as conn:
            self._check_fence(conn)
            row = conn.execute(select(db.sessions.c.warnings).where(db.sessions.c.id == session_id)).first()
            current = json.loads(row.warnings) if row else []
            merged = current + [w for w in new if w not in current]
            conn.execute(update(db.sessions).where(db.sessions.c.id == session_id).values(warnings=json.dumps(merged)))

    # -- devices ---------------------------------------------------------------------------------
    def upsert_device(self, session_id: str, role: str, *, device_id: str = "", platform: str = "unknown",
                      model: str = "", placement: str | None = None) -> None:
        """Register the session's device of ``role``, or update it. Two first batches of a session at once both find
        none: the second insert updates what the first inserted; a session deleted meanwhile is its 404.
        """
        dev = db.devices
        mine = (dev.c.session_id == session_id, dev.c.role == role)
        values = dict(device_id=device_id, platform=platform, model=model, placement=placement)
        with self.engine.begin() as conn:
            if conn.execute(select(dev.c.id).where(*mine)).first() is None:
                try:
                    with conn.begin_nested():
                        conn.execute(insert(dev).values(session_id=session_id, role=role, **values))
                    return
                except IntegrityError:  # inserted meanwhile by another request, or the session deleted meanwhile
                    self.session_row(session_id)
            conn.execute(update(dev).where(*mine).values(**values))

    def devices(self, session_id: str) -> list[Row[Any]]:
        with self.engine.connect() as conn:
            return list(conn.execute(select(db.devices).where(db.devices.c.session_id == session_id)
                                     .order_by(db.devices.c.role)))

    # -- batches ---------------------------------------------------------------------------------
    def add_batch(self, session_id: str, *, device_role: str, client_batch_id: str, payload_format: str,
                  payload: bytes, t_first_ns: int | None, t_last_ns: int | None,
                  content: Any = None, decoded: bytes | None = None) -> tuple[int, bool]:
        """Persist a raw batch; returns (id, created). A re-sent identical batch is a no-op; a different
        payload under the same client batch id is a 409 conflict.

        ``content`` is the decoded JSON of a JSON payload: then the batch is identified by its content
        (:func:`content_digest`), so a re-send that differs only in whitespace or key order is a replay.
        ``decoded``: what was decoded from the payload at ingest (:class:`BatchRecord`), which processing reads
        instead of decoding the payload again.
        """
        digest = hashlib.sha256(payload).hexdigest() if content is None else content_digest(content)
        q = select(db.batches.c.id, db.batches.c.payload_sha256).where(
            db.batches.c.session_id == session_id, db.batches.c.client_batch_id == client_batch_id)
        with self.engine.begin() as conn:
            found = conn.execute(q).first()
            if found is None:
                try:
                    with conn.begin_nested():
                        res = conn.execute(insert(db.batches).values(
                            session_id=session_id, device_role=device_role, client_batch_id=client_batch_id,
                            payload_format=payload_format, payload=zlib.compress(payload, 6), payload_sha256=digest,
                            decoded=None if decoded is None else zlib.compress(decoded, DECODED_ZLIB_LEVEL),
                            size_bytes=len(payload), t_first_ns=t_first_ns, t_last_ns=t_last_ns,
                            received_at=db.utcnow(), status="pending"))
                    conn.execute(update(db.sessions).where(db.sessions.c.id == session_id)
                                 .values(status="pending", updated_at=db.utcnow()))
                    key = res.inserted_primary_key
                    assert key is not None
                    return int(key[0]), True
                except IntegrityError:
                    found = conn.execute(q).first()
                    if found is None:  # no replay of this batch: the session's foreign key, the session deleted
                        self.session_row(session_id)   # meanwhile, whose 404 this is
                        raise
        if found.payload_sha256 not in (digest, hashlib.sha256(payload).hexdigest()):  # raw: stored before 0005
            raise APIError(409, f"batch '{client_batch_id}' was already received with different content",
                           details={"batch_id": client_batch_id})
        return int(found.id), False

    def batches(self, session_id: str, statuses: Sequence[str] | None = None,
                with_payload: bool = True) -> list[BatchRecord]:
        """Batches of a session in processing order (first sample time, then arrival); ``with_payload``: with what
        processing reads, the decoded form, or the raw payload of a batch that has none (:class:`BatchRecord`).
        """
        b = db.batches
        cols: list[ColumnElement[Any]] = [b.c.id, b.c.session_id, b.c.device_role, b.c.client_batch_id,
                                          b.c.payload_format, b.c.t_first_ns, b.c.t_last_ns, b.c.status]
        if with_payload:
            cols += [b.c.decoded, case((b.c.decoded.is_(None), b.c.payload), else_=null()).label("payload")]
        q = select(*cols).where(b.c.session_id == session_id)
        if statuses:
            q = q.where(b.c.status.in_(list(statuses)))
        q = q.order_by(b.c.t_first_ns, b.c.id)
        with self.engine.connect() as conn:
            rows = list(conn.execute(q))
        return [BatchRecord(int(r.id), r.session_id, r.device_role, r.client_batch_id, r.payload_format,
                            zlib.decompress(r.payload) if with_payload and r.payload is not None else b"",
                            r.t_first_ns, r.t_last_ns, r.status,
                            zlib.decompress(r.decoded) if with_payload and r.decoded is not None else None)
                for r in rows]

    def batch_summary(self, session_id: str) -> dict[str, int]:
        with self.engine.connect() as conn:
            rows = conn.execute(select(db.batches.c.status, func.count()).where(db.batches.c.session_id == session_id)
                                .group_by(db.batches.c.status))
            return {str(r[0]): int(r[1]) for r in rows}

    def first_sample_ns(self, session_id: str) -> int | None:
        """Time of the session's first stored sample on its log's clock (ns), None before any batch."""
        with self.engine.connect() as conn:
            t = conn.execute(select(func.min(db.batches.c.t_first_ns)).where(
                db.batches.c.session_id == session_id)).scalar()
            return None if t is None else int(t)

    def batch_roles(self, session_id: str) -> set[str]:
        """Device roles with at least one stored batch in the session."""
        with self.engine.connect() as conn:
            rows = conn.execute(select(db.batches.c.device_role).where(db.batches.c.session_id == session_id)
                                .distinct())
            return {str(r[0]) for r in rows}

    def batch_list(self, session_id: str) -> list[Row[Any]]:
        with self.engine.connect() as conn:
            return list(conn.execute(
                select(db.batches.c.id, db.batches.c.client_batch_id, db.batches.c.device_role,
                       db.batches.c.payload_format, db.batches.c.size_bytes, db.batches.c.t_first_ns,
                       db.batches.c.t_last_ns, db.batches.c.received_at, db.batches.c.status, db.batches.c.error)
                .where(db.batches.c.session_id == session_id).order_by(db.batches.c.t_first_ns, db.batches.c.id)))

    def set_batch_status(self, batch_id: int, status: str, error: str | None = None) -> None:
        with self.engine.begin() as conn:
            self._check_fence(conn)
            conn.execute(update(db.batches).where(db.batches.c.id == batch_id).values(
                status=status, error=error, processed_at=db.utcnow()))

    def sessions_with_pending(self) -> list[str]:
        with self.engine.connect() as conn:
            rows = conn.execute(select(db.batches.c.session_id).where(
                db.batches.c.status.in_(["pending", "processing"])).distinct())
            return [str(r[0]) for r in rows]

    # -- processing state and results ------------------------------------------------------------
    def load_state(self, session_id: str, role: str) -> tuple[bytes | None, int | None]:
        with self.engine.connect() as conn:
            row = conn.execute(select(db.processor_states.c.state, db.processor_states.c.last_t_ns).where(
                db.processor_states.c.session_id == session_id, db.processor_states.c.device_role == role)).first()
        if row is None:
            return None, None
        return unpack_state(row.state), row.last_t_ns

    def commit_results(self, session_id: str, role: str, batch_id: int | None, state: bytes, last_t_ns: int | None,
                       track: Sequence[StoredStep], events: Sequence[EventRow],
                       guard: Callable[[Connection], None] | None = None,
                       tail_track: Sequence[StoredStep] = (), tail_events: Sequence[EventRow] = ()) -> None:
        """Atomically store a processed batch's results, the processor state after it and its status.

        The role's provisional rows are replaced by ``tail_track``/``tail_events``: what the processor would
        still emit if the session ended now (e.g. the last step), flagged ``provisional``. The steps are numbered
        on from the role's last final step (``step_index``), the tail's after this batch's.

        ``batch_id`` is ``None`` for results derived from other roles' results (the fused foot track).

        ``guard(conn)`` runs first in the same transaction and may raise to abort the commit (a worker
        checking that it still holds the session's lease, :mod:`server.leases`).
        """
        now = db.utcnow()
        with self.engine.begin() as conn:
            self._check_fence(conn)
            if guard is not None:
                guard(conn)
            key = (db.processor_states.c.session_id == session_id) & (db.processor_states.c.device_role == role)
            values = dict(state=state, last_t_ns=last_t_ns, updated_at=now)
            if conn.execute(select(db.processor_states.c.session_id).where(key)).first():
                conn.execute(update(db.processor_states).where(key).values(**values))
            else:
                conn.execute(insert(db.processor_states).values(session_id=session_id, device_role=role, **values))
            for table in (db.track_points, db.events):
                conn.execute(delete(table).where(table.c.session_id == session_id, table.c.device_role == role,
                                                 table.c.provisional.is_(True)))
            tp = db.track_points
            last = conn.execute(select(func.max(tp.c.step_index)).where(
                tp.c.session_id == session_id, tp.c.device_role == role)).scalar()
            first = 0 if last is None else int(last) + 1
            for rows, evs, start, provisional in ((track, events, first, False),
                                                  (tail_track, tail_events, first + len(track), True)):
                if rows:
                    conn.execute(insert(tp), [
                        dict(session_id=session_id, device_role=role, provisional=provisional, step_index=start + i,
                             **step_values(r)) for i, r in enumerate(rows)])
                if evs:
                    conn.execute(insert(db.events), [
                        dict(session_id=session_id, device_role=role, kind=e.kind, t_s=e.t_s, t_end_s=e.t_end_s,
                             label=e.label, value=e.value, data=json.dumps(e.data or {}), provisional=provisional,
                             step_index=None if e.step is None else start + e.step) for e in evs])
            if batch_id is not None:
                conn.execute(update(db.batches).where(db.batches.c.id == batch_id).values(
                    status="done", error=None, processed_at=now))

    def clear_results(self, session_id: str) -> None:
        """Forget every processor state of a session and mark it and its batches pending (reprocess): a rebuild.
        Its results epoch is incremented first (which locks its row): a pass begun before writes nothing more.

        The results stay readable until the rebuild ends (:meth:`end_rebuild`): they move under the device role
        ``PREVIOUS + role``, which :meth:`track`, :meth:`events` and :meth:`track_summary` serve with
        ``previous=True``. A rebuild cleared again keeps the results from before the first one.
        """
        s = db.sessions
        with self.engine.begin() as conn:
            self._check_fence(conn)
            conn.execute(update(s).where(s.c.id == session_id).values(
                results_epoch=s.c.results_epoch + 1, status="pending", updated_at=db.utcnow()))
            kept = self._has_previous(conn, session_id)
            for table in (db.track_points, db.events):
                mine = (table.c.session_id == session_id) & ~table.c.device_role.startswith(PREVIOUS)
                if kept:
                    conn.execute(delete(table).where(mine))
                else:
                    conn.execute(update(table).where(mine).values(device_role=PREVIOUS + table.c.device_role))
            conn.execute(delete(db.processor_states).where(db.processor_states.c.session_id == session_id))
            conn.execute(delete(db.batch_attempts).where(db.batch_attempts.c.batch_id.in_(
                select(db.batches.c.id).where(db.batches.c.session_id == session_id))))
            conn.execute(update(db.batches).where(db.batches.c.session_id == session_id)
                         .values(status="pending", error=None, processed_at=None))

    @staticmethod
    def _has_previous(conn: Connection, session_id: str) -> bool:
        return any(conn.execute(select(table.c.id).where(
            table.c.session_id == session_id, table.c.device_role.startswith(PREVIOUS)).limit(1)).first()
            for table in (db.track_points, db.events))

    def rebuilding(self, session_id: str) -> bool:
        """Whether a rebuild of the session is running and its previous results are kept (:meth:`clear_results`)."""
        with self.engine.connect() as conn:
            return self._has_previous(conn, session_id)

    def end_rebuild(self, session_id: str) -> None:
        """Drop the results kept from before a rebuild (its own results are complete)."""
        with self.engine.begin() as conn:
            self._check_fence(conn)
            for table in (db.track_points, db.events):
                conn.execute(delete(table).where(table.c.session_id == session_id,
                                                 table.c.device_role.startswith(PREVIOUS)))

    @staticmethod
    def _role_columns(table: Any, previous: bool) -> tuple[list[Any], Any]:
        """The table's columns with ``device_role`` as clients see it, and the condition on the role's prefix."""
        role = table.c.device_role
        if not previous:
            return list(table.c), ~role.startswith(PREVIOUS)
        shown = func.substr(role, len(PREVIOUS) + 1).label("device_role")
        return [shown if c.name == "device_role" else c for c in table.c], role.startswith(PREVIOUS)

    @staticmethod
    def _newer(q: Any, table: Any, since_s: float | None, after_id: int | None) -> Any:
        """``q`` restricted to the rows of ``table`` with ``t_s`` after ``since_s`` and stored after the row whose
        ``id`` is ``after_id`` (each bound only when given).
        """
        if since_s is not None:
            q = q.where(table.c.t_s > since_s)
        if after_id is not None:
            q = q.where(table.c.id > after_id)
        return q

    def track(self, session_id: str, role: str | None = None, since_s: float | None = None,
              previous: bool = False, after_id: int | None = None) -> list[Row[Any]]:
        """The track rows (of ``role``; after ``since_s``; stored after the row whose ``id`` is ``after_id``);
        ``previous``: those kept during a rebuild.
        """
        columns, kept = self._role_columns(db.track_points, previous)
        q = select(*columns).where(db.track_points.c.session_id == session_id, kept)
        if role:
            q = q.where(db.track_points.c.device_role == (PREVIOUS + role if previous else role))
        q = self._newer(q, db.track_points, since_s, after_id)
        with self.engine.connect() as conn:
            return list(conn.execute(q.order_by(db.track_points.c.device_role, db.track_points.c.t_s,
                                                db.track_points.c.id)))

    def steps(self, session_id: str, since_s: float | None = None, previous: bool = False,
              after_id: int | None = None) -> list[Row[Any]]:
        """The stored steps of every device role (after ``since_s``; stored after the track row whose ``id`` is
        ``after_id``) in time order: each track row with the ``data`` of its step event (a foot step's increment;
        null for phone and fused steps), joined by step index; ``previous``: those kept during a rebuild.
        """
        tp, ev = db.track_points, db.events
        columns, kept = self._role_columns(tp, previous)
        joined = tp.outerjoin(ev, (ev.c.session_id == tp.c.session_id) & (ev.c.device_role == tp.c.device_role)
                              & (ev.c.kind == "step") & (ev.c.step_index == tp.c.step_index))
        q = self._newer(select(*columns, ev.c.data).select_from(joined).where(tp.c.session_id == session_id, kept),
                        tp, since_s, after_id)
        with self.engine.connect() as conn:
            return list(conn.execute(q.order_by(tp.c.t_s, tp.c.id)))

    def track_summary(self, session_id: str, previous: bool = False) -> dict[str, dict[str, float]]:
        """Per device role: steps (rows but a foot's resets while it stands and their fused updates, mode
        :data:`server.foot_steps.STAND_MODE`),
        distance (sum of step lengths, m) and first/last row time (s), by SQL; ``previous``: of the results kept
        during a rebuild.
        """
        tp = db.track_points
        kept = tp.c.device_role.startswith(PREVIOUS)
        feet = [*FOOT_ROLES, FUSED, *(PREVIOUS + r for r in (*FOOT_ROLES, FUSED))]
        stand = (tp.c.mode == STAND_MODE) & tp.c.device_role.in_(feet)
        steps = func.coalesce(func.sum(case((stand, 0), else_=1)), 0)
        q = (select(tp.c.device_role, steps, func.coalesce(func.sum(tp.c.step_length_m), 0.0),
                    func.min(tp.c.t_s), func.max(tp.c.t_s))
             .where(tp.c.session_id == session_id, kept if previous else ~kept).group_by(tp.c.device_role))
        with self.engine.connect() as conn:
            return {str(r[0]).removeprefix(PREVIOUS): {"steps": int(r[1]), "distance_m": float(r[2]),
                                                       "first_t_s": float(r[3]), "last_t_s": float(r[4])}
                    for r in conn.execute(q)}

    def events(self, session_id: str, kind: str, since_s: float | None = None,
               previous: bool = False, after_id: int | None = None) -> list[Row[Any]]:
        """The events of ``kind`` (with ``t_s`` after ``since_s``; stored after the event whose ``id`` is
        ``after_id``) in time order; ``previous``: those kept during a rebuild.
        """
        columns, kept = self._role_columns(db.events, previous)
        q = select(*columns).where(db.events.c.session_id == session_id, db.events.c.kind == kind, kept)
        q = self._newer(q, db.events, since_s, after_id)
        with self.engine.connect() as conn:
            return list(conn.execute(q.order_by(db.events.c.t_s, db.events.c.id)))
