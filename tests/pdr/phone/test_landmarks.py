"""Landmarks (seed 003 Sec. 3): the step label (eqs. 1-3), the neighbour correction, the elevator impulses, the
site description and its matching, the pipeline's label stage."""

import json
import math

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.phone.history import SampleHistory
from pdr.phone.landmarks import (
    ElevatorDetector,
    LandmarkConfig,
    Site,
    SiteLandmark,
    StepModeLabeller,
    classify_step,
    neighbour_correction,
)

CFG = LandmarkConfig()
BASE = (40.0, 25.0, -15.0)            # flat walking: opening, Pitch_max, Pitch_min (deg)


@pytest.mark.parametrize(("rate", "pmax", "pmin", "mode"), [
    (0.3, None, None, "stairs_up"), (-0.3, 50.0, -10.0, "stairs_down"),        # the barometer decides when present
    (0.05, 60.0, -15.0, "walking"),
    (None, 45.0, -15.0, "stairs_up"),           # opening 60 > 1.25 * 40 and Pitch_max 45 > 25 + 8 (eqs. 2-3)
    (None, 45.0, -2.0, "walking"),              # opening 47 < 50: not up
    (None, 20.0, -5.0, "stairs_down"),          # opening 25 < 0.8 * 40 and Pitch_min -5 > -15 + 8
    (None, 20.0, -8.0, "walking"),              # Pitch_min -8 is not above -7
    (math.nan, 45.0, -15.0, "stairs_up"),       # a NaN rate is no barometer
])
def test_classify_step_follows_the_rate_or_the_pitch_pattern(rate, pmax, pmin, mode):
    assert classify_step(rate, pmax, pmin, BASE, CFG) == mode


def test_without_baseline_or_pitch_a_step_is_walking_and_neighbours_correct_an_isolated_label():
    assert classify_step(None, 45.0, -15.0, None, CFG) == "walking"
    assert classify_step(None, None, None, BASE, CFG) == "walking"
    assert neighbour_correction("walking", "stairs_up", "walking") == "walking"
    assert neighbour_correction("stairs_up", "walking", "stairs_up") == "stairs_up"
    assert neighbour_correction("walking", "stairs_up", "stairs_up") == "stairs_up"


def _impulses(rate: float, gap_s: float, first: float) -> np.ndarray:
    n = int(rate)
    pulse = np.full(n, first * 0.5)
    return np.concatenate([np.zeros(n), pulse, np.zeros(int(gap_s * rate)), -pulse, np.zeros(n)])


def _walked(det: ElevatorDetector, steps_in=(0, 25), steps_out=(660, 685)) -> ElevatorDetector:
    """``det`` told of the steps walking into the cabin before the first impulse (at 50) and out after the second
    (grid indices)."""
    for i in (*steps_in, *steps_out):
        det.add_step(i)
    return det


def _still(n: int) -> np.ndarray:
    return np.zeros(n, dtype=bool)


@pytest.mark.parametrize("first", [1.0, -1.0])
def test_elevator_is_a_pair_of_opposite_impulses_in_any_batching(first):
    rate = 50.0
    dv = np.concatenate([_impulses(rate, 10.0, first), np.zeros(100)])
    one = _walked(ElevatorDetector(rate)).update(dv, _still(dv.size))
    assert len(one) == 1 and one[0][2] == int(first)
    s, e, _ = one[0]
    assert s == 50 and e == 50 + 50 + 500 + 50 - 1 + 1        # from the first impulse's start to the second's end
    # Batch by batch, the step out is confirmed after the second impulse has passed: the ride waits for it.
    det, got = _walked(ElevatorDetector(rate), steps_out=()), []
    for part in np.array_split(dv, 7):
        got += det.update(part, _still(part.size))
        det = ElevatorDetector.from_state(json.loads(json.dumps(det.state())))
        if det.pending and 660 not in det.steps:
            assert got == [] and det.pending == [(s, e, int(first))]
            det.add_step(660)
    assert got == one and det.pending == []


