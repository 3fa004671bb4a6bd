"""A batch's ``payload_format`` holds an uploaded file's ``file:FORMAT/FILENAME``
(:data:`server.processing.FILE_PREFIX`, the name as :func:`server.sandbox.safe_filename` keeps it: up to 120
characters), which processing reads the file by:
``VARCHAR(40)`` refused every upload whose format and name were longer than 34 characters in PostgreSQL (SQLite does
not enforce it), e.g. ``file:sensorconnect/SensorConnectData_31.csv``; now ``VARCHAR(200)``. The downgrade fails
while such a batch is stored.

Revision ID: 0012_payload_format_length
Revises: 0011_pocket_side
"""

import sqlalchemy as sa
from alembic import op

revision = "0012_payload_format_length"
down_revision = "0011_pocket_side"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("batches") as batch_op:
        batch_op.alter_column("payload_format", type_=sa.String(200), existing_type=sa.String(40),
                              existing_nullable=False)


def downgrade() -> None:
    with op.batch_alter_table("batches") as batch_op:
        batch_op.alter_column("payload_format", type_=sa.String(40), existing_type=sa.String(200),
                              existing_nullable=False)
