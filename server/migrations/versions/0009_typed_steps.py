"""The typed step: a track row holds the whole phone step event, and every stored step has an integer index.

``track_points`` gains ``step_index`` (0, 1, ... per session and device role, in commit order) and the fields of
:class:`pdr.phone.events.StepEvent` beyond the track's columns (null on foot and fused rows); ``events`` gains
``step_index`` (a foot step event's track row). Existing rows are carried over: the indices are numbered in
time order, and the old phone ``step`` events (the smoother's inputs in a JSON ``data`` blob beside each track
row, matched by their shared time) become the new columns of their rows and are dropped; foot step events keep
their increments and get their row's index. Downgrade writes the phone step events back.

Revision ID: 0009_typed_steps
Revises: 0008_sites
"""

from __future__ import annotations

import json
from collections import defaultdict
from typing import Any

import sqlalchemy as sa
from alembic import op

revision = "0009_typed_steps"
down_revision = "0008_sites"
branch_labels = None
depends_on = None

#: The step event's columns beyond the track's (server.db.track_points): name, type.
STEP_COLUMNS = (("t_start_s", sa.Float()), ("turn_deg", sa.Float()), ("placement", sa.String(length=16)),
                ("heading_sigma_deg", sa.Float()), ("pos_sigma_m", sa.Float()), ("patterns", sa.Text()),
                ("heading_raw_deg", sa.Float()), ("gyro_heading_deg", sa.Float()), ("up_time_s", sa.Text()),
                ("gyro_bias_dps", sa.Text()), ("position_fix", sa.Boolean()), ("landmark_heading", sa.Boolean()))
#: The vector fields, stored as JSON arrays.
VECTORS = ("patterns", "up_time_s", "gyro_bias_dps")
#: What the old phone step event's data held besides its ``smoother`` inputs (already in the track row).
_SMOOTHER_SCALARS = ("placement", "heading_sigma_deg", "heading_raw_deg", "gyro_heading_deg", "position_fix",
                     "landmark_heading")


def _tables() -> tuple[sa.Table, sa.Table]:
    meta = sa.MetaData()
    return (sa.Table("track_points", meta, autoload_with=op.get_bind()),
            sa.Table("events", meta, autoload_with=op.get_bind()))


def upgrade() -> None:
    with op.batch_alter_table("track_points") as batch_op:
        batch_op.add_column(sa.Column("step_index", sa.Integer(), nullable=True))
        for name, kind in STEP_COLUMNS:
            batch_op.add_column(sa.Column(name, kind, nullable=True))
    with op.batch_alter_table("events") as batch_op:
        batch_op.add_column(sa.Column("step_index", sa.Integer(), nullable=True))
    _carry_over()
    op.create_index("ix_track_points_step", "track_points", ["session_id", "device_role", "step_index"])


def _carry_over() -> None:
    """Number the existing rows and move the old phone step events into their rows (module doc)."""
    conn = op.get_bind()
    tp, ev = _tables()
    index: dict[tuple[str, str, float], int] = {}
    count: dict[tuple[str, str], int] = defaultdict(int)
    updates: list[dict[str, Any]] = []
    for r in conn.execute(sa.select(tp.c.id, tp.c.session_id, tp.c.device_role, tp.c.t_s)
                          .order_by(tp.c.session_id, tp.c.device_role, tp.c.provisional, tp.c.t_s, tp.c.id)):
        key = (r.session_id, r.device_role)
        index.setdefault((*key, r.t_s), count[key])
        updates.append({"row_id": r.id, "step_index": count[key]})
        count[key] += 1
    _update(conn, tp, updates)
    moved: list[dict[str, Any]] = []
    foot: list[dict[str, Any]] = []
    dropped: list[int] = []
    for e in conn.execute(sa.select(ev.c.id, ev.c.session_id, ev.c.device_role, ev.c.t_s, ev.c.data)
                          .where(ev.c.kind == "step")):
        i = index.get((e.session_id, e.device_role, e.t_s))
        data = json.loads(e.data or "{}")
        if i is None:
            continue
        if isinstance(data.get("smoother"), dict):
            s = data["smoother"]
            values = {k: s.get(k) for k in _SMOOTHER_SCALARS} | {
                "t_start_s": data.get("t_start_s"), "up_time_s": _vector(s.get("up_time_s")),
                "gyro_bias_dps": _vector(s.get("gyro_bias_dps"))}
            moved.append({"session": e.session_id, "role": e.device_role, "idx": i, **values})
            dropped.append(e.id)
        else:
            foot.append({"row_id": e.id, "step_index": i})
    _update(conn, ev, foot)
    if moved:
        names = [k for k in moved[0] if k not in ("session", "role", "idx")]
        conn.execute(sa.update(tp).where(tp.c.session_id == sa.bindparam("session"),
                                         tp.c.device_role == sa.bindparam("role"),
                                         tp.c.step_index == sa.bindparam("idx"))
                     .values({n: sa.bindparam(n) for n in names}), moved)
    if dropped:
        conn.execute(sa.delete(ev).where(ev.c.id.in_(dropped)))


def _update(conn: Any, table: sa.Table, rows: list[dict[str, Any]]) -> None:
    if rows:
        conn.execute(sa.update(table).where(table.c.id == sa.bindparam("row_id"))
                     .values(step_index=sa.bindparam("step_index")), rows)


def _vector(v: Any) -> str | None:
    return None if v is None else json.dumps(v)


def downgrade() -> None:
    conn = op.get_bind()
    tp, ev = _tables()
    rows = list(conn.execute(sa.select(tp).where(tp.c.t_start_s.is_not(None))))
    if rows:
        conn.execute(sa.insert(ev), [
            {"session_id": r.session_id, "device_role": r.device_role, "kind": "step", "t_s": r.t_s,
             "label": r.mode, "value": r.step_length_m, "provisional": r.provisional,
             "data": json.dumps({"t_start_s": r.t_start_s, "heading_deg": r.heading_deg, "floor": r.floor,
                                 "smoother": {k: getattr(r, k) for k in _SMOOTHER_SCALARS} | {
                                     k: None if getattr(r, k) is None else json.loads(getattr(r, k))
                                     for k in ("up_time_s", "gyro_bias_dps")}})} for r in rows])
    op.drop_index("ix_track_points_step", table_name="track_points")
    with op.batch_alter_table("events") as batch_op:
        batch_op.drop_column("step_index")
    with op.batch_alter_table("track_points") as batch_op:
        for name, _ in reversed(STEP_COLUMNS):
            batch_op.drop_column(name)
        batch_op.drop_column("step_index")
