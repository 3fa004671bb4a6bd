"""Storage of cooperative-localization groups: tables (migration ``0002_groups``) and their repository.

A group's fusion state (:class:`pdr.fusion.group.Group`, JSON, zlib-compressed) lives in one row with a version
counter: an update reads the state, applies the upload and writes it back only if nobody else wrote in between
(optimistic concurrency, portable across SQLite and PostgreSQL), otherwise it retries. Raw uploads are stored
before they are applied (idempotent by the client's ``batch_id``), and fused reset poses are appended to
``group_track_points`` so that the state itself stays the size of the group, not of its history.
"""

from __future__ import annotations

import json
import math
import uuid
import zlib
from collections.abc import Callable, Sequence
from typing import Any

from sqlalchemy import (
    Column,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    String,
    Table,
    UniqueConstraint,
    delete,
    insert,
    select,
    update,
)
from sqlalchemy.engine import Engine, Row
from sqlalchemy.exc import IntegrityError

from pdr.fusion.group import Group
from server import db
from server.errors import APIError

groups = Table(
    "groups", db.metadata,
    Column("id", String(36), primary_key=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("name", String(200), nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("updated_at", DateTime(timezone=True), nullable=False),
    Column("version", Integer, nullable=False),
    Column("state", LargeBinary, nullable=False),
)

group_agents = Table(
    "group_agents", db.metadata,
    Column("group_id", String(36), ForeignKey("groups.id", ondelete="CASCADE"), primary_key=True),
    Column("agent", String(200), primary_key=True),
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="SET NULL")),
    Column("joined_at", DateTime(timezone=True), nullable=False),
    # group time = session time + clock_offset_s (s) for an agent fed from a session (migration 0010)
    Column("clock_offset_s", Float, nullable=False, server_default="0"),
)

