"""Migration 0010_group_clock on a database written before it, in SQLite and in PostgreSQL: a group agent fed from
a session keeps the clock it was fed on (offset 0), and the downgrade removes the column again.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import command

from pdr.fusion.group import Group
from server import db
from server.group_store import GroupStore, encode_state
from tests.server.helpers import legacy_session
from tests.server.realservers import database_url, pg_database  # noqa: F401  (fixtures)


def test_existing_session_fed_agents_get_offset_zero(database_url: str) -> None:  # noqa: F811
    cfg, engine, user, sid = legacy_session(database_url, "0009_typed_steps")
    try:
        meta = sa.MetaData()
        groups = sa.Table("groups", meta, autoload_with=engine)
        agents = sa.Table("group_agents", meta, autoload_with=engine)
        assert "clock_offset_s" not in agents.c
        now = db.utcnow()
        with engine.begin() as conn:
            conn.execute(sa.insert(groups).values(id="g1", user_id=user, name="old", created_at=now, updated_at=now,
                                                  version=0, state=encode_state(Group())))
            conn.execute(sa.insert(agents).values(group_id="g1", agent="a", session_id=sid, joined_at=now))
        command.upgrade(cfg, "head")
        [link] = GroupStore(engine).followers(sid)
        assert (link.group_id, link.agent, link.clock_offset_s) == ("g1", "a", 0.0)
        command.downgrade(cfg, "0009_typed_steps")
        assert "clock_offset_s" not in {c["name"] for c in sa.inspect(engine).get_columns("group_agents")}
    finally:
        engine.dispose()
