"""Uploads decoded once: the decoded recording of a raw batch and of a pending report's upload.

The view reads each upload (one sandboxed reader, or one JSON parse) and stores what it decoded
(:mod:`pdr.recording_codec`, zlib-compressed); processing reads that instead of the raw payload. Rows stored
before this revision have none and are read from their raw payload.

Revision ID: 0007_decoded
Revises: 0006
"""

import sqlalchemy as sa
from alembic import op

revision = "0007_decoded"
down_revision = "0006"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("batches") as batch_op:
        batch_op.add_column(sa.Column("decoded", sa.LargeBinary(), nullable=True))
    with op.batch_alter_table("report_uploads") as batch_op:
        batch_op.add_column(sa.Column("decoded", sa.LargeBinary(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("report_uploads") as batch_op:
        batch_op.drop_column("decoded")
    with op.batch_alter_table("batches") as batch_op:
        batch_op.drop_column("decoded")