def test_impulses_too_short_too_far_apart_or_of_one_sign_are_no_elevator():
    rate = 50.0
    short_pulses = np.concatenate([np.zeros(50), np.full(20, 0.5), np.zeros(200), np.full(20, -0.5)])
    assert _walked(ElevatorDetector(rate)).update(short_pulses, _still(short_pulses.size)) == []
    far = _impulses(rate, 70.0, 1.0)                            # longer than elevator_max_ride_s
    assert _walked(ElevatorDetector(rate)).update(far, _still(far.size)) == []
    same = np.concatenate([np.zeros(50), np.full(50, 0.5), np.zeros(100), np.full(50, 0.5)])
    assert _walked(ElevatorDetector(rate)).update(same, _still(same.size)) == []


def test_impulses_with_a_walk_between_them_are_no_elevator():
    rate = 50.0
    dv = _impulses(rate, 20.0, -1.0)                            # impulses at samples 50-100 and 1100-1150
    walk = _walked(ElevatorDetector(rate), steps_out=(1160,))
    for i in range(300, 900, 25):                               # steps every 0.5 s between the jolts
        walk.add_step(i)
    assert walk.update(dv, _still(dv.size)) == []
    # Turning round in the cabin (two steps) still leaves a ride, also across a state round trip.
    det = _walked(ElevatorDetector(rate), steps_out=(1160,))
    det.add_step(400)
    det.add_step(425)
    det = ElevatorDetector.from_state(json.loads(json.dumps(det.state())))
    assert len(det.update(dv, _still(dv.size))) == 1
    # After a walk between two jolts, the second jolt opens a pair with a third.
    three = np.concatenate([dv, np.zeros(200), np.full(50, -0.5), np.zeros(50)])
    walk = _walked(ElevatorDetector(rate), steps_out=(1460,))
    for i in range(300, 900, 25):
        walk.add_step(i)
    walk.add_step(1090)                                         # the walk reaches the second jolt
    got = walk.update(three, _still(three.size))
    assert len(got) == 1 and got[0][0] == 1100 and got[0][2] == 1


@pytest.mark.parametrize(("steps_in", "steps_out"), [
    ((), ()),                       # a car's jolts: no walking anywhere near (driving_phone_mount trip 17)
    ((0, 25), ()),                  # walked to the car, drove off: no one walks out
    ((), (660, 685)),               # drove up, got out
    ((-600,), (660,)),              # the last step in 13 s before the first jolt (the doors close in a few)
    ((0,), (1250,)),                # the first step out 12 s after the second jolt
])
def test_jolts_not_walked_into_and_out_of_are_no_elevator(steps_in, steps_out):
    """A ride is walked into and out of within ``elevator_walk_s`` (10 s): the same pair of jolts without the walking
    around it (a vehicle's) is none, whether the whole log comes in one batch or the rest of the day follows."""
    rate = 50.0
    dv = _impulses(rate, 10.0, 1.0)
    det = _walked(ElevatorDetector(rate), steps_in, steps_out)
    assert det.update(dv, _still(dv.size)) == []
    later = np.zeros(int(80 * rate))
    assert det.update(later, _still(later.size)) == [] and det.pending == []   # forgotten once out of reach


SITE = {"name": "museum", "floor_height_m": 3.5, "declination_deg": 2.0, "grid_deg": 69.5, "landmarks": [
    {"id": "S1", "type": "stairs_up", "east_m": 10.0, "north_m": 0.0, "floor": 0, "heading_deg": [80, 100]},
    {"id": "S2", "type": "stairs", "east_m": 14.0, "north_m": 0.0, "floor": 0, "heading_deg": [350, 10],
     "radius_m": 3.0},
    {"id": "E1", "type": "elevator", "east_m": 0.0, "north_m": 30.0, "floor": 1, "heading_deg": [0, 90]}]}


def _id(lm: SiteLandmark | None) -> str | None:
    return None if lm is None else lm.id


