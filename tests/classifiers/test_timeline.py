"""Stops (the standing labelling rule), the stop/elevator timeline, and the car transition gate."""

from __future__ import annotations

import json

import numpy as np
import pytest

from classifiers.stops import MIN_STOP_S, StopDetector, stop_intervals, subtract
from classifiers.timeline import StopTimeline
from classifiers.transitions import TRANSITION_REACH_S, TransitionGate, gate_transitions
from pdr.errors import InputError
from pdr.recording import Recording, SensorStream

RATE = 100.0
G = 9.81


def _walk_and_stand(parts: list[tuple[str, float]], seed: int = 0) -> Recording:
    """Hand-held-like log: 'walk' (2 Hz, 1.5 m/s^2 bounce, 0.4 rad/s sway), 'still' (tremor 0.05 m/s^2),
    'fidget' (0.6 s of 1.5 m/s^2 shaking), 'turn' (phone turned over at 2 rad/s, little acceleration)."""
    rng = np.random.default_rng(seed)
    t_all, a_all, g_all = [], [], []
    t0 = 0.0
    for kind, dur in parts:
        t = t0 + np.arange(int(round(dur * RATE))) / RATE
        a = np.tile([0.0, 0.0, G], (t.size, 1)) + rng.normal(0.0, 0.05, (t.size, 3))
        w = rng.normal(0.0, 0.02, (t.size, 3))
        if kind == "walk":
            a[:, 2] += 1.5 * np.sin(2 * np.pi * 2.0 * t)
            w[:, 0] += 0.4 * np.sin(2 * np.pi * 1.0 * t)
        elif kind == "fidget":
            a[:, 0] += 1.5 * np.sin(2 * np.pi * 5.0 * t)
        elif kind == "turn":
            w[:, 1] += 2.0
        t_all.append(t)
        a_all.append(a)
        g_all.append(w)
        t0 += dur
    t_ns = (np.concatenate(t_all) * 1e9).astype(np.int64)
    return Recording({"acc": SensorStream("acc", t_ns, np.vstack(a_all)),
                      "gyro": SensorStream("gyro", t_ns, np.vstack(g_all))}, t0_ns=0)


def _steps(t0: float, t1: float) -> list[tuple[float, float]]:
    """Step intervals every 0.5 s over [t0, t1) s."""
    s = np.arange(t0, t1 - 0.25, 0.5)
    return [(float(a), float(a + 0.5)) for a in s]


def test_stop_rule_finds_the_stop_between_two_walks():
    rec = _walk_and_stand([("walk", 10.0), ("still", 8.0), ("walk", 10.0)])
    stops = stop_intervals(rec, _steps(0, 10) + _steps(18, 28))
    assert len(stops) == 1
    assert stops[0].t_start_s == pytest.approx(10.0, abs=0.51) and stops[0].t_end_s == pytest.approx(18.0, abs=0.51)


def test_short_pause_is_not_a_stop_and_steps_cut_still_runs():
    rec = _walk_and_stand([("walk", 10.0), ("still", 1.5), ("walk", 10.0)])
    assert stop_intervals(rec, _steps(0, 10) + _steps(11.5, 21.5)) == []
    # A still device with steps (a shuffle) is no stop: each piece between steps is under MIN_STOP_S.
    rec = _walk_and_stand([("still", 10.0)])
    assert stop_intervals(rec, _steps(0, 10)) == []
    # ... and a step in the middle splits a stop in two.
    stops = stop_intervals(rec, [(4.8, 5.3)])
    assert [round(s.t_end_s - s.t_start_s) for s in stops] == [5, 5]


def test_fidget_is_bridged_but_turning_the_phone_ends_a_stop():
    rec = _walk_and_stand([("still", 5.0), ("fidget", 0.6), ("still", 5.0)])
    assert len(stop_intervals(rec, [])) == 1
    rec = _walk_and_stand([("still", 5.0), ("turn", 3.0), ("still", 5.0)])
    stops = stop_intervals(rec, [])
    assert len(stops) == 2 and stops[0].t_end_s == pytest.approx(5.0, abs=0.51)


