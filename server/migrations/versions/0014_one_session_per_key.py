"""A client's ``session_id`` names one session per user, whatever the source (``uq_sessions_user_key``): the unique
constraint ``uq_sessions_client`` included the source, so a JSON create and a Sensor Logger push racing with one key
(both looked the key up, found none, and inserted) made two sessions, and the key found only the first.

Existing duplicates are kept whole, not merged (merging would join the batches of two walks that may only share a
key by accident, and rebuild both): the first session made under a key (``created_at``, then ``id``) keeps it, which
is the one the key found before; each later one is renamed ``KEY~ID`` (its own id; the key cut to fit 200
characters) and stays reachable by its id. ``uq_sessions_client`` stays: SQLite cannot drop it without copying
``sessions`` (which would cascade into every row referring to it), and the new index implies it.
The downgrade drops the index; renamed keys stay renamed.

Revision ID: 0014_one_session_per_key
Revises: 0013_results_epoch
"""

import sqlalchemy as sa
from alembic import op

revision = "0014_one_session_per_key"
down_revision = "0013_results_epoch"
branch_labels = None
depends_on = None

#: Length of ``sessions.client_session_id``.
KEY_CHARS = 200


def upgrade() -> None:
    s = sa.table("sessions", sa.column("id", sa.String), sa.column("user_id", sa.Integer),
                 sa.column("client_session_id", sa.String), sa.column("created_at", sa.DateTime))
    conn = op.get_bind()
    shared = conn.execute(sa.select(s.c.user_id, s.c.client_session_id)
                          .group_by(s.c.user_id, s.c.client_session_id).having(sa.func.count() > 1)).all()
    for user_id, key in shared:
        ids = conn.execute(sa.select(s.c.id).where(s.c.user_id == user_id, s.c.client_session_id == key)
                           .order_by(s.c.created_at, s.c.id)).scalars().all()
        for sid in ids[1:]:
            conn.execute(sa.update(s).where(s.c.id == sid).values(
                client_session_id=f"{key[:KEY_CHARS - len(sid) - 1]}~{sid}"))
    op.create_index("uq_sessions_user_key", "sessions", ["user_id", "client_session_id"], unique=True)


def downgrade() -> None:
    op.drop_index("uq_sessions_user_key", table_name="sessions")