def test_site_round_trip_match_and_landmark_heading():
    site = Site.from_dict(SITE)
    assert Site.from_dict(site.to_dict()) == site
    assert site.floor_height_m == 3.5 and site.declination_deg == 2.0 and site.grid_deg == 69.5
    assert _id(site.match("stairs_up", 13.0, 0.0, 0.0)) == "S2"             # nearer; "stairs" takes both ways
    assert _id(site.match("stairs_down", 11.0, 0.0, 0.0)) == "S2"
    assert site.match("stairs_down", 5.0, 0.0, 0.0) is None               # S2 only within 3 m
    assert _id(site.match("stairs_up", 5.0, 0.0, 0.0)) == "S1"
    assert site.match("stairs_up", 10.0, 0.0, 2.0) is None                # another floor
    assert _id(site.match("elevator", 1.0, 29.0, math.nan)) == "E1"         # unknown floor: any
    e1, s1, s2 = site.by_id("E1"), site.by_id("S1"), site.by_id("S2")
    assert e1 is not None and s1 is not None and s2 is not None and site.by_id("X") is None
    assert e1.type == "elevator"
    yaw, var = s1.yaw_and_var()
    assert yaw == pytest.approx(0.0, abs=1e-12)                           # heading 90 deg = east = yaw 0
    assert math.sqrt(var) == pytest.approx(math.radians(20.0) / 6.0)      # three-sigma interval
    yaw2, var2 = s2.yaw_and_var()                           # an interval across north
    assert yaw2 == pytest.approx(math.pi / 2) and math.sqrt(var2) == pytest.approx(math.radians(20.0) / 6.0)


@pytest.mark.parametrize(("edit", "match"), [
    (lambda d: d["landmarks"][0].update(type="lift"), "type must be one of"),
    (lambda d: d["landmarks"][0].update(id={"a": 1}), "field .id.: id must be text or a whole number, not dict"),
    (lambda d: d["landmarks"][0].update(id=True), "id must be text or a whole number, not bool"),
    (lambda d: d.update(name=["hall"]), "field .name.: name must be text, not list"),
    (lambda d: d.update(name=None), "name must be text, not NoneType"),
    (lambda d: d.update(landmarks=[7]), "bad value"),
    (lambda d: d["landmarks"][0].update(heading_deg=90), "heading_deg must be"),
    (lambda d: d["landmarks"][0].pop("east_m"), "missing field 'east_m'"),
    (lambda d: d["landmarks"][0].update(north_m="north"), "field .north_m.: north_m must be a number, not str"),
    (lambda d: d["landmarks"][0].update(east_m="12"), "field .east_m.: east_m must be a number, not str"),
    (lambda d: d["landmarks"][0].update(floor=True), "field .floor.: floor must be a number, not bool"),
    (lambda d: d["landmarks"][0].update(radius_m=float("nan")), "field .radius_m.: radius_m must be finite"),
    (lambda d: d["landmarks"][0].update(heading_deg=[0, 10 ** 400]), "heading_deg is beyond any number"),
    (lambda d: d.update(floor_height_m="high"), "floor_height_m must be a number"),
    (lambda d: d.update(floor_height_m="4"), "floor_height_m must be a number, not str"),
    (lambda d: d.update(floor_height_m=True), "floor_height_m must be a number, not bool"),
    (lambda d: d.update(floor_height_m=-3.0), "floor_height_m must be positive and at most 100 m"),
    (lambda d: d.update(floor_height_m=4000.0), "floor_height_m must be positive and at most 100 m"),
    (lambda d: d.update(floor_height_m=float("nan")), "floor_height_m must be finite"),
    (lambda d: d.update(declination_deg="3"), "declination_deg must be a number, not str"),
    (lambda d: d.update(grid_deg=400), r"grid_deg must be a number of degrees in \[-180, 180\]"),
    (lambda d: d.pop("landmarks"), "'landmarks' list"),
    (lambda d: d.update(floors={"floor": 0}), "expected a non-empty 'floors' list"),
    (lambda d: d.update(floors=[]), "expected a non-empty 'floors' list"),
    (lambda d: d.update(floors=[{"floor": "ground", "altitude_m": 0.0}]), "floor must be a number, not str"),
    (lambda d: d.update(floors=[{"altitude_m": 0.0}]), "missing field 'floor'"),
    (lambda d: d.update(floors=[{"floor": 0, "altitude_m": "3"}]), "altitude_m must be a number, not str"),
    (lambda d: d.update(floors=[{"floor": 0, "altitude_m": 1e5}]), r"altitude_m must be within \+/-10000 m"),
])
def test_bad_site_descriptions_name_the_field(edit, match):
    d = json.loads(json.dumps(SITE))
    edit(d)
    with pytest.raises(InputError, match=match):
        Site.from_dict(d)


