"""Live sessions fed the way real phones stream: batches whose streams start, lag or go back in time, compared with
the one-batch run of the same samples."""

from typing import Any

import numpy as np
import pytest

from pdr.io.registry import read_recording
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.recording import Recording, SensorStream
from pdr.sim import load_scenario, simulate
from tests.conftest import REPO_ROOT, data_path


@pytest.fixture(scope="module")
def hand_walk() -> Recording:
    return simulate(load_scenario(REPO_ROOT / "mobile_logs" / "sim" / "hand_escalator.json"), 1)


def _lagged(rec: Recording, dt_s: float, late: tuple[str, ...], from_batch: int = 0) -> list[Recording]:
    """``rec`` in batches of ``dt_s`` seconds whose streams ``late`` carry the samples of the batch before from batch
    ``from_batch`` on (a phone that sends them one batch late: with ``from_batch`` 0 the first batch has none)."""
    t0, t1 = rec.time_span_s()
    out = []
    for i, a in enumerate(np.arange(t0, t1 + dt_s, dt_s)):
        streams = {}
        for k, s in rec.streams.items():
            lo = a - dt_s if k in late and i >= from_batch else a
            t = s.t_s(rec.origin_ns)
            m = (t >= lo) & (t < lo + dt_s)
            if m.any():
                streams[k] = SensorStream(k, s.t_ns[m], s.values[m])
        if streams:
            out.append(Recording(streams, rec.device, t0_ns=rec.origin_ns, meta=rec.meta))
    return out


def _live(parts: list[Recording]) -> list[dict[str, Any]]:
    p = PdrPipeline(PipelineConfig())
    events: list[dict[str, Any]] = []
    for part in parts:
        events += p.update(part)
        p = PdrPipeline.from_state(p.state())
    return events + p.finish()


