"""Alembic environment: runs migrations online against the configured URL."""

from __future__ import annotations

from alembic import context
from sqlalchemy import text

from server.db import make_engine, metadata

config = context.config
url = config.get_main_option("sqlalchemy.url")
assert url is not None
engine = make_engine(url)
with engine.connect() as connection:
    context.configure(connection=connection, target_metadata=metadata, render_as_batch=url.startswith("sqlite"))
    with context.begin_transaction():
        if connection.dialect.name == "postgresql":
            # Web processes and workers starting together: one migrates, the others wait here, then find it done.
            connection.execute(text("SELECT pg_advisory_xact_lock(7351001)"))
        context.run_migrations()
engine.dispose()
