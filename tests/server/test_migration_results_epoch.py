"""Migration 0013_results_epoch on a database written before it, in SQLite and in PostgreSQL: sessions start at epoch
0, a clear of the results increments it, and neither the upgrade nor the downgrade loses a row that refers to a
session (SQLite's batch mode would copy ``sessions`` and drop the old table, cascading into every such row).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import command

from server import db
from server.store import Store, TrackRow
from tests.server.helpers import legacy_session
from tests.server.realservers import database_url, pg_database  # noqa: F401  (fixtures)

BEFORE = "0012_payload_format_length"


def _counts(engine: sa.Engine, sid: str) -> dict[str, int]:
    with engine.connect() as conn:
        return {t.name: len(conn.execute(sa.select(t.c.session_id).where(t.c.session_id == sid)).all())
                for t in (db.batches, db.track_points, db.processor_states)}


def test_sessions_start_at_epoch_0_and_keep_their_rows_both_ways(database_url: str) -> None:  # noqa: F811
    cfg, engine, _, sid = legacy_session(database_url, BEFORE)
    try:
        store = Store(engine)
        batch, _ = store.add_batch(sid, device_role="phone", client_batch_id="b0", payload_format="native-json",
                                   payload=b"{}", t_first_ns=0, t_last_ns=1)
        store.commit_results(sid, "phone", batch, b"{}", 1, [TrackRow(1.0, 0.0, 0.0, 0.0, 0.0, 90.0, 0.7, "walking")],
                             [])
        command.upgrade(cfg, "head")
        assert store.results_epoch(sid) == 0
        assert _counts(engine, sid) == {"batches": 1, "track_points": 1, "processor_states": 1}
        store.clear_results(sid)
        assert store.results_epoch(sid) == 1 and store.session_row(sid).status == "pending"
        command.downgrade(cfg, BEFORE)
        assert "results_epoch" not in {c["name"] for c in sa.inspect(engine).get_columns("sessions")}
        assert _counts(engine, sid) == {"batches": 1, "track_points": 1, "processor_states": 0}
    finally:
        engine.dispose()