def _max_distance_m(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> float:
    return max(float(np.hypot(r["east_m"] - s["east_m"], r["north_m"] - s["north_m"]))
               for r, s in zip(a, b, strict=True))


def test_a_magnetometer_and_gyroscope_that_start_a_batch_late_are_used_from_then_on(hand_walk):
    # The phone's first batch has only the accelerometer (its gyroscope and magnetometer start a batch later). Before,
    # the session ran without them to its end: heading relative to the first device heading, from the
    # accelerometer alone.
    one = track_rows(PdrPipeline(PipelineConfig()).run(hand_walk))
    events = _live(_lagged(hand_walk, 1.0, ("gyro", "mag")))
    live = track_rows(events)
    assert len(live) == len(one) and _max_distance_m(live, one) < 0.5
    assert all(r["gyro_heading_deg"] is not None for r in live)
    notices = [e["message"] for e in events if e["type"] == "notice"]
    assert any(m.startswith("gyroscope data starts at t=") for m in notices)
    assert any(m.startswith("magnetometer data starts at t=") for m in notices)


@pytest.mark.data
def test_a_real_walks_magnetometer_a_batch_late_keeps_the_one_batch_track():
    # Sensor Logger pocket walk (28 steps), 2 s batches whose magnetometer samples come one batch late. Before, the
    # session never used the magnetometer: the track ended 31.6 m from the one-batch one.
    rec = read_recording(data_path("sensor_logger_walks", "inpocket-27-steps-Matan"))
    one = track_rows(PdrPipeline(PipelineConfig()).run(rec))
    live = track_rows(_live(_lagged(rec, 2.0, ("mag",))))
    assert len(live) == len(one) == 28
    assert _max_distance_m(live, one) < 0.5


def _batches(rec: Recording, dt_s: float) -> list[Recording]:
    return _lagged(rec, dt_s, ())


def _halves(shift_s: float) -> tuple[Recording, Recording]:
    """The Sensor Logger hand-held walk (29 steps) cut in two halves, the second moved by ``shift_s`` seconds on the
    phone's clock."""
    rec = read_recording(data_path("sensor_logger_walks", "inhand-30-steps-Zyf"))
    t0, t1 = rec.time_span_s()
    mid = t0 + 0.5 * (t1 - t0)
    second = rec.slice_time(mid, t1 + 1.0)
    moved = {k: SensorStream(k, s.t_ns + int(round(shift_s * 1e9)), s.values) for k, s in second.streams.items()}
    return rec.slice_time(t0, mid), Recording(moved, rec.device, t0_ns=rec.origin_ns, meta=rec.meta)


@pytest.mark.data
def test_a_clock_that_goes_back_is_said_and_a_batch_sent_twice_changes_nothing():
    # Sensor Logger hand-held walk (29 steps) in 2 s batches. Its second half comes 3 s back on the phone's clock
    # (a clock correction): those 3 s cannot be placed among what was processed and are dropped (25 steps, as
    # before), now with a notice instead of silently.
    first, back = _halves(-3.0)
    events = _live(_batches(first, 2.0) + _batches(back, 2.0))
    said = [e["message"] for e in events
            if e["type"] == "notice" and "back before data already processed" in e["message"]]
    assert len(said) == 1 and "goes 2.99 s back" in said[0]
    # A batch uploaded twice (after a timeout) is dropped without a word: the one-batch track.
    rec = read_recording(data_path("sensor_logger_walks", "inhand-30-steps-Zyf"))
    one = PdrPipeline(PipelineConfig()).run(rec)
    parts = _batches(rec, 2.0)
    twice = _live(parts[:5] + parts[3:5] + parts[5:])
    assert track_rows(twice) == track_rows(one) and len(track_rows(one)) == 29
    assert [e for e in twice if e["type"] == "notice"] == [e for e in one if e["type"] == "notice"]


@pytest.mark.data
def test_a_gyroscope_that_falls_a_whole_batch_behind_is_waited_for_not_taken_as_stopped():
    # Sensor Logger pocket walk in 5 s batches; from the third batch on the gyroscope's samples come one batch late
    # (a phone that batches that sensor), more than the grid's 4 s slack. Before, the grid took the gyroscope as
    # stopped in every batch (3 s of each 5 s without it): 19 of the 28 steps had no gyro heading; now it learns the
    # lag after the first late batch and says so: only the steps of that batch lack it.
    rec = read_recording(data_path("sensor_logger_walks", "inpocket-27-steps-Matan"))
    events = _live(_lagged(rec, 5.0, ("gyro",), from_batch=2))
    rows = track_rows(events)
    assert len(rows) == 28 and sum(r["gyro_heading_deg"] is None for r in rows) <= 6
    said = [e["message"] for e in events if e["type"] == "notice" and "behind the accelerometer's" in e["message"]]
    assert len(said) == 1 and said[0].startswith("gyroscope data comes 5.0 s behind")


@pytest.mark.data
def test_thirty_seconds_without_data_keep_the_steps_and_the_track_and_are_said():
    # Sensor Logger hand-held walk (29 steps) whose app is suspended for 30 s mid-walk, in 2 s batches: every step is
    # kept (13 before, 16 after), live as in one batch, the step over the gap moves by its length, and a notice (new)
    # says that 30 s had no data.
    first, after = _halves(30.0)
    gap = first.with_streams({k: SensorStream(k, np.concatenate([s.t_ns, after.streams[k].t_ns]),
                                              np.concatenate([s.values, after.streams[k].values]))
                              for k, s in first.streams.items()})
    one = PdrPipeline(PipelineConfig()).run(gap)
    events = _live(_batches(gap, 2.0))
    rows = track_rows(events)
    assert rows == track_rows(one) and len(rows) == 29
    i = int(np.argmax(np.diff([r["t_s"] for r in rows])))
    moved = np.hypot(rows[i + 1]["east_m"] - rows[i]["east_m"], rows[i + 1]["north_m"] - rows[i]["north_m"])
    assert moved == pytest.approx(rows[i + 1]["step_length_m"], abs=0.01)
    said = [e["message"] for e in events if e["type"] == "notice" and e["message"].startswith("no accelerometer data")]
    assert len(said) == 1 and "(30.0 s: the app suspended" in said[0]
