"""Migration 0011_pocket_side on a database written before it, in SQLite and in PostgreSQL: a stored phone step keeps
its other fields and reads back without the pocket's side (the smoother's prior split), a new one stores it, and the
downgrade removes the column again.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import command

from pdr.phone.events import StepEvent
from server import db
from server.store import STEP_FIELDS, step_fields, step_values
from tests.server.helpers import legacy_session
from tests.server.realservers import database_url, pg_database  # noqa: F401  (fixtures)


def _step(pocket_side: float | None) -> StepEvent:
    return StepEvent(t_s=1.0, t_start_s=0.5, east_m=0.6, north_m=0.1, up_m=0.0, floor=0.0, heading_deg=80.0,
                     step_length_m=0.6, turn_deg=2.0, mode="walking", placement="pocket", heading_sigma_deg=5.0,
                     pos_sigma_m=0.2, patterns=[1.8, 1.0, 1.0, 1.0, 2.0, 2.0], heading_raw_deg=81.0,
                     gyro_heading_deg=10.0, up_time_s=[0.0, 0.0, 1.0], gyro_bias_dps=None, position_fix=False,
                     landmark_heading=False, pocket_side=pocket_side)


def test_steps_stored_before_read_back_without_the_pocket_side(database_url: str) -> None:  # noqa: F811
    cfg, engine, _, sid = legacy_session(database_url, "0010_group_clock")
    try:
        tp = sa.Table("track_points", sa.MetaData(), autoload_with=engine)
        assert "pocket_side" not in tp.c
        old = {k: v for k, v in step_values(_step(None)).items() if k != "pocket_side"}
        with engine.begin() as conn:
            conn.execute(sa.insert(tp).values(session_id=sid, device_role="phone", step_index=0, **old))
        command.upgrade(cfg, "head")
        with engine.begin() as conn:
            conn.execute(sa.insert(db.track_points).values(session_id=sid, device_role="phone", step_index=1,
                                                           **step_values(_step(-0.25))))
            rows = conn.execute(sa.select(db.track_points).order_by(db.track_points.c.step_index)).all()
        before, after = (step_fields(r) for r in rows)
        assert "pocket_side" in STEP_FIELDS
        assert "pocket_side" not in before and before["heading_raw_deg"] == 81.0
        assert after["pocket_side"] == -0.25
        command.downgrade(cfg, "0010_group_clock")
        assert "pocket_side" not in {c["name"] for c in sa.inspect(engine).get_columns("track_points")}
    finally:
        engine.dispose()
