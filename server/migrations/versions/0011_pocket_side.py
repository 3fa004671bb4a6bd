"""A phone step keeps its trouser-pocket side evidence (``track_points.pocket_side``,
:class:`pdr.phone.events.StepEvent`): the offline heading smoother splits the turn lag between the gyro and the
measured direction by it. Steps stored before have null there, and the smoother takes the prior split for them.

Revision ID: 0011_pocket_side
Revises: 0010_group_clock
"""

import sqlalchemy as sa
from alembic import op

revision = "0011_pocket_side"
down_revision = "0010_group_clock"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("track_points") as batch_op:
        batch_op.add_column(sa.Column("pocket_side", sa.Float(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("track_points") as batch_op:
        batch_op.drop_column("pocket_side")