def test_online_batches_give_the_offline_stops_and_state_round_trips():
    rec = _walk_and_stand([("walk", 6.0), ("still", 7.0), ("walk", 4.0), ("still", 3.0), ("walk", 5.0)], seed=3)
    steps = _steps(0, 6) + _steps(13, 17) + _steps(20, 25)
    offline = stop_intervals(rec, steps)
    assert len(offline) == 2
    det = StopDetector()
    online = []
    for a in np.arange(0.0, 25.0, 1.7):
        batch = rec.slice_time(a, a + 1.7)
        reported = [s for s in steps if a <= s[1] < a + 1.7]  # steps come with the batch they end in
        online += det.update(batch, reported)
        det = StopDetector.from_state(json.loads(json.dumps(det.state())))
    online += det.finish()
    assert online == offline
    # A stop is reported only once the steps after it are known.
    det = StopDetector()
    assert det.update(rec.slice_time(0, 14.0), _steps(0, 6)) == []
    assert len(det.pending()) == 1 and len(det.update(rec.slice_time(14.0, 15.0), _steps(13, 15))) == 1


def test_stop_rule_rejects_bad_input():
    with pytest.raises(InputError, match="min_stop_s"):
        StopDetector(min_stop_s=0.1)
    with pytest.raises(InputError, match="before it starts"):
        StopDetector().update(_walk_and_stand([("still", 1.0)]), [(2.0, 1.0)])
    with pytest.raises(InputError, match="not a stop detector state"):
        StopDetector.from_state({"version": 1})
    assert subtract([(0.0, 10.0)], (2.0, 3.0)) == [(0.0, 2.0), (3.0, 10.0)]
    assert MIN_STOP_S == 2.0


def test_timeline_labels_a_stop_with_a_floor_change_as_an_elevator_ride():
    rec = _walk_and_stand([("walk", 5.0), ("still", 20.0), ("walk", 5.0), ("still", 6.0), ("walk", 3.0)])
    events = [{"type": "step", "t_start_s": a, "t_s": b, "up_m": 0.0 if b < 10 else 8.1}
              for a, b in _steps(0, 5) + _steps(25, 30) + _steps(36, 39)]
    events.insert(10, {"type": "floor_change", "t_s": 22.0, "floor": 2.0, "from_floor": 0.0})
    tl = StopTimeline()
    entries = tl.update(rec, events) + tl.finish()
    assert [e.label for e in entries] == ["elevator_up", "standing"]
    assert entries[0].data["floors"] == 2.0 and entries[0].data["from_floor"] == 0.0
    assert entries[0].data["altitude_change_m"] == pytest.approx(8.1)
    tl2 = StopTimeline.from_state(json.loads(json.dumps(StopTimeline().state())))
    assert tl2.update(rec, events)[0].label == "elevator_up"
    # A version 1 state counted the detector's time from its first batch's t0_ns: its detector starts again.
    old = {**tl.state(), "version": 1}
    assert StopTimeline.from_state(old).detector.state() == StopTimeline().detector.state()
    assert StopTimeline.from_state(old).floor_changes == tl.floor_changes


@pytest.mark.parametrize(("assumed", "floors"), [(True, 2.0), (False, 1.0)])
def test_a_ride_counts_the_whole_floors_of_its_climb_while_the_height_is_assumed(assumed, floors):
    # 5.8 m down read with the 4 m default as one floor (0 -> -1); only two 2.5-5 m floors fit 5.8 m. With a
    # site's or a learnt height the pipeline's own count stands. More steps come before the ride than the
    # timeline keeps, all in one batch (a whole recording): the ride still has its altitude change.
    rec = _walk_and_stand([("walk", 40.0), ("still", 20.0), ("walk", 5.0)])
    events = [{"type": "step", "t_start_s": a, "t_s": b, "up_m": 0.0 if b < 50 else -5.8}
              for a, b in _steps(0, 40) + _steps(60, 65)]
    events.insert(90, {"type": "floor_change", "t_s": 55.0, "floor": -1.0, "from_floor": 0.0,
                       "height_assumed": assumed})
    tl = StopTimeline()
    entries = tl.update(rec, events) + tl.finish()
    assert [e.label for e in entries] == ["elevator_down"]
    assert entries[0].data["floors"] == floors and entries[0].data["floor"] == -floors
    assert entries[0].data["altitude_change_m"] == pytest.approx(-5.8)


