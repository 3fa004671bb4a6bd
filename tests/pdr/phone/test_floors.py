"""Barometric floor tracking: floor counting with hysteresis, drift re-anchoring, online chunks, state."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.frames import altitude_to_pressure_hpa
from pdr.phone.floors import LEVEL_SPAN, FloorConfig, FloorTracker, whole_floors

RATE_HZ = 10.0
LEVEL_MID = LEVEL_SPAN


def pressures(altitude_m: np.ndarray, base_m: float = 300.0) -> np.ndarray:
    return altitude_to_pressure_hpa(base_m + altitude_m)


def _up_and_floor(samples):
    """The altitude above the start (m) and the floor of :meth:`FloorTracker.track`'s samples."""
    return samples.up_m, samples.floor


def test_two_flights_up_and_one_down_count_floors_at_the_configured_height():
    # 60 s flat, 20 s of stairs up 8 m (two 4 m floors), 60 s flat, 10 s down 4 m, 60 s flat.
    alt = np.concatenate([np.zeros(600), np.linspace(0, 8, 200), np.full(600, 8.0), np.linspace(8, 4, 100),
                          np.full(600, 4.0)])
    flat = np.ones(alt.size, dtype=bool)
    flat[600:800] = flat[1400:1500] = False
    up, floor = _up_and_floor(FloorTracker(RATE_HZ, floor0=1.0).track(pressures(alt), flat))
    assert floor[599] == 1.0 and floor[1399] == 3.0 and floor[-1] == 2.0
    assert up[1399] == pytest.approx(8.0, abs=0.05)
    # The same climb with 3 m floors: 8 m is 2.67 floors, counted as 3 (0.6 floor of hysteresis past floor 2);
    # on the flat the reference settles on that floor, so the 4 m down (1.33 floors) is one floor: 2.
    _, floor3 = _up_and_floor(FloorTracker(RATE_HZ, FloorConfig(floor_height_m=3.0)).track(pressures(alt),
                                                                                           flat))
    assert floor3[1399] == 3.0 and floor3[-1] == 2.0


def test_slow_pressure_drift_on_the_flat_is_not_a_floor():
    # Weather: 6 m of apparent altitude over 20 minutes while walking on the flat.
    alt = np.linspace(0.0, 6.0, 12000)
    _, floor = _up_and_floor(FloorTracker(RATE_HZ).track(pressures(alt), np.ones(alt.size, dtype=bool)))
    assert np.all(floor == 0.0)
    # Without re-anchoring (never flat) the same drift counts as a floor.
    _, floor = _up_and_floor(FloorTracker(RATE_HZ).track(pressures(alt), np.zeros(alt.size, dtype=bool)))
    assert floor[-1] == 1.0


def test_chunks_with_state_round_trips_equal_one_batch():
    rng = np.random.default_rng(3)
    alt = np.cumsum(rng.normal(0, 0.05, 3000)) + np.repeat([0.0, 4.0, 8.0, 4.0, 0.0, -4.0], 500)
    flat = rng.random(alt.size) < 0.8
    p = pressures(alt)
    up1, fl1 = _up_and_floor(FloorTracker(RATE_HZ, floor0=-1.0).track(p, flat))
    tracker = FloorTracker(RATE_HZ, floor0=-1.0)
    ups, fls = [], []
    for a, b in zip([0, 7, 700, 701, 1999], [7, 700, 701, 1999, 3000], strict=True):
        u, f = _up_and_floor(tracker.track(p[a:b], flat[a:b]))
        ups.append(u)
        fls.append(f)
        tracker = FloorTracker.from_state(tracker.state())
    np.testing.assert_array_equal(np.concatenate(ups), up1)
    np.testing.assert_array_equal(np.concatenate(fls), fl1)


def test_bad_configuration_and_state_are_named():
    with pytest.raises(InputError, match="floor height must be positive"):
        FloorConfig(floor_height_m=0.0)
    with pytest.raises(InputError, match="bad floor state"):
        FloorTracker.from_state({"rate_hz": 10.0})


def _ride(alt_from: float, alt_to: float, speed_mps: float) -> np.ndarray:
    """30 s at ``alt_from``, a ride at ``speed_mps``, 30 s at ``alt_to`` (m)."""
    n = int(abs(alt_to - alt_from) / speed_mps * RATE_HZ)
    return np.concatenate([np.full(300, alt_from), np.linspace(alt_from, alt_to, n), np.full(300, alt_to)])


MUSEUM = FloorConfig(floor_height_m=2.85, altitudes_m=((0, 0.0), (-1, -3.1), (-2, -5.7)))


