"""Migration 0009_typed_steps (the typed step) on a database written before it, in SQLite and in PostgreSQL.

The old layout is written here as the service wrote it up to migration 0006 (``server.phone_processor`` then): a
phone step was a track row plus a ``step`` event whose JSON ``data`` kept the heading smoother's inputs, matched to
the row by their shared time; a foot step a track row plus a ``step`` event carrying its increment.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sqlalchemy as sa
from alembic import command

from pdr.io import read_recording
from pdr.phone.events import StepEvent
from pdr.phone.heading_smoother import smooth_track
from pdr.phone.pipeline import PdrPipeline, PipelineConfig
from server import auth, db, migrations
from server.api.results import _smoothed
from server.store import STEP_FIELDS, Store, step_fields
from tests.server.realservers import database_url, pg_database  # noqa: F401  (fixtures)

LOG = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim" / "hand_escalator.zip"
#: The step event fields the service kept for the heading smoother until migration 0009_typed_steps.
OLD_SMOOTHER_INPUTS = ("placement", "heading_sigma_deg", "heading_raw_deg", "gyro_heading_deg", "up_time_s",
                       "gyro_bias_dps", "position_fix", "landmark_heading")
TRACK = ("t_s", "east_m", "north_m", "up_m", "floor", "heading_deg", "step_length_m", "mode")


@pytest.fixture(scope="module")
def phone_rows() -> list[dict[str, Any]]:
    """The step rows of a hand-held walk (the simulator's escalator log), as the pipeline emits them."""
    events = PdrPipeline(PipelineConfig(placement="hand")).run(read_recording(LOG))
    return [e for e in events if e["type"] == "step"]


def _step(row: dict[str, Any]) -> StepEvent:
    """The typed step event of a step row."""
    return StepEvent(**{k: v for k, v in row.items() if k != "type"})


def _write_legacy(engine: sa.Engine, phone: list[dict[str, Any]]) -> str:
    """A session with a phone walk (its last step provisional) and three foot steps, in the layout of 0006."""
    meta = sa.MetaData()
    tp = sa.Table("track_points", meta, autoload_with=engine)
    ev = sa.Table("events", meta, autoload_with=engine)
    with engine.begin() as conn:
        auth.add_user(conn, "legacy")
    store = Store(engine)
    with engine.connect() as conn:
        user = conn.execute(sa.select(db.users.c.id)).scalar_one()
    sid, _ = store.create_session(int(user), source="native", client_session_id="legacy-walk")
    track: list[dict[str, Any]] = []
    events: list[dict[str, Any]] = []
    for k, e in enumerate(phone):
        common = {"session_id": sid, "device_role": "phone", "provisional": k == len(phone) - 1}
        track.append(common | {c: e[c] for c in TRACK})
        events.append(common | {"kind": "step", "t_s": e["t_s"], "t_end_s": None, "label": e["mode"],
                                "value": e["step_length_m"],
                                "data": json.dumps({"t_start_s": e["t_start_s"], "heading_deg": e["heading_deg"],
                                                    "floor": e["floor"],
                                                    "smoother": {k: e.get(k) for k in OLD_SMOOTHER_INPUTS}})})
    for k in range(3):
        common = {"session_id": sid, "device_role": "left_foot", "provisional": False}
        track.append(common | {"t_s": 1.0 + k, "east_m": 0.7 * k, "north_m": 0.0, "up_m": 0.0, "floor": None,
                               "heading_deg": 90.0, "step_length_m": 0.7, "mode": "walking"})
        events.append(common | {"kind": "step", "t_s": 1.0 + k, "t_end_s": None, "label": "walking", "value": 0.7,
                                "data": json.dumps({"heading_deg": 90.0, "increment": {"index": 100 * k}})})
    events.append({"session_id": sid, "device_role": "phone", "provisional": False, "kind": "mode",
                   "t_s": phone[0]["t_start_s"], "t_end_s": None, "label": "walking", "value": None, "data": "{}"})
    with engine.begin() as conn:
        conn.execute(sa.insert(tp), track)
        conn.execute(sa.insert(ev), events)
    return sid


def _check_migrated(store: Store, sid: str, phone: list[dict[str, Any]]) -> None:
    rows = store.track(sid, "phone")
    assert [r.step_index for r in rows] == list(range(len(phone)))
    assert [bool(r.provisional) for r in rows] == [False] * (len(phone) - 1) + [True]
    for r, e in zip(rows, phone, strict=True):
        kept = step_fields(r)
        assert kept == {k: e[k] for k in (*OLD_SMOOTHER_INPUTS, "t_start_s") if e[k] is not None}
    # The heading smoother gets what it got from the old layout: pdr track's default output, exactly.
    smoothed, smoothing = _smoothed(rows)
    ours, _ = smooth_track(phone)
    assert smoothing.devices == ("phone",)
    for key in ("east_m", "north_m", "heading_deg"):
        assert [p[key] for p in smoothed] == [r[key] for r in ours]
    # Phone step events are gone (their fields are in the rows); foot step events point at their rows by index.
    step_events = store.events(sid, "step")
    assert {e.device_role for e in step_events} == {"left_foot"}
    assert [e.step_index for e in step_events] == [0, 1, 2]
    steps = [s for s in store.steps(sid) if s.device_role == "left_foot"]
    assert [json.loads(s.data)["increment"]["index"] for s in steps] == [0, 100, 200]
    assert len(store.events(sid, "mode")) == 1


def test_migration_keeps_old_steps_and_numbers_them(database_url: str,  # noqa: F811
                                                    phone_rows: list[dict[str, Any]]) -> None:
    cfg = migrations.alembic_config(database_url)
    command.upgrade(cfg, "0006")
    engine = db.make_engine(database_url)
    try:
        sid = _write_legacy(engine, phone_rows)
        command.upgrade(cfg, "head")
        store = Store(engine)
        _check_migrated(store, sid, phone_rows)

        # Downgrading writes the phone step events back as 0006 had them; upgrading again gives the same rows.
        command.downgrade(cfg, "0006")
        with engine.connect() as conn:
            ev = sa.Table("events", sa.MetaData(), autoload_with=conn)
            back = list(conn.execute(sa.select(ev).where(ev.c.kind == "step", ev.c.device_role == "phone")
                                     .order_by(ev.c.t_s)))
        assert [json.loads(r.data)["smoother"] for r in back] == [{k: e[k] for k in OLD_SMOOTHER_INPUTS}
                                                                   for e in phone_rows]
        command.upgrade(cfg, "head")
        _check_migrated(store, sid, phone_rows)

        # New steps go on from the last final one; the provisional row is replaced.
        new = _step(phone_rows[-1] | {"t_s": phone_rows[-1]["t_s"] + 0.6})
        store.commit_results(sid, "phone", None, b"{}", None, [new], [])
        rows = store.track(sid, "phone")
        assert [r.step_index for r in rows] == list(range(len(phone_rows)))
        assert not any(r.provisional for r in rows)
        last = step_fields(rows[-1])
        assert last["patterns"] == new.patterns and last["turn_deg"] == new.turn_deg
        assert math.isclose(rows[-1].t_s, new.t_s, rel_tol=0, abs_tol=0)
    finally:
        engine.dispose()


def test_stored_step_is_the_typed_step_event(tmp_path: Path, phone_rows: list[dict[str, Any]]) -> None:
    """A step stored after 0009_typed_steps reads back as the pipeline's step event, every field bit for bit."""
    url = f"sqlite:///{tmp_path / 'new.db'}"
    migrations.upgrade(url)
    engine = db.make_engine(url)
    try:
        with engine.begin() as conn:
            auth.add_user(conn, "walker")
        store = Store(engine)
        sid, _ = store.create_session(1, source="native", client_session_id="walk")
        steps = [_step(r) for r in phone_rows]
        half = len(steps) // 2
        store.commit_results(sid, "phone", None, b"{}", None, steps[:half], [], tail_track=steps[half:half + 1])
        store.commit_results(sid, "phone", None, b"{}", None, steps[half:], [])
        rows = store.track(sid, "phone")
        assert [r.step_index for r in rows] == list(range(len(steps)))
        back = [_step({c: getattr(r, c) for c in TRACK} | dict.fromkeys(STEP_FIELDS) | step_fields(r)) for r in rows]
        assert back == steps
        assert np.array_equal([r.t_s for r in rows], [s.t_s for s in steps])
    finally:
        engine.dispose()
