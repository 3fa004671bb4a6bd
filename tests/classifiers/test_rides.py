"""Rides: elevator or escalator from the barometric altitude profile; the stairs rule after a ride."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from classifiers.rides import (
    ESCALATOR_MAX_TAIL_S,
    ESCALATOR_MAX_VERTICAL_MPS,
    AltitudeRecord,
    RideProfile,
    ride_kind,
)
from classifiers.timeline import RATE_DELAY_S, RIDE_REACH_S, StepModes
from pdr.errors import InputError
from pdr.frames import altitude_to_pressure_hpa
from pdr.recording import Recording, SensorStream

SIM = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim"


def _ride(lead_s: float, climb_m: float, speed_mps: float, tail_s: float, noise_hpa: float = 0.0,
          rate_hz: float = 10.0, seed: int = 0) -> tuple[Recording, float, float]:
    """Pressure of a ride at ``speed_mps`` (constant) between still spells; returns it and the stop's [t0, t1]."""
    move_s = abs(climb_m) / speed_mps
    total = lead_s + move_s + tail_s
    t = np.arange(int(total * rate_hz)) / rate_hz
    h = np.clip((t - lead_s) * np.sign(climb_m) * speed_mps, -abs(climb_m), abs(climb_m))
    p = altitude_to_pressure_hpa(h + 100.0) + np.random.default_rng(seed).normal(0.0, noise_hpa, t.size)
    rec = Recording({"baro": SensorStream("baro", (t * 1e9).astype(np.int64), p[:, None])}, t0_ns=0)
    return rec, 0.0, float(t[-1])


@pytest.mark.parametrize(("speed", "tail", "kind"), [
    (0.25, 1.5, "escalator"),   # 0.5 m/s along 30 deg, stepping off the exit landing
    (1.0, 5.0, "elevator"),     # a traction lift; the doors open after it stops
    (0.4, 3.0, "elevator"),     # the IPIN museum's slow lift
    (0.25, 5.0, "elevator"),    # slow, but the rider stays put seconds after the altitude settles: doors
    (1.0, 1.5, "elevator"),     # far faster than any escalator
])
def test_ride_kind_from_the_altitude_profile(speed, tail, kind):
    rec, t0, t1 = _ride(4.0, -5.0, speed, tail, noise_hpa=0.01)
    r = AltitudeRecord()
    r.update(rec)
    prof = r.profile(t0, t1)
    assert prof is not None
    assert prof.vertical_speed_mps == pytest.approx(speed, rel=0.15)
    assert prof.tail_s == pytest.approx(tail, abs=0.7)
    assert ride_kind(prof) == kind


def test_physical_bounds_and_unknown_profiles():
    assert ESCALATOR_MAX_VERTICAL_MPS == pytest.approx(0.375)
    assert 2.0 < ESCALATOR_MAX_TAIL_S < 3.0
    assert ride_kind(None) == "elevator"
    assert ride_kind(RideProfile(0.3, 1.0)) == "escalator"
    r = AltitudeRecord()
    assert r.profile(0.0, 10.0) is None                       # nothing recorded
    rec, _, _ = _ride(2.0, 3.0, 0.25, 2.0)
    r.update(rec)
    assert r.profile(-30.0, 10.0) is None                     # the record does not reach the stop's start
    flat = AltitudeRecord()
    flat.update(_ride(10.0, 0.0, 1.0, 5.0)[0])
    assert flat.profile(0.0, 14.0) is None                    # no altitude change


def test_altitude_record_online_equals_offline_and_state_round_trips():
    rec, t0, t1 = _ride(3.0, 4.0, 0.3, 2.0, noise_hpa=0.02, seed=2)
    whole = AltitudeRecord()
    whole.update(rec)
    online = AltitudeRecord()
    for a in np.arange(0.0, t1 + 1.0, 1.3):
        online.update(rec.slice_time(a, a + 1.3))
        online = AltitudeRecord.from_state(json.loads(json.dumps(online.state())))
    a, b = online.profile(t0, t1), whole.profile(t0, t1)
    assert a is not None and b is not None
    assert (a.vertical_speed_mps, a.tail_s) == pytest.approx((b.vertical_speed_mps, b.tail_s))
    with pytest.raises(InputError, match="not an altitude record state"):
        AltitudeRecord.from_state({"version": 1})


