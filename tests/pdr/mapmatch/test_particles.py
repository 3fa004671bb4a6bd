"""The map-matching particle filter: walls correct heading and scale errors, resumes bit-identically, suspends."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pdr import state_codec
from pdr.errors import InputError
from pdr.mapmatch.particles import MapMatchConfig, MapMatcher, StepInput, smooth_walk
from pdr.mapmatch.rows import match_rows
from pdr.site.plan import SitePlan

# An L-shaped corridor 2 m wide: east along y in [0, 2] for 30 m, then north along x in [28, 30] for 30 m.
L_CORRIDOR = [[0, 0], [30, 0], [30, 30], [28, 30], [28, 2], [0, 2], [0, 0]]


def corridor_site() -> SitePlan:
    return SitePlan.from_dict({"floors": [{"floor": 0, "walkable": {"type": "Polygon", "coordinates": [L_CORRIDOR]}}]})


def l_walk(heading_error_deg: float, length_scale: float, step_m: float = 0.7) -> tuple[list[StepInput], np.ndarray]:
    """Steps along the corridor's centre line, measured with a heading error and a step-length scale; the truth."""
    steps, truth, t = [], [], 0.0
    pos = np.array([1.0, 1.0])
    for leg_heading, n in ((90.0, 41), (0.0, 40)):       # east 28.7 m, then north 28 m
        for _ in range(n):
            t += 0.55
            yaw = math.radians(90.0 - leg_heading)
            pos = pos + step_m * np.array([math.cos(yaw), math.sin(yaw)])
            truth.append(pos.copy())
            steps.append(StepInput(t, step_m * length_scale, leg_heading + heading_error_deg, 0))
    return steps, np.array(truth)


def dead_reckoning(steps: list[StepInput], start: tuple[float, float]) -> np.ndarray:
    yaw = np.radians(90.0 - np.array([s.heading_deg for s in steps]))
    d = np.array([s.length_m for s in steps])[:, None] * np.column_stack([np.cos(yaw), np.sin(yaw)])
    return np.asarray(start) + np.cumsum(d, axis=0)


def test_walls_correct_a_heading_error_and_a_long_step_length() -> None:
    steps, truth = l_walk(heading_error_deg=12.0, length_scale=1.15)
    pdr_err = np.linalg.norm(dead_reckoning(steps, (1.0, 1.0)) - truth, axis=1)
    matched, notices = MapMatcher(corridor_site(), (1.0, 1.0), 0).update(steps)
    mm = np.array([[m.east_m, m.north_m] for m in matched])
    err = np.linalg.norm(mm - truth, axis=1)
    assert notices == []
    assert all(m.matched for m in matched)
    assert pdr_err[-1] > 10.0
    assert err[-1] < 2.0 and np.percentile(err, 75) < 2.0
    assert matched[-1].scale < 0.95                    # it learnt that the measured steps are too long
    smoothed, _ = smooth_walk(corridor_site(), steps, (1.0, 1.0), 0)
    sm = np.array([[m.east_m, m.north_m] for m in smoothed])
    assert np.percentile(np.linalg.norm(sm - truth, axis=1), 75) < 2.0


def test_the_state_resumes_bit_identically_through_the_state_codec() -> None:
    steps, _ = l_walk(heading_error_deg=-8.0, length_scale=0.9)
    wobble = np.random.default_rng(1).normal(0.0, 4.0, len(steps))      # the gyro's heading differs step by step
    steps = [replace(s, gyro_heading_deg=s.heading_deg + 40.0 + w) for s, w in zip(steps, wobble, strict=True)]
    whole, _ = MapMatcher(corridor_site(), (1.0, 1.0), 0).update(steps)
    first = MapMatcher(corridor_site(), (1.0, 1.0), 0)
    a, _ = first.update(steps[:37])
    blob = state_codec.dumps(first.state())
    second = MapMatcher.from_state(corridor_site(), state_codec.loads(blob))
    b, _ = second.update(steps[37:])
    assert a + b == whole
    assert len(blob) < 100_000           # bounded: particle arrays, not the walk
    with pytest.raises(InputError, match="version"):
        MapMatcher.from_state(corridor_site(), {"version": 0})


def test_when_every_particle_dies_matching_is_suspended_and_the_track_goes_on() -> None:
    # Walk east out of the corridor's open end? It has none: walk west through the wall at x = 0 instead.
    steps = [StepInput(0.5 * k, 0.7, 270.0, 0) for k in range(1, 12)]
    matched, notices = MapMatcher(corridor_site(), (1.0, 1.0), 0).update(steps)
    assert any("suspended" in n for n in notices)
    assert not matched[-1].matched
    assert matched[-1].east_m < -1.5                  # dead reckoning goes on past the wall
    # and a walk that comes back into the plan is matched again
    back = [StepInput(10 + 0.5 * k, 0.7, 90.0, 0) for k in range(1, 12)]
    mm = MapMatcher(corridor_site(), (1.0, 1.0), 0)
    out, notes = mm.update(steps + back)
    assert any("resumed" in n for n in notes) and out[-1].matched