def _labels(pattern: str) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, tuple[str, ...]]:
    names = {"w": "walking", "s": "stationary", "i": "car_step_in", "o": "car_step_out", "v": "vehicle"}
    classes = ("car_step_in", "car_step_out", "stationary", "vehicle", "walking")
    labels = tuple(names[c] for c in pattern)
    t0 = np.arange(len(labels)) * 1.28
    proba = np.full((len(labels), 5), 0.05)
    for i, lab in enumerate(labels):
        proba[i, classes.index(lab)] = 0.6
        if lab.startswith("car"):
            proba[i, classes.index("stationary")] = 0.2
    return labels, proba, t0, classes


def test_car_transitions_hold_only_next_to_a_vehicle_segment():
    labels, proba, t0, classes = _labels("wwwsiiisswww" + "w" * 30 + "sii" + "v" * 30 + "ooww")
    out, conf = gate_transitions(labels, np.full(len(labels), 0.6), proba, classes, t0, t0 + 2.56)
    s = "".join({"walking": "w", "stationary": "s", "car_step_in": "i", "car_step_out": "o",
                 "vehicle": "v"}[x] for x in out)
    assert s == "wwwsssssswww" + "w" * 30 + "sii" + "v" * 30 + "ooww"
    assert conf[4] == pytest.approx(0.2 / (0.2 + 0.05))  # renormalised over stationary and walking
    # A vehicle run shorter than MIN_SEGMENT_S is no car trip; the step-in before it goes with it.
    labels, proba, t0, classes = _labels("wwsii" + "v" * 8 + "sww")
    out, _ = gate_transitions(labels, np.full(len(labels), 0.6), proba, classes, t0, t0 + 2.56)
    assert not {"vehicle", "car_step_in"} & set(out)
    # car_step_out with no vehicle before it is standing too.
    labels, proba, t0, classes = _labels("wwoows")
    out, _ = gate_transitions(labels, np.full(6, 0.6), proba, classes, t0, t0 + 2.56)
    assert "car_step_out" not in out


def test_transition_gate_online_equals_offline():
    pattern = ("wwwsiiisswww" + "w" * 30 + "sii" + "v" * 30 + "ooww" + "s" * 5 + "ii" + "v" * 6 + "ss"
               + "i" * 3 + "w" * 10 + "v" * 40 + "o")
    labels, proba, t0, classes = _labels(pattern)
    offline, _ = gate_transitions(labels, np.full(len(labels), 0.6), proba, classes, t0, t0 + 2.56)
    items = [{"t_start_s": float(a), "t_end_s": float(a + 2.56), "mode": lab, "confidence": 0.6,
              "proba": dict(zip(classes, p.tolist(), strict=True))}
             for a, lab, p in zip(t0, labels, proba, strict=True)]
    gate = TransitionGate()
    got = []
    for k in range(0, len(items), 4):
        got += gate.push(items[k:k + 4])
        gate = TransitionGate.from_state(json.loads(json.dumps(gate.state())))
    got += gate.flush()
    assert tuple(g["mode"] for g in got) == offline
    assert [g["t_start_s"] for g in got] == sorted(g["t_start_s"] for g in got)
    assert TRANSITION_REACH_S > 2.56 and set(offline) >= {"vehicle", "car_step_in", "car_step_out", "stationary"}


def test_step_modes_need_a_flight_for_a_stairs_entry():
    from classifiers.timeline import MIN_FLIGHT_STEPS, StepModes

    m = StepModes()
    seq = ["walking"] * 3 + ["stairs_down"] * 2 + ["walking"] * 3 + ["stairs_up"] * 5 + ["walking"]
    entries = [e for i, mode in enumerate(seq) for e in m.step(mode, float(i))]
    assert entries == [(0.0, "walking"), (8.0, "stairs_up"), (13.0, "walking")]
    assert MIN_FLIGHT_STEPS == 3
    m.step("stairs_down", 20.0)
    m2 = StepModes.from_state(json.loads(json.dumps(m.state())))
    assert m2.step("stairs_down", 21.0) == [] and m2.step("stairs_down", 22.0) == [(20.0, "stairs_down")]
    with pytest.raises(InputError, match="step-modes state"):
        StepModes.from_state({})