def test_stairs_steps_right_after_a_ride_read_its_climb():
    m = StepModes("walking")
    m.entry("escalator_down", 20.0)
    # The walk off the ride is walking, although its first steps' barometric rate still reads the descent.
    assert [m.step("stairs_down", 20.5 + 0.5 * i) for i in range(4)] == [[(20.5, "walking")], [], [], []]
    assert m.last == "walking" and m.pending is None
    # Once the step's rate window has left the ride, stairs steps count again.
    t = 20.0 + RIDE_REACH_S
    out = [m.step("stairs_up", t + 0.5 * i) for i in range(3)]
    assert out[-1] == [(t, "stairs_up")]
    # A stop is no ride: stairs after standing are stairs.
    m = StepModes("walking")
    m.entry("standing", 20.0)
    assert [m.step("stairs_up", 20.5 + 0.5 * i) for i in range(3)][-1] == [(20.5, "stairs_up")]
    s = StepModes.from_state(json.loads(json.dumps(StepModes("x").state())))
    assert s.last == "x" and s.ride_end_s == -np.inf


@pytest.mark.slow
@pytest.mark.parametrize(("name", "label", "floors"), [("hand_escalator.zip", "escalator_down", 1),
                                                       ("torso_elevator.zip", "elevator_up", 2)])
def test_simulated_rides_are_named_by_their_carrier(name, label, floors):
    from classifiers.step_timeline import step_timeline
    from pdr.io import read_recording

    rec = read_recording(SIM / name)
    tm = rec.truth.modes
    assert tm is not None
    truth = [(a, b) for a, b, lab in zip(tm.t_start_s, tm.t_end_s, tm.label, strict=True) if lab == label]
    tl = step_timeline(rec)
    rides = [e for e in tl.entries if e.label.startswith(("elevator", "escalator"))]
    assert [e.label for e in rides] == [label]
    # The scenarios' floor counts (mobile_logs/sim/*.json): the elevator rides two floors of 2.9 m, which the
    # default 4 m floor height read as one until a ride counted the whole floors its climb spans.
    assert rides[0].data["floors"] == floors
    assert rides[0].t_start_s < truth[0][1] and rides[0].t_end_s > truth[0][0]
    assert not np.isin(tl.step_label, ["stairs_up", "stairs_down"]).any()  # the truth has no stairs


def test_stairs_entries_are_placed_back_by_the_rate_delay():
    m = StepModes()
    assert m.step("walking", 0.0, 0.5) == [(0.0, "walking")]
    for t in (1.0, 1.5, 2.0, 2.5):
        assert m.step("walking", t, t + 0.5) == []
    out = [m.step("stairs_up", t, t + 0.5) for t in (3.0, 3.5, 4.0)]
    # The flight opens RATE_DELAY_S before the end of its first stairs-labelled step, not at that step's start.
    assert out[-1] == [(pytest.approx(3.5 - RATE_DELAY_S), "stairs_up")]
    assert m.step("walking", 6.0, 6.5) == [(pytest.approx(6.5 - RATE_DELAY_S), "walking")]
    # Never before the latest entry (here a stop ending at 12 s), nor without the step's end.
    m.entry("standing", 12.0)
    assert m.step("stairs_down", 12.2, 12.6) == [] and m.step("stairs_down", 12.6, 13.0) == []
    assert m.step("stairs_down", 13.0, 13.4) == [(12.0, "stairs_down")]
    m2 = StepModes("walking")
    assert [m2.step("stairs_up", t) for t in (1.0, 1.5, 2.0)][-1] == [(1.0, "stairs_up")]