def test_site_floor_altitudes_count_a_mezzanine_and_continue_by_the_floor_height():
    # Down the stairs from floor 0 to the mezzanine (-3.1 m), then to floor -2 (-5.7 m), walking all the way.
    alt = np.concatenate([_ride(0.0, -3.1, 0.3), _ride(-3.1, -5.7, 0.3)])
    walking = 9.81 + 2.0 * np.sin(np.arange(alt.size) * 2 * np.pi * 2.0 / RATE_HZ)
    flat = np.ones(alt.size, dtype=bool)
    _, floor = _up_and_floor(FloorTracker(RATE_HZ, MUSEUM).track(pressures(alt), flat, walking))
    half = _ride(0.0, -3.1, 0.3).size
    assert floor[half - 1] == -1.0 and floor[-1] == -2.0
    # Floors beyond the listed ones continue from the nearest by the floor height.
    assert MUSEUM.altitude_m(1) == pytest.approx(2.85) and MUSEUM.altitude_m(-3) == pytest.approx(-8.55)
    # Uniform 4 m floors (the default, not learnt) put -5.7 m on floor -1: 2.6 m below the mezzanine is less than
    # 0.6 of a 4 m floor. Learning the height from the first flight (3.1 m) gets floor -2 without the site.
    _, floor4 = _up_and_floor(FloorTracker(RATE_HZ, FloorConfig(learn_height=False)).track(pressures(alt), flat,
                                                                                            walking))
    assert floor4[-1] == -1.0
    learner = FloorTracker(RATE_HZ)
    _, learnt = _up_and_floor(learner.track(pressures(alt), flat, walking))
    assert learnt[half - 1] == -1.0 and learnt[-1] == -2.0
    assert learner.learnt_height_m == pytest.approx(3.1, abs=0.1)


def test_an_elevator_ride_changes_the_floor_once_when_it_ends():
    alt = _ride(0.0, -5.7, 1.0)
    still = np.full(alt.size, 9.81)                      # a rider standing in the cabin
    up, floor = _up_and_floor(FloorTracker(RATE_HZ, MUSEUM).track(pressures(alt), np.ones(alt.size, dtype=bool),
                                                                  still))
    changes = np.flatnonzero(np.diff(floor))
    assert changes.size == 1 and floor[-1] == -2.0       # 0 -> -2 at once, never through the mezzanine
    arrived = 300 + int(5.7 * RATE_HZ)
    assert arrived <= changes[0] <= arrived + 5 * RATE_HZ
    # Walking (no accelerometer given: taken as walking), the floors passed show as they are passed.
    _, walked = _up_and_floor(FloorTracker(RATE_HZ, MUSEUM).track(pressures(alt), np.ones(alt.size, dtype=bool)))
    assert np.flatnonzero(np.diff(walked)).size == 2 and np.flatnonzero(np.diff(walked))[0] < arrived
    tracker = FloorTracker(RATE_HZ, MUSEUM)
    tracker.track(pressures(alt), np.ones(alt.size, dtype=bool), still)
    assert tracker.floors_between(0.0, float(up[-1])) == 2 and tracker.floors_between(-3.0, -0.2) == 1


def test_the_altitude_moves_while_the_cabin_rides_and_not_on_a_floor():
    # A 1 m/s ride down 5.7 m between flat stretches: moving within a second or two of the start, to within a few
    # seconds of the end (the rate is low-passed), never on the floors.
    alt = _ride(0.0, -5.7, 1.0)
    out = FloorTracker(RATE_HZ, MUSEUM).track(pressures(alt), np.ones(alt.size, dtype=bool), np.full(alt.size, 9.81))
    start, end = 300, 300 + int(5.7 * RATE_HZ)
    assert out.moving[start + int(2 * RATE_HZ):end].all()
    assert not out.moving[:start].any() and not out.moving[end + int(5 * RATE_HZ):].any()


def test_floor_altitudes_are_checked():
    with pytest.raises(InputError, match="rise with the floor number"):
        FloorConfig(altitudes_m=((0, 0.0), (1, -3.0)))
    with pytest.raises(InputError, match="pairs"):
        FloorConfig(altitudes_m=(("ground", 0.0),))  # type: ignore[arg-type]
    # Saved states keep the altitudes and resume with them.
    t = FloorTracker(RATE_HZ, MUSEUM)
    assert FloorTracker.from_state(t.state()).config == MUSEUM


