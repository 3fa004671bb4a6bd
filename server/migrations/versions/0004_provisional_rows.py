"""Provisional tail rows of tracks and events.

Revision ID: 0004
Revises: 0003
"""

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    for table in ("track_points", "events"):
        with op.batch_alter_table(table) as batch_op:
            batch_op.add_column(sa.Column("provisional", sa.Boolean(), nullable=False, server_default=sa.false()))


def downgrade() -> None:
    for table in ("track_points", "events"):
        with op.batch_alter_table(table) as batch_op:
            batch_op.drop_column("provisional")
