"""Floor legs and the step-mode timeline's figures on multi-floor walks (``pdr eval classifier --floors``)."""

from __future__ import annotations

import numpy as np
import pytest

from classifiers.floor_eval import floor_figures, floor_legs
from pdr.io import read_recording
from pdr.recording import GroundTruth, PositionTruth, Recording, SensorStream
from tests.conftest import data_path


def _landmark_walk(pos: list[tuple[float, float, float, float]]) -> Recording:
    """A still accelerometer with landmarks ``(t_s, east_m, north_m, floor)``."""
    t = np.arange(0, 60_000_000_000, 20_000_000, dtype=np.int64)
    acc = SensorStream("acc", t, np.tile([0.0, 0.0, 9.81], (t.size, 1)))
    p = np.array(pos, dtype=np.float64)
    truth = GroundTruth(positions=PositionTruth(p[:, 0], np.column_stack([p[:, 1:3], np.zeros(len(p))]), p[:, 3]))
    return Recording({"acc": acc}, truth=truth, source="walk", format="synthetic")


def test_floor_legs_split_stairs_from_elevator_by_the_horizontal_distance():
    rec = _landmark_walk([(0, 0, 0, 0), (10, 20, 0, 0), (20, 30, 0, -1), (30, 31, 0, -1), (40, 31, 1, 1)])
    legs = floor_legs(rec)
    assert [(leg.t0_s, leg.kind, leg.direction) for leg in legs] == [(10, "stairs", "down"), (30, "elevator", "up")]


def test_no_floor_legs_without_a_floor_change():
    assert floor_legs(_landmark_walk([(0, 0, 0, 0), (10, 20, 0, 0)])) == []
    assert floor_figures([_landmark_walk([(0, 0, 0, 0), (10, 20, 0, 0)])])["stairs_leg_share"] is None


@pytest.mark.data
@pytest.mark.slow
def test_elevator_walk_rides_reported_without_stairs():
    rec = read_recording(data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial53_repetition01.mat"))
    fig = floor_figures([rec])
    assert fig["elevator_rides"] == 4 and fig["elevator_rides_reported"] == 4
    assert fig["elevator_walk_stairs_steps"] == 0


@pytest.mark.data
def test_ipin_standing_labels_the_stop_between_two_landmarks_at_one_place():
    from classifiers.datasets import ipin_mode_labels, ipin_standing

    rec = read_recording(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial03_repetition01.txt"))
    stands = ipin_standing(rec)
    # The truth stop (landmarks at one place passed at 118 s and 154 s) is standing for most of its length.
    inside = sum(max(0.0, min(b, 154.0) - max(a, 118.0)) for a, b in stands)
    assert inside >= 0.8 * 36.0
    labels = ipin_mode_labels(rec)
    assert labels is not None and labels.at(np.array([136.0]))[0] == "standing"


@pytest.mark.data
@pytest.mark.slow
def test_stairs_legs_split_into_climbing_and_level_steps():
    rec = read_recording(data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial51_repetition01.mat"))
    fig = floor_figures([rec])
    for leg in fig["legs"]:
        assert leg["climbing_steps"] + leg["level_steps"] <= leg["steps"]  # the rest: barometric stairs the other way
    # Most of the legs' level steps (the walk to the stairs, the landings) show walking, not stairs.
    assert fig["level_steps"] > 0 and fig["level_walking"] >= 0.8 * fig["level_steps"]
    assert fig["climbing_share"] >= 0.85
