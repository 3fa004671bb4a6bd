"""Barometric floor tracking: floor counting with hysteresis, drift re-anchoring, online chunks, state."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.frames import altitude_to_pressure_hpa
from pdr.phone.floors import FloorConfig, FloorTracker

RATE_HZ = 10.0


def pressures(altitude_m: np.ndarray, base_m: float = 300.0) -> np.ndarray:
    return altitude_to_pressure_hpa(base_m + altitude_m)


def test_two_flights_up_and_one_down_count_floors_at_the_configured_height():
    # 60 s flat, 20 s of stairs up 8 m (two 4 m floors), 60 s flat, 10 s down 4 m, 60 s flat.
    alt = np.concatenate([np.zeros(600), np.linspace(0, 8, 200), np.full(600, 8.0), np.linspace(8, 4, 100),
                          np.full(600, 4.0)])
    flat = np.ones(alt.size, dtype=bool)
    flat[600:800] = flat[1400:1500] = False
    up, floor = FloorTracker(RATE_HZ, floor0=1.0).update(pressures(alt), flat)
    assert floor[599] == 1.0 and floor[1399] == 3.0 and floor[-1] == 2.0
    assert up[1399] == pytest.approx(8.0, abs=0.05)
    # The same climb with 3 m floors: 8 m is 2.67 floors, counted as 3 (0.6 floor of hysteresis past floor 2);
    # on the flat the reference settles on that floor, so the 4 m down (1.33 floors) is one floor: 2.
    _, floor3 = FloorTracker(RATE_HZ, FloorConfig(floor_height_m=3.0)).update(pressures(alt), flat)
    assert floor3[1399] == 3.0 and floor3[-1] == 2.0


def test_slow_pressure_drift_on_the_flat_is_not_a_floor():
    # Weather: 6 m of apparent altitude over 20 minutes while walking on the flat.
    alt = np.linspace(0.0, 6.0, 12000)
    _, floor = FloorTracker(RATE_HZ).update(pressures(alt), np.ones(alt.size, dtype=bool))
    assert np.all(floor == 0.0)
    # Without re-anchoring (never flat) the same drift counts as a floor.
    _, floor = FloorTracker(RATE_HZ).update(pressures(alt), np.zeros(alt.size, dtype=bool))
    assert floor[-1] == 1.0


def test_chunks_with_state_round_trips_equal_one_batch():
    rng = np.random.default_rng(3)
    alt = np.cumsum(rng.normal(0, 0.05, 3000)) + np.repeat([0.0, 4.0, 8.0, 4.0, 0.0, -4.0], 500)
    flat = rng.random(alt.size) < 0.8
    p = pressures(alt)
    up1, fl1 = FloorTracker(RATE_HZ, floor0=-1.0).update(p, flat)
    tracker = FloorTracker(RATE_HZ, floor0=-1.0)
    ups, fls = [], []
    for a, b in zip([0, 7, 700, 701, 1999], [7, 700, 701, 1999, 3000], strict=True):
        u, f = tracker.update(p[a:b], flat[a:b])
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
