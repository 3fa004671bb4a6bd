"""groups of agents fused by the server (cooperative localization): groups, members, raw uploads, fused tracks

Revision ID: 0002_groups
Revises: 0004

(Named 0002 as planned; it follows the current head 0004 so that the chain stays linear: 0001 -> 0003 -> 0004
-> 0002_groups. ``upgrade head`` refuses a history with two heads.)
"""

import sqlalchemy as sa
from alembic import op

revision = "0002_groups"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "groups",
        sa.Column("id", sa.String(length=36), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("state", sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(["user_id"], ["users.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_groups_user_id", "groups", ["user_id"], unique=False)
    op.create_table(
        "group_agents",
        sa.Column("group_id", sa.String(length=36), nullable=False),
        sa.Column("agent", sa.String(length=200), nullable=False),
        sa.Column("session_id", sa.String(length=36), nullable=True),
        sa.Column("joined_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["group_id"], ["groups.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["session_id"], ["sessions.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("group_id", "agent"),
    )
    op.create_table(
        "group_uploads",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("group_id", sa.String(length=36), nullable=False),
        sa.Column("agent", sa.String(length=200), nullable=False),
        sa.Column("client_batch_id", sa.String(length=200), nullable=False),
        sa.Column("payload", sa.LargeBinary(), nullable=False),
        sa.Column("received_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["group_id"], ["groups.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("group_id", "client_batch_id", name="uq_group_uploads_client"),
    )
    op.create_index("ix_group_uploads_group_id", "group_uploads", ["group_id"], unique=False)
    op.create_table(
        "group_track_points",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("group_id", sa.String(length=36), nullable=False),
        sa.Column("agent", sa.String(length=200), nullable=False),
        sa.Column("foot", sa.String(length=40), nullable=False),
        sa.Column("t_s", sa.Float(), nullable=False),
        sa.Column("east_m", sa.Float(), nullable=False),
        sa.Column("north_m", sa.Float(), nullable=False),
        sa.Column("up_m", sa.Float(), nullable=False),
        sa.Column("heading_deg", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(["group_id"], ["groups.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_group_track_points_group_id", "group_track_points", ["group_id"], unique=False)


def downgrade() -> None:
    op.drop_index("ix_group_track_points_group_id", table_name="group_track_points")
    op.drop_table("group_track_points")
    op.drop_index("ix_group_uploads_group_id", table_name="group_uploads")
    op.drop_table("group_uploads")
    op.drop_table("group_agents")
    op.drop_index("ix_groups_user_id", table_name="groups")
    op.drop_table("groups")