group_uploads = Table(
    "group_uploads", db.metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("group_id", String(36), ForeignKey("groups.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("agent", String(200), nullable=False),
    Column("client_batch_id", String(200), nullable=False),
    Column("payload", LargeBinary, nullable=False),
    Column("received_at", DateTime(timezone=True), nullable=False),
    UniqueConstraint("group_id", "client_batch_id", name="uq_group_uploads_client"),
)

group_track_points = Table(
    "group_track_points", db.metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("group_id", String(36), ForeignKey("groups.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("agent", String(200), nullable=False),
    Column("foot", String(40), nullable=False),
    Column("t_s", Float, nullable=False),
    Column("east_m", Float, nullable=False),
    Column("north_m", Float, nullable=False),
    Column("up_m", Float, nullable=False),
    Column("heading_deg", Float, nullable=False),
)

#: Attempts of an optimistic update before answering 409.
MAX_ATTEMPTS = 8


def encode_state(group: Group) -> bytes:
    return zlib.compress(json.dumps(group.to_dict(), separators=(",", ":")).encode(), 6)


def decode_state(blob: bytes) -> Group:
    return Group.from_dict(json.loads(zlib.decompress(blob)))


def _drain_tracks(group: Group) -> list[tuple[str, str, list[float]]]:
    """The fused poses (agent, foot, [t, x, y, z, chi]) added since the last save; the state keeps none."""
    rows = []
    for key, poses in group.tracks.items():
        agent, foot = key.rsplit("/", 1)
        rows += [(agent, foot, p) for p in poses]
        group.tracks[key] = []
    return rows


class GroupStore:
    """Repository of groups over the service's database engine."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def create(self, user_id: int, name: str, group: Group) -> str:
        gid = str(uuid.uuid4())
        now = db.utcnow()
        with self.engine.begin() as conn:
            conn.execute(insert(groups).values(id=gid, user_id=user_id, name=name, created_at=now, updated_at=now,
                                               version=0, state=encode_state(group)))
        return gid

    def row(self, group_id: str, user_id: int) -> Row[Any]:
        """The group; 404 when absent or owned by another user (existence is not revealed)."""
        with self.engine.connect() as conn:
            row = conn.execute(select(groups).where(groups.c.id == group_id)).first()
        if row is None or row.user_id != user_id:
            raise APIError(404, f"no group '{group_id[:64]}'")
        return row

    def delete(self, group_id: str, user_id: int) -> None:
        """Delete the user's group; its members, uploads and track points go with it (their foreign keys cascade, as
        when its user is deleted). 404 as :meth:`row`; a request on it under way meanwhile finds it gone (404).
        """
        self.row(group_id, user_id)
        with self.engine.begin() as conn:
            conn.execute(delete(groups).where(groups.c.id == group_id))

    def list_for(self, user_id: int) -> list[Row[Any]]:
        with self.engine.connect() as conn:
            return list(conn.execute(select(groups).where(groups.c.user_id == user_id).order_by(groups.c.created_at)))

    def agents(self, group_id: str) -> list[Row[Any]]:
        with self.engine.connect() as conn:
            return list(conn.execute(select(group_agents).where(group_agents.c.group_id == group_id)
                                     .order_by(group_agents.c.joined_at)))

    def modify(self, group_id: str, change: Callable[[Group], Any]) -> Any:
        """Apply ``change`` to the group's state and store it (optimistic retry); returns what it returned."""
        for _ in range(MAX_ATTEMPTS):
            with self.engine.connect() as conn:
                row = conn.execute(select(groups.c.version, groups.c.state).where(groups.c.id == group_id)).first()
            if row is None:
                raise APIError(404, f"no group '{group_id[:64]}'")
            group = decode_state(row.state)
            result = change(group)
            tracks = _drain_tracks(group)
            with self.engine.begin() as conn:
                done = conn.execute(update(groups).where(groups.c.id == group_id, groups.c.version == row.version)
                                    .values(state=encode_state(group), version=row.version + 1,
                                            updated_at=db.utcnow())).rowcount
                if done != 1:
                    continue
                if tracks:
                    conn.execute(insert(group_track_points), [
                        {"group_id": group_id, "agent": a, "foot": f, "t_s": p[0], "east_m": p[1], "north_m": p[2],
                         "up_m": p[3], "heading_deg": (90.0 - math.degrees(p[4])) % 360.0} for a, f, p in tracks])
            return result
        raise APIError(409, "the group is being updated concurrently; retry the request")

    def state(self, group_id: str) -> Group:
        with self.engine.connect() as conn:
            row = conn.execute(select(groups.c.state).where(groups.c.id == group_id)).first()
        if row is None:
            raise APIError(404, f"no group '{group_id[:64]}'")
        return decode_state(row.state)

    def add_agent(self, group_id: str, agent: str, session_id: str | None, clock_offset_s: float = 0.0) -> None:
        """Record a member; ``clock_offset_s``: group time less session time (s) of an agent fed from a session.
        404 when the group was deleted meanwhile (its foreign key refuses the row).
        """
        try:
            with self.engine.begin() as conn:
                conn.execute(insert(group_agents).values(group_id=group_id, agent=agent, session_id=session_id,
                                                         joined_at=db.utcnow(), clock_offset_s=clock_offset_s))
        except IntegrityError:
            self.state(group_id)
            raise

    def followers(self, session_id: str) -> list[Row[Any]]:
        """The group agents that take their steps from the session (``group_id``, ``agent``, ``clock_offset_s``)."""
        with self.engine.connect() as conn:
            return list(conn.execute(select(group_agents.c.group_id, group_agents.c.agent,
                                            group_agents.c.clock_offset_s)
                                     .where(group_agents.c.session_id == session_id)
                                     .order_by(group_agents.c.group_id, group_agents.c.agent)))

    def remove_upload(self, upload_id: int) -> None:
        """Forget a stored upload that was refused (its ``batch_id`` may be sent again)."""
        with self.engine.begin() as conn:
            conn.execute(delete(group_uploads).where(group_uploads.c.id == upload_id))

    def add_upload(self, group_id: str, agent: str, batch_id: str, payload: bytes) -> tuple[int, bool]:
        """Store a raw upload; returns (id, created) — a repeated ``batch_id`` is not stored again."""
        with self.engine.begin() as conn:
            existing = conn.execute(select(group_uploads.c.id).where(
                group_uploads.c.group_id == group_id, group_uploads.c.client_batch_id == batch_id)).first()
            if existing:
                return int(existing.id), False
            try:
                res = conn.execute(insert(group_uploads).values(group_id=group_id, agent=agent,
                                                                client_batch_id=batch_id, payload=payload,
                                                                received_at=db.utcnow()))
            except IntegrityError:
                # The same batch stored meanwhile (taken as a repeat), or the group deleted meanwhile (404).
                conn.rollback()
                self.state(group_id)
                return self.add_upload(group_id, agent, batch_id, payload)
        key = res.inserted_primary_key
        return int(key[0]) if key else 0, True

    def track(self, group_id: str, agents: Sequence[str] | None = None, since_s: float | None = None) -> list[Row[Any]]:
        q = select(group_track_points).where(group_track_points.c.group_id == group_id)
        if agents:
            q = q.where(group_track_points.c.agent.in_(list(agents)))
        if since_s is not None:
            q = q.where(group_track_points.c.t_s > since_s)
        with self.engine.connect() as conn:
            return list(conn.execute(q.order_by(group_track_points.c.t_s, group_track_points.c.id)))
