"""Migration 0014_one_session_per_key on a database written before it, in SQLite and in PostgreSQL: of the sessions
that share a client key (what a JSON create and a Sensor Logger push racing could make), the first keeps it, the
others are renamed ``KEY~ID`` whole (their batches stay), and the database refuses a second session under one key.
"""

from __future__ import annotations

from datetime import timedelta

import pytest
import sqlalchemy as sa
from alembic import command
from sqlalchemy.exc import IntegrityError

from server import db
from server.store import Store
from tests.server.helpers import legacy_session
from tests.server.realservers import database_url, pg_database  # noqa: F401  (fixtures)

BEFORE = "0013_results_epoch"


def _insert(engine: sa.Engine, user: int, sid: str, key: str, source: str, created_s: int) -> None:
    """Insert a session as the schema before the migration allowed, made ``created_s`` after now."""
    created = db.utcnow() + timedelta(seconds=created_s)
    with engine.begin() as conn:
        conn.execute(sa.insert(db.sessions).values(
            id=sid, user_id=user, client_session_id=key, source=source, name=key, status="empty", created_at=created,
            updated_at=created, warnings="[]", meta="{}"))


def test_later_sessions_of_one_key_are_renamed_whole_and_a_key_names_one_session(database_url: str) -> None:  # noqa: F811
    cfg, engine, user, first = legacy_session(database_url, BEFORE)   # key "walk", source native
    try:
        long_key = "k" * 200
        _insert(engine, user, "00000000-0000-0000-0000-00000000000b", "walk", "sensor_logger", 60)
        _insert(engine, user, "00000000-0000-0000-0000-00000000000c", long_key, "native", 1)
        _insert(engine, user, "00000000-0000-0000-0000-00000000000d", long_key, "upload", 2)
        store = Store(engine)
        store.add_batch("00000000-0000-0000-0000-00000000000b", device_role="phone", client_batch_id="m1",
                        payload_format="sensor-logger-json", payload=b"{}", t_first_ns=0, t_last_ns=1)
        command.upgrade(cfg, "head")
        with engine.connect() as conn:
            keys = dict(conn.execute(sa.select(db.sessions.c.id, db.sessions.c.client_session_id)).all())
        assert keys == {first: "walk",
                        "00000000-0000-0000-0000-00000000000b": "walk~00000000-0000-0000-0000-00000000000b",
                        "00000000-0000-0000-0000-00000000000c": long_key,
                        "00000000-0000-0000-0000-00000000000d": "k" * 163 + "~00000000-0000-0000-0000-00000000000d"}
        found = store.session_by_key(user, "walk")
        assert found is not None and found.id == first
        assert [b.client_batch_id for b in store.batch_list("00000000-0000-0000-0000-00000000000b")] == ["m1"]
        with pytest.raises(IntegrityError):
            _insert(engine, user, "00000000-0000-0000-0000-00000000000e", "walk", "upload", 3)
        command.downgrade(cfg, BEFORE)
        assert "uq_sessions_user_key" not in {i["name"] for i in sa.inspect(engine).get_indexes("sessions")}
    finally:
        engine.dispose()