def test_site_floor_altitudes_from_the_floor_plan_layout():
    # The floors list of a floor-plan site (pdr.site.plan): only the entries with an altitude count.
    d = {**SITE, "floors": [{"floor": -2, "altitude_m": -5.7, "walkable": []}, {"floor": 0, "altitude_m": 0.0},
                            {"floor": -1, "altitude_m": -3.1}, {"floor": 1}]}
    site = Site.from_dict(d)
    assert site.floor_altitudes_m == ((-2.0, -5.7), (-1.0, -3.1), (0.0, 0.0))
    assert Site.from_dict(site.to_dict()) == site
    assert Site.from_dict(SITE).floor_altitudes_m == ()


def test_a_plan_only_site_needs_no_landmarks_list():
    # What `pdr site check` validates, `pdr track --site` reads: a site of floor plans alone has no landmarks.
    site = Site.from_dict({"floors": [{"floor": 0, "altitude_m": 0.0, "walkable": []}]})
    assert site.landmarks == () and site.floor_altitudes_m == ((0.0, 0.0),)
    with pytest.raises(InputError, match="'landmarks' list") as exc:
        Site.from_dict({"floors": [{"floor": 0, "altitude_m": 0.0, "walkable": []}], "landmarks": {"id": 1}})
    assert exc.value.field == "landmarks"


def test_site_load_names_an_unreadable_file(tmp_path):
    bad = tmp_path / "site.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="cannot read site description") as exc:
        Site.load(bad)
    assert str(bad) in str(exc.value)


def _history(y_up: np.ndarray, up: np.ndarray, rate: float) -> SampleHistory:
    n = y_up.size
    h = SampleHistory(n)
    h.append(0, np.arange(n) / rate, np.zeros((n, 3)), np.zeros(n), np.zeros(n), up, np.zeros(n))
    h.y_up[:] = y_up
    return h


def test_the_label_stage_learns_the_flat_pitch_baseline_and_labels_a_steeper_step_stairs():
    rate = 50.0
    flat = np.sin(np.radians(25.0 * np.sin(np.linspace(0, 2 * np.pi, 30))))       # pitch -25..25 deg
    steep = np.sin(np.radians(np.concatenate([np.linspace(-15, 50, 15), np.linspace(50, -15, 15)])))
    y_up = np.concatenate([np.tile(flat, 4), steep])
    h = _history(y_up, np.zeros(y_up.size), rate)
    lab = StepModeLabeller(CFG, rate)
    modes = [lab.label(h, 30 * k, 30 * (k + 1), "pocket", has_baro=False) for k in range(5)]
    assert modes == ["walking"] * 4 + ["stairs_up"]
    assert lab.pitch_baseline == pytest.approx([50.0, 25.0, -25.0], abs=0.5)
    # A hand-held phone's pitch does not follow the leg: without barometer every step is walking.
    assert StepModeLabeller(CFG, rate).label(h, 120, 150, "hand", has_baro=False) == "walking"
    # With a barometer the vertical rate over the last 2 s decides (0.2 m/s up).
    hb = _history(y_up, 0.2 * np.arange(y_up.size) / rate, rate)
    assert StepModeLabeller(CFG, rate).label(hb, 120, 150, "hand", has_baro=True) == "stairs_up"
    # Output: the neighbour correction against the last output label; state round trip.
    lab.prev_mode = "walking"
    assert lab.corrected("stairs_up", "walking") == "walking" and lab.corrected("stairs_up", None) == "stairs_up"
    again = StepModeLabeller.from_state(json.loads(json.dumps(lab.state())), CFG, rate)
    assert again.prev_mode == "walking" and again.pitch_baseline == lab.pitch_baseline