def test_stair_flights_are_runs_of_three_or_more_stairs_steps_with_their_height_from_the_foot():
    from pdr.phone.floors import StairFlights
    # (mode, altitude at the step's end): level at 0 m, 12 steps up to 1.8 m, level, 2 steps down (too short for a
    # flight), level, 4 steps down to 1.2 m, straight into 3 steps up (a new flight), level.
    # The floor shown goes from 0 to 1 on the first flight and back to 0 on the 4 steps down.
    walk = ([("walking", 0.0, 0)] * 3 + [("stairs_up", 0.15 * k, int(k > 8)) for k in range(1, 13)]
            + [("walking", 1.8, 1)] * 2 + [("stairs_down", 1.65, 1), ("stairs_down", 1.5, 1)]
            + [("walking", 1.5, 1)] * 2
            + [("stairs_down", 1.5 - 0.15 * k, int(k < 3)) for k in range(1, 5)]
            + [("stairs_up", 0.9 + 0.15 * k, 0) for k in (1, 2, 3)] + [("walking", 1.35, 0)])
    flights, t = [], 0.0
    f = StairFlights()
    for k, (mode, up, floor) in enumerate(walk):
        if k == 20:                                    # resume from the saved state half way
            f = StairFlights.from_state(f.state())
        out = f.step(t, t + 0.5, mode, up, floor)
        t += 0.5
        if out is not None:
            flights.append(out)
    assert [(d, n, floors) for _, _, d, n, _, _, floors in flights] == [("up", 12, 1), ("down", 4, 1), ("up", 3, 0)]
    assert flights[0][4:6] == (0.0, pytest.approx(1.8))           # from the foot of the flight to its top
    assert flights[1][4] == pytest.approx(1.5) and flights[1][5] == pytest.approx(0.9)
    assert flights[2][4] == pytest.approx(0.9)                    # the turn at the bottom is the next flight's foot
    assert flights[0][0] == 1.5 and flights[0][1] == 7.5          # first step's start, last step's end (s)
    with pytest.raises(InputError, match="stair flight state"):
        StairFlights.from_state({"min_steps": 3})


def _walking(n: int) -> np.ndarray:
    """Specific-force magnitudes (m/s^2) of a walker: 2 m/s^2 at 2 Hz about gravity."""
    return 9.81 + 2.0 * np.sin(np.arange(n) * 2 * np.pi * 2.0 / RATE_HZ)


def _flights(*legs: tuple[float, float, float]) -> np.ndarray:
    """Altitudes (m): for each leg ``(seconds level, metres climbed, climbing speed m/s)``, a level then a climb."""
    alt, level = [], 0.0
    for hold_s, climb_m, speed in legs:
        alt.append(np.full(int(hold_s * RATE_HZ), level))
        if climb_m:
            n = int(abs(climb_m) / speed * RATE_HZ)
            alt.append(np.linspace(level, level + climb_m, n))
            level += climb_m
    return np.concatenate(alt)


def test_the_floor_height_is_learnt_from_the_first_flight_walked_between_two_levels():
    # Two 3.2 m floors up, each as two half flights with a 2 s landing between them (too short for a level), then
    # 30 s on the floor. The default 4 m floors would read 6.4 m as floor 1; the learnt height reads floor 2.
    alt = _flights((30, 1.6, 0.3), (2, 1.6, 0.3), (30, 1.6, 0.3), (2, 1.6, 0.3), (30, 0, 0))
    flat = np.ones(alt.size, dtype=bool)
    tracker = FloorTracker(RATE_HZ)
    _, floor = _up_and_floor(tracker.track(pressures(alt), flat, _walking(alt.size)))
    assert tracker.learnt_height_m == pytest.approx(3.2, abs=0.15) and tracker.floor_height_m == tracker.learnt_height_m
    assert floor[-1] == 2.0
    assert tracker.levels[LEVEL_MID + 2] == pytest.approx(2 * tracker.learnt_height_m)
    _, default = _up_and_floor(FloorTracker(RATE_HZ, FloorConfig(learn_height=False)).track(
        pressures(alt), flat, _walking(alt.size)))
    assert default[-1] == 1.0
    # Batches of any size, with the state saved and restored between them, learn the same at the same sample.
    chunked = FloorTracker(RATE_HZ)
    parts = []
    for a, b in zip([0, 13, 320, 321, 700, 1500], [13, 320, 321, 700, 1500, alt.size], strict=True):
        parts.append(chunked.track(pressures(alt[a:b]), flat[a:b], _walking(alt.size)[a:b]).floor)
        chunked = FloorTracker.from_state(chunked.state())
    np.testing.assert_array_equal(np.concatenate(parts), floor)
    assert chunked.learnt_height_m == tracker.learnt_height_m


def test_whole_floors_counts_a_climb_only_when_one_count_fits():
    assert [whole_floors(d, 2.5, 5.0) for d in (2.0, 2.5, 3.1, 4.9, 5.5, 5.9, 7.4, 7.6, 9.0, 20.0)] == [
        0, 1, 1, 1, 2, 2, 2, 0, 0, 0]         # under a floor; one; two; 2 or 3 floors (and more) are ambiguous


