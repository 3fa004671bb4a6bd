"""A group agent fed from a session relates the session's clock to the group's: ``group_agents.clock_offset_s``
(group time = session time + offset, s); existing agents get 0, the clock they were fed on before.

Revision ID: 0010_group_clock
Revises: 0009_typed_steps
"""

import sqlalchemy as sa
from alembic import op

revision = "0010_group_clock"
down_revision = "0009_typed_steps"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("group_agents") as batch_op:
        batch_op.add_column(sa.Column("clock_offset_s", sa.Float(), nullable=False, server_default="0"))


def downgrade() -> None:
    with op.batch_alter_table("group_agents") as batch_op:
        batch_op.drop_column("clock_offset_s")
