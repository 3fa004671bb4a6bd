"""Database schema (SQLAlchemy Core) and engine creation: SQLite by default (WAL), PostgreSQL by URL.

The schema is created and upgraded by the Alembic migrations in ``server/migrations``; these table
objects are what the code queries. A change here needs a new migration revision.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    BigInteger,
    Boolean,
    Column,
    DateTime,
    Engine,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    Text,
    UniqueConstraint,
    create_engine,
    event,
    false,
)

metadata = MetaData()


def utcnow() -> datetime:
    return datetime.now(UTC)


users = Table(
    "users", metadata,
    Column("id", Integer, primary_key=True),
    Column("name", String(100), nullable=False, unique=True),
    Column("created_at", DateTime(timezone=True), nullable=False),
)

api_tokens = Table(
    "api_tokens", metadata,
    Column("id", Integer, primary_key=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("token_hash", String(64), nullable=False, unique=True),
    Column("prefix", String(16), nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("revoked_at", DateTime(timezone=True)),
    # Migration 0005: what the token may do (server.auth.SCOPES), when it stops working, when it was last used.
    Column("scope", String(8), nullable=False, server_default="full"),
    Column("expires_at", DateTime(timezone=True)),
    Column("last_used_at", DateTime(timezone=True)),
)

sessions = Table(
    "sessions", metadata,
    Column("id", String(36), primary_key=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("client_session_id", String(200), nullable=False),
    Column("source", String(32), nullable=False),
    Column("name", String(200), nullable=False, default=""),
    Column("placement", String(40)),
    Column("status", String(16), nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("updated_at", DateTime(timezone=True), nullable=False),
    Column("t0_ns", BigInteger),
    Column("origin_lat_deg", Float),
    Column("origin_lon_deg", Float),
    Column("warnings", Text, nullable=False, default="[]"),
    Column("meta", Text, nullable=False, default="{}"),
    # Migration 0013_results_epoch: incremented by every clear of the session's results (reprocess, new processing
    # options, a late batch's rebuild); a processing pass writes only while it is unchanged (server.store.Store.fenced).
    Column("results_epoch", Integer, nullable=False, server_default="0"),
    # Implied by uq_sessions_user_key (migration 0014), which SQLite could not put in its place without a table copy.
    UniqueConstraint("user_id", "source", "client_session_id", name="uq_sessions_client"),
)
# Migration 0014_one_session_per_key: a client's session_id names one session of the user, whatever the source.
Index("uq_sessions_user_key", sessions.c.user_id, sessions.c.client_session_id, unique=True)

devices = Table(
    "devices", metadata,
    Column("id", Integer, primary_key=True),
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("role", String(16), nullable=False),
    Column("device_id", String(200), nullable=False, default=""),
    Column("platform", String(16), nullable=False, default="unknown"),
    Column("model", String(200), nullable=False, default=""),
    Column("placement", String(40)),
    UniqueConstraint("session_id", "role", name="uq_devices_role"),
)

batches = Table(
    "batches", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("device_role", String(16), nullable=False),
    Column("client_batch_id", String(200), nullable=False),
    Column("payload_format", String(200), nullable=False),  # file:FORMAT/FILENAME; 0012_payload_format_length
    Column("payload", LargeBinary, nullable=False),
    Column("payload_sha256", String(64), nullable=False),
    Column("size_bytes", Integer, nullable=False),
    Column("t_first_ns", BigInteger),
    Column("t_last_ns", BigInteger),
    Column("received_at", DateTime(timezone=True), nullable=False),
    Column("status", String(16), nullable=False),
    Column("error", Text),
    Column("processed_at", DateTime(timezone=True)),
    # Migration 0007_decoded: the payload as its reader decoded it at ingest (pdr.recording_codec, zlib), read by
    # processing instead of the raw payload; NULL for rows stored before it and for step summaries.
    Column("decoded", LargeBinary),
    UniqueConstraint("session_id", "client_batch_id", name="uq_batches_client"),
)

processor_states = Table(
    "processor_states", metadata,
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), primary_key=True),
    Column("device_role", String(16), primary_key=True),
    Column("state", LargeBinary, nullable=False),
    Column("last_t_ns", BigInteger),
    Column("updated_at", DateTime(timezone=True), nullable=False),
)

track_points = Table(
    "track_points", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("device_role", String(16), nullable=False),
    Column("t_s", Float, nullable=False),
    Column("east_m", Float, nullable=False),
    Column("north_m", Float, nullable=False),
    Column("up_m", Float, nullable=False),
    Column("floor", Float),
    Column("heading_deg", Float),
    Column("step_length_m", Float),
    Column("mode", String(40)),
    # Rows of the processor's provisional tail (what ending the session now would add); replaced by the next batch.
    Column("provisional", Boolean, nullable=False, server_default=false()),
    # Migration 0009_typed_steps: the step's number in its device role (0, 1, ...) and the rest of a phone's step
    # (pdr.phone.events.StepEvent; null on foot and fused rows; vectors as JSON arrays; server.store.step_values).
    Column("step_index", Integer),
    Column("t_start_s", Float),
    Column("turn_deg", Float),
    Column("placement", String(16)),
    Column("heading_sigma_deg", Float),
    Column("pos_sigma_m", Float),
    Column("patterns", Text),
    Column("heading_raw_deg", Float),
    Column("gyro_heading_deg", Float),
    Column("up_time_s", Text),
    Column("gyro_bias_dps", Text),
    Column("position_fix", Boolean),
    Column("landmark_heading", Boolean),
    Column("pocket_side", Float),               # migration 0011_pocket_side
    Index("ix_track_points_step", "session_id", "device_role", "step_index"),
)

events = Table(
    "events", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("device_role", String(16), nullable=False),
    Column("kind", String(16), nullable=False),
    Column("t_s", Float, nullable=False),
    Column("t_end_s", Float),
    Column("label", String(60)),
    Column("value", Float),
    Column("data", Text, nullable=False, default="{}"),
    Column("provisional", Boolean, nullable=False, server_default=false()),
    # Migration 0009_typed_steps: a step event's track row (a foot step's increment, joined to its row by this index).
    Column("step_index", Integer),
)

reports = Table(
    "reports", metadata,
    Column("id", String(36), primary_key=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("kind", String(16), nullable=False),
    Column("status", String(16), nullable=False),
    Column("source_name", String(300), nullable=False, default=""),
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("result", Text),
    Column("error", Text),
    # Migration 0006: a report is a recoverable job (server.report_jobs).
    Column("attempts", Integer, nullable=False, server_default="0"),
    Column("started_at", DateTime(timezone=True)),
)

report_uploads = Table(
    "report_uploads", metadata,
    Column("report_id", String(36), ForeignKey("reports.id", ondelete="CASCADE"), primary_key=True),
    Column("descriptor", String(300), nullable=False),
    Column("payload", LargeBinary, nullable=False),  # zlib-compressed upload, deleted once the report is done
    Column("decoded", LargeBinary),  # migration 0007_decoded: the upload's recording as read at ingest, zlib
)

report_files = Table(
    "report_files", metadata,
    Column("report_id", String(36), ForeignKey("reports.id", ondelete="CASCADE"), primary_key=True),
    Column("name", String(100), primary_key=True),
    Column("media_type", String(60), nullable=False),
    Column("content", LargeBinary, nullable=False),
)

# Scale-out (migration 0003): which worker processes a session now (a lease with expiry, see
# server/leases.py), and how often a batch's processing was interrupted (dead-letter after too many).
session_leases = Table(
    "session_leases", metadata,
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), primary_key=True),
    Column("owner", String(120), nullable=False),
    Column("expires_at", DateTime(timezone=True), nullable=False),
)

batch_attempts = Table(
    "batch_attempts", metadata,
    Column("batch_id", Integer, ForeignKey("batches.id", ondelete="CASCADE"), primary_key=True),
    Column("attempts", Integer, nullable=False),
    Column("last_error", Text),
    Column("updated_at", DateTime(timezone=True), nullable=False),
)

Index("ix_batches_status", batches.c.status)


def make_engine(url: str, **kwargs: Any) -> Engine:
    """Engine for ``url``; SQLite gets WAL journaling, full sync and foreign keys on every connection."""
    if url.startswith("sqlite"):
        engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": 30}, **kwargs)

        @event.listens_for(engine, "connect")
        def _sqlite_pragmas(dbapi_conn: Any, _record: Any) -> None:
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA synchronous=FULL")  # an accepted batch survives a crash of the process or OS
            cur.execute("PRAGMA foreign_keys=ON")
            cur.close()

        return engine
    return create_engine(url, pool_pre_ping=True, **kwargs)