def test_a_start_outside_the_walkable_area_or_on_an_unknown_floor_is_refused() -> None:
    with pytest.raises(InputError, match="outside floor 0's walkable area") as exc:
        MapMatcher(corridor_site(), (10.0, 10.0), 0, source="--start")
    assert exc.value.field == "start"
    with pytest.raises(InputError, match="no floor plan for floor 2"):
        MapMatcher(corridor_site(), (1.0, 1.0), 2)


def test_match_rows_keeps_the_rows_and_maps_floors_relative_to_the_start() -> None:
    rows = [{"t_s": 0.5 * k, "step_length_m": 0.7, "heading_deg": 90.0, "floor": 2.0, "mode": "walking"}
            for k in range(1, 6)]
    site = SitePlan.from_dict({"floors": [{"floor": 5, "walkable": {"type": "Polygon",
                                                                    "coordinates": [L_CORRIDOR]}}]})
    out, notices = match_rows(rows, site, (1.0, 1.0), 5, MapMatchConfig(particles=200))
    assert [r["floor"] for r in out] == [5.0] * 5 and [r["mode"] for r in out] == ["walking"] * 5
    assert out[-1]["east_m"] == pytest.approx(1.0 + 3.5, abs=1.0) and notices == []


# A corridor 2 m wide (y in [0, 2]) from x = 0 to 20 that opens into a hall 40 m square: no wall near the walk there.
CORRIDOR_HALL = [[0, 0], [20, 0], [20, -20], [60, -20], [60, 22], [20, 22], [20, 2], [0, 2], [0, 0]]


def hall_walk(gyro: bool) -> tuple[list[StepInput], np.ndarray]:
    """East along the corridor's centre line into the hall, 0.7 m steps. The step heading reads 15 deg too far
    clockwise in the corridor, and 25 deg too far anticlockwise in the hall from step 30 on (a disturbed field); the
    gyro's heading (its own origin, 123 deg) has no error.
    """
    steps, truth = [], []
    for k in range(1, 66):
        truth.append([1.0 + 0.7 * k, 1.0])
        error = 15.0 if k < 30 else -25.0
        steps.append(StepInput(0.55 * k, 0.7, 90.0 + error, 0, 123.0 + 90.0 if gyro else None))
    return steps, np.array(truth)


def test_the_gyro_carries_the_offset_the_walls_taught_through_a_disturbed_field() -> None:
    site = SitePlan.from_dict({"floors": [{"floor": 0, "walkable": {"type": "Polygon",
                                                                    "coordinates": [CORRIDOR_HALL]}}]})
    end_err = {}
    for gyro in (True, False):
        steps, truth = hall_walk(gyro)
        matched, notices = MapMatcher(site, (1.0, 1.0), 0).update(steps)
        assert notices == []
        end_err[gyro] = math.hypot(matched[-1].east_m - truth[-1, 0], matched[-1].north_m - truth[-1, 1])
        assert abs(matched[28].heading_offset_deg - 15.0) < 5.0   # the corridor taught the offset (anticlockwise)
    assert end_err[True] < 2.5                 # the hall's 40 deg disturbance did not move the matched heading
    assert end_err[False] > 8.0                # without the gyro the particles follow it (40 deg over 25 m)
    # (b): relaxing towards the magnetometer's heading over 5 m undoes the taught offset in the hall
    steps, truth = hall_walk(True)
    relaxed, _ = MapMatcher(site, (1.0, 1.0), 0, MapMatchConfig(mag_distance_m=5.0)).update(steps)
    assert abs(relaxed[-1].heading_offset_deg) < abs(relaxed[28].heading_offset_deg) / 2


def test_a_wandering_heading_in_a_corridor_does_not_teach_a_short_stride() -> None:
    # A straight corridor 2 m wide walked with the true stride (scale 1) and a step heading that wanders about its
    # axis: the particles that die graze the side walls. Were the scale inherited from the survivors, the short
    # striders (who drift sideways more slowly) would be selected; a grazing death keeps its own scale.
    site = SitePlan.from_dict({"floors": [{"floor": 0, "walkable": {
        "type": "Polygon", "coordinates": [[[0, 0], [80, 0], [80, 2], [0, 2], [0, 0]]]}}]})
    final = {}
    for graze in (0.0, 45.0):
        scales = []
        for seed in range(5):
            wander = np.cumsum(np.random.default_rng(seed).normal(0.0, 1.5, 100))     # deg
            steps = [StepInput(0.55 * (k + 1), 0.7, 90.0 + w, 0) for k, w in enumerate(wander)]
            matched, _ = MapMatcher(site, (1.0, 1.0), 0, MapMatchConfig(graze_deg=graze, seed=seed)).update(steps)
            assert all(m.matched for m in matched)
            scales.append(matched[-1].scale)
        final[graze] = float(np.mean(scales))
    assert final[0.0] < 0.99                # the survivor bias when every death teaches the stride
    assert abs(final[45.0] - 1.0) < 0.01