def test_no_height_is_learnt_from_a_ride_an_ambiguous_climb_or_with_a_stated_height():
    # An elevator ride of one 3 m floor that nobody walks out of (pdr.phone.baro_rides.WALK_OUT_S).
    ride = _flights((30, 3.0, 1.0), (30, 0, 0))
    t = FloorTracker(RATE_HZ)
    t.track(pressures(ride), np.ones(ride.size, dtype=bool), np.full(ride.size, 9.81))
    assert np.isnan(t.learnt_height_m)
    # Two 3 m floors walked without a level between them: 6 m is two floors (one cannot be so high).
    double = _flights((30, 6.0, 0.3), (30, 0, 0))
    t = FloorTracker(RATE_HZ)
    t.track(pressures(double), np.ones(double.size, dtype=bool), _walking(double.size))
    assert t.learnt_height_m == pytest.approx(3.0, abs=0.25)
    # Three 3 m floors at once: 9 m may be two floors of 4.5 m or three of 3 m.
    triple = _flights((30, 9.0, 0.3), (30, 0, 0))
    t = FloorTracker(RATE_HZ)
    t.track(pressures(triple), np.ones(triple.size, dtype=bool), _walking(triple.size))
    assert np.isnan(t.learnt_height_m)
    # A pause of 10 s on the half landing (1.5 m) is no floor: the flight is measured from the floor it left.
    landing = _flights((30, 1.5, 0.3), (10, 1.5, 0.3), (30, 0, 0))
    t = FloorTracker(RATE_HZ)
    t.track(pressures(landing), np.ones(landing.size, dtype=bool), _walking(landing.size))
    assert t.learnt_height_m == pytest.approx(3.0, abs=0.25)
    # A stated height (or a site's) is kept.
    one = _flights((30, 3.0, 0.3), (30, 0, 0))
    for config in (FloorConfig(floor_height_m=3.5), MUSEUM, FloorConfig(learn_height=False)):
        t = FloorTracker(RATE_HZ, config)
        t.track(pressures(one), np.ones(one.size, dtype=bool), _walking(one.size))
        assert np.isnan(t.learnt_height_m) and t.floor_height_m == config.floor_height_m


def _lift(climb_m: float, speed: float, walk_after_s: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Altitudes (m) and specific-force magnitudes (m/s^2): walk 20 s, stand 5 s, ride ``climb_m`` at ``speed``
    (m/s) standing, stand until ``walk_after_s`` after the climb (None: 40 s, no walk), then walk 20 s.
    """
    alt = _flights((25, climb_m, speed), (40, 0, 0))
    acc = np.full(alt.size, 9.81)
    acc[:int(20 * RATE_HZ)] = _walking(int(20 * RATE_HZ))
    if walk_after_s is not None:
        out = int((25 + abs(climb_m) / speed + walk_after_s) * RATE_HZ)
        acc[out:] = _walking(alt.size - out)
    return alt, acc


@pytest.mark.parametrize(("climb_m", "speed", "walk_after_s", "learnt"), [
    (-5.6, 1.0, 3.0, 2.8),          # two 2.8 m floors down in an elevator, walked out of after 3 s
    (5.6, 1.0, 8.0, 2.8),           # the doors took longer: the level waits for the walk out (WALK_OUT_S)
    (5.6, 1.0, None, None),         # nobody walks off: a car climbing a road
    (3.0, 0.3, 1.0, None),          # at an escalator's speed (EN 115-1: 0.375 m/s at most)
    (9.0, 1.5, 2.0, None),          # 2 floors of 4.5 m or 3 of 3 m
])
def test_an_elevator_ride_walked_out_of_measures_the_floor_height(climb_m, speed, walk_after_s, learnt):
    alt, acc = _lift(climb_m, speed, walk_after_s)
    t = FloorTracker(RATE_HZ)
    t.track(pressures(alt), np.ones(alt.size, dtype=bool), acc)
    if learnt is None:
        assert np.isnan(t.learnt_height_m)
    else:
        assert t.learnt_height_m == pytest.approx(learnt, abs=0.2)


def test_states_saved_before_the_height_was_learnt_resume():
    t = FloorTracker(RATE_HZ)
    old = {k: v for k, v in t.state().items() if k not in ("level_up", "held", "walked", "ridden", "learnt_height_m")}
    resumed = FloorTracker.from_state(old)
    assert np.isnan(resumed.learnt_height_m) and resumed.held == 0
    with pytest.raises(InputError, match="floor_height_range_m"):
        FloorConfig(floor_height_range_m=(5.0, 2.0))
