"""The placement detector's evaluation: labels grouped as the pipeline groups them, the confusion matrix, and the
detector run on recordings whose label was taken off."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from pdr.evaluation.placement import (
    RecordingPlacement,
    detected_placements,
    evaluate_recording,
    summary,
    true_placement,
)
from pdr.io import read_recording
from tests.conftest import REPO_ROOT, data_path


def test_labels_are_grouped_as_the_pipeline_groups_placements():
    rec = read_recording(REPO_ROOT / "mobile_logs" / "sim" / "pocket_office.zip")
    assert rec.device.placement is not None
    assert true_placement(rec, Path("pocket_office.zip")) == "pocket"


def test_the_confusion_counts_steps_and_a_torso_phone_read_as_held_is_right():
    results = [RecordingPlacement("ipin2023_t3", "a", "hand", Counter(hand=90, pocket=10), 2),
               RecordingPlacement("oxford_step_counter", "b", "torso", Counter(hand=40), 0),
               RecordingPlacement("oxford_step_counter", "c", "pocket", Counter(hand=30, pocket=10), 1),
               RecordingPlacement("oxford_step_counter", "d", "pocket", Counter(hand=50), 0, has_gyro=False)]
    s = summary(results)
    assert s["all"]["confusion"]["hand"] == {"hand": 90, "pocket": 10, "swinging": 0, "none": 0}
    assert s["all"]["steps"] == 180 and s["all"]["right"] == pytest.approx((90 + 40 + 10) / 180)
    assert s["by_dataset"]["oxford_step_counter"]["recordings"] == 2 and s["changes"] == 3
    assert [w["recording"] for w in s["mostly_wrong"]] == ["c"]
    assert s["without_gyroscope"] == {"recordings": 1, "steps": 50, "datasets": ["oxford_step_counter"]}


def test_the_detector_names_the_simulated_pocket_walk_without_its_label():
    rec = read_recording(REPO_ROOT / "mobile_logs" / "sim" / "pocket_office.zip")
    steps = detected_placements(rec)
    assert len(steps) > 20 and Counter(steps)["pocket"] > 0.8 * len(steps)


@pytest.mark.slow
def test_real_hand_held_and_pocket_walks():
    ipin = evaluate_recording("ipin2023_t3", data_path("ipin2023_t3", "logfiles",
                                                       "IPIN2023_T3_TrainingTrial01_repetition01.txt"))
    pocket = evaluate_recording("attitude_smartphones", data_path("attitude_smartphones", "android",
                                                                  "Guillaume_Nexus5_NoDist_FrontPocket"))
    assert ipin is not None and ipin.label == "hand" and ipin.right > 0.9
    assert pocket is not None and pocket.label == "pocket" and pocket.right > 0.9
