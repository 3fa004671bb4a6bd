"""A session's results epoch (``sessions.results_epoch``, :meth:`server.store.Store.fenced`): every clear of its
results (reprocess, new processing options, a late batch's rebuild) increments it, and a processing pass writes its
results, its batches' status and the session's status only while the session still exists at the epoch the pass
began with. Control requests (``DELETE``, ``reprocess``, ``PUT .../processing``) then answer without waiting for a
running pass. Existing sessions start at 0.

Revision ID: 0013_results_epoch
Revises: 0012_payload_format_length
"""

import sqlalchemy as sa
from alembic import op

revision = "0013_results_epoch"
down_revision = "0012_payload_format_length"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("sessions", sa.Column("results_epoch", sa.Integer(), nullable=False, server_default="0"))


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), not a batch operation: SQLite's batch mode copies the table and
    # drops the old one, and dropping ``sessions`` with foreign keys on deletes every row referring to it (CASCADE).
    op.drop_column("sessions", "results_epoch")
