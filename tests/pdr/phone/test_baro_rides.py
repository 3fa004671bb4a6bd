"""Elevator rides from the barometer (pdr.phone.baro_rides): a climb stood through and walked out of."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io.registry import read_recording
from pdr.phone.baro_rides import BaroRide, BaroRides
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, PipelineConfig
from tests.conftest import REPO_ROOT, data_path

RATE_HZ = 10.0


def _legs(*legs: tuple[str, float, float]) -> tuple[np.ndarray, ...]:
    """Samples of ``(what, seconds, vertical speed m/s)`` legs, ``what`` one of ``walk``, ``stand``, ``ride``:
    the floor tracker's ``t_s``, ``moving`` (speed of 0.2 m/s or more), ``walking``, ``up_m`` and ``rate_mps``.
    """
    walking, rate = [], []
    for what, seconds, speed in legs:
        n = int(seconds * RATE_HZ)
        walking.append(np.full(n, what == "walk"))
        rate.append(np.full(n, speed))
    v = np.concatenate(rate)
    up = np.concatenate([[0.0], np.cumsum(v)[:-1]]) / RATE_HZ         # the altitude at each sample's start
    return np.arange(v.size) / RATE_HZ, np.abs(v) >= 0.2, np.concatenate(walking), up, v


def _run(samples: tuple[np.ndarray, ...], cuts: tuple[int, ...] = ()) -> tuple[list[BaroRide], BaroRides]:
    """Rides of the samples fed in batches split at ``cuts``, the state saved and restored between batches."""
    rides: list[BaroRide] = []
    det = BaroRides(RATE_HZ)
    edges = [0, *cuts, samples[0].size]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        t_s, moving, walking, up_m, rate_mps = (x[a:b] for x in samples)
        rides += det.update(t_s, moving, walking, up_m, rate_mps, 1.25)
        det = BaroRides.from_state(det.state())
    return rides, det


def test_a_ride_stood_through_and_walked_out_of_is_reported_once_the_rider_walks():
    # Walk in, wait, ride two 3 m floors down at 1 m/s, wait for the doors, walk out.
    s = _legs(("walk", 10, 0), ("stand", 5, 0), ("ride", 6, -1.0), ("stand", 3, 0), ("walk", 10, 0))
    rides, _ = _run(s)
    assert len(rides) == 1
    r = rides[0]
    assert (r.start, r.end) == (150, 210) and (r.t_start_s, r.t_end_s) == (15.0, 21.0)
    assert r.altitude_change_m == pytest.approx(-6.0)
    # Batches of any size, the state saved and restored between them, report the same ride.
    for cuts in ((1,), (150, 151), (100, 170, 209, 211, 239, 240, 241)):
        assert _run(s, cuts)[0] == rides


def test_a_cabin_that_stops_on_the_way_with_the_rider_in_it_is_one_ride():
    s = _legs(("walk", 5, 0), ("ride", 3, 1.0), ("stand", 4, 0), ("ride", 3, 1.0), ("stand", 2, 0), ("walk", 5, 0))
    rides, _ = _run(s, (70,))
    assert len(rides) == 1 and rides[0].altitude_change_m == pytest.approx(6.0)
    assert (rides[0].t_start_s, rides[0].t_end_s) == (5.0, 15.0)


@pytest.mark.parametrize("legs", [
    # A car climbing a hill: nobody walks off it within walk_out_s.
    (("walk", 5, 0), ("stand", 5, 0), ("ride", 10, 0.5), ("stand", 30, 0), ("walk", 5, 0)),
    # Stairs: the climb is walked.
    (("walk", 5, 0), ("walk", 10, 0.3), ("walk", 5, 0)),
    # An escalator: at most 0.375 m/s (EN 115-1).
    (("walk", 5, 0), ("ride", 20, 0.3), ("stand", 1, 0), ("walk", 5, 0)),
    # Less than half a floor: a ramp, or the weather.
    (("walk", 5, 0), ("ride", 1, 1.0), ("stand", 1, 0), ("walk", 5, 0)),
])
def test_no_ride_from_a_road_stairs_an_escalator_or_a_small_change(legs):
    rides, det = _run(_legs(*legs))
    assert rides == [] and det.pending is None


def test_bad_input_and_state_are_named():
    det = BaroRides(RATE_HZ)
    with pytest.raises(InputError, match="one value per sample"):
        det.update(np.zeros(3), np.zeros(3, bool), np.zeros(2, bool), np.zeros(3), np.zeros(3), 1.25)
    with pytest.raises(InputError, match="barometric ride state"):
        BaroRides.from_state({"rate_hz": 10.0})


def test_the_simulated_elevator_ride_is_an_elevator_event_of_the_pipeline():
    # mobile_logs/sim/torso_elevator: walk to an elevator, ride two floors up (5.6 m), walk out. The impulse
    # detector missed it; the barometer does not.
    rec = read_recording(REPO_ROOT / "mobile_logs" / "sim" / "torso_elevator.zip")
    pipe = PdrPipeline(PipelineConfig())
    rides = [e for e in pipe.run(rec) if e["type"] == "elevator"]
    assert len(rides) == 1 and rides[0]["direction"] == "up" and rides[0]["altitude_change_m"] > 4.5
    assert rides[0]["source"] == "barometer"
    assert pipe.elevator.steps == []       # the impulse detector is not fed: its state stays small


@pytest.mark.data
@pytest.mark.slow
def test_every_ride_of_the_ipin_elevator_walk_is_an_elevator_event_with_its_floor_count():
    # IPIN 2023 .mat trial 53 rides the museum's slow lift (0.4 m/s) between floors 0 and -2 four times; the site
    # gives the floors' altitudes. The stairs walk (trial 52) has no ride.
    site = Site.load(REPO_ROOT / "docs" / "sites" / "ipin2023_museum_floors.json")
    rec = read_recording(data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial53_repetition01.mat"))
    rides = [e for e in PdrPipeline(PipelineConfig(initial_floor=0.0), site).run(rec) if e["type"] == "elevator"]
    assert [(e["direction"], e["floors"]) for e in rides] == [("down", 2), ("up", 2), ("down", 2), ("up", 2)]
    truth = rec.truth.positions
    assert truth is not None and truth.floor is not None
    t_truth = rec.origin_ns / 1e9 + truth.t_s
    for e in rides:        # between the last landmark before the ride and the first after it, on another floor
        before = truth.floor[t_truth < e["t_start_s"]][-1]
        after = truth.floor[t_truth > e["t_end_s"]][0]
        assert abs(after - before) == 2
    stairs = read_recording(data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial52_repetition01.mat"))
    assert not [e for e in PdrPipeline(PipelineConfig(initial_floor=0.0), site).run(stairs)
                if e["type"] == "elevator"]
