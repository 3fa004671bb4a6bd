"""Scoped tokens with expiry and last use; existing tokens become ``full``.

Revision ID: 0005
Revises: 0002_groups
"""

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0002_groups"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("api_tokens") as batch_op:
        batch_op.add_column(sa.Column("scope", sa.String(length=8), nullable=False, server_default="full"))
        batch_op.add_column(sa.Column("expires_at", sa.DateTime(timezone=True), nullable=True))
        batch_op.add_column(sa.Column("last_used_at", sa.DateTime(timezone=True), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("api_tokens") as batch_op:
        for name in ("last_used_at", "expires_at", "scope"):
            batch_op.drop_column(name)
