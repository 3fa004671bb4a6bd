"""The modes timeline's figures on real recordings (``pdr eval classifier MODEL --timeline``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from classifiers.artifacts import load_model
from classifiers.timeline_eval import timeline_figures, truth_stops
from pdr.cli import main
from pdr.io import read_recording
from tests.conftest import REPO_ROOT, data_path

pytestmark = pytest.mark.data


def test_truth_stops_of_ipin_landmarks():
    rec = read_recording(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial03_repetition01.txt"))
    assert [(round(a), round(b), k) for a, b, k in truth_stops(rec)] == [(118, 154, "standing")]
    rides = truth_stops(read_recording(data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial53_repetition01.mat")))
    assert [k for *_, k in rides] == ["elevator_down", "standing", "elevator_up", "standing", "elevator_down",
                                      "standing", "elevator_up"]


def test_timeline_figures_stop_pocket_rest_and_driving():
    recs = [read_recording(p) for p in (
        data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial03_repetition01.txt"),
        REPO_ROOT / "mobile_logs" / "sim" / "pocket_office.zip",
        data_path("driving_phone_mount", "17"))]
    fig = timeline_figures(load_model("motion_mode"), recs)
    assert fig["truth_stops"] == fig["truth_stops_found"] == 1
    # Stops of 2 s or more: the walk's landmark stop and the simulated pocket walk's two, each its own entry.
    assert fig["short_stops"] == fig["short_stops_found"] == 3
    office = next(w for w in fig["walks"] if w["recording"] == "pocket_office.zip")
    assert office["vehicle_labels"] == 0 and office["ungated_vehicle_labels"] > 0  # the gate is what removes them
    assert fig["driving"][0]["vehicle_fraction"] >= 0.9


def test_eval_classifier_timeline_cli(tmp_path, capsys):
    log = REPO_ROOT / "mobile_logs" / "sim" / "pocket_office.zip"
    assert main(["eval", "classifier", "motion_mode", "--timeline", "--data", str(log), "--json"]) == 0
    fig = json.loads(capsys.readouterr().out)
    assert fig["walk_recordings"] == 1 and fig["walk_vehicle_windows"] == 0


def test_eval_classifier_targets_cli(capsys):
    sim = REPO_ROOT / "mobile_logs" / "sim"
    logs = [str(sim / "pocket_office.zip"), str(sim / "hand_escalator.zip")]
    assert main(["eval", "classifier", "motion_mode", "--targets", "--data", *logs, "--json"]) == 0
    fig = json.loads(capsys.readouterr().out)
    by_name = {r["target"]: r for r in fig["targets"]}
    walks = by_name["walking recordings with a car_*/vehicle label"]
    assert walks["value"] == "0 of 2" and walks["met"] is True
    stops = by_name["stops of 2 s or more appearing as their own (still) entry"]
    assert stops["value"] == "4 of 4" and stops["met"] is True  # each walk starts and ends standing
    # No landmarks, no car trip, no floor legs in simulated logs: those targets say so instead of passing.
    assert by_name["stops of 5 s or more (IPIN landmarks) appearing as standing"]["met"] is None
    assert by_name["driving windows labelled vehicle"]["met"] is None
    assert by_name["elevator rides reported with the right floor count"]["met"] is None


def test_timeline_scores_of_a_hand_held_walk_with_a_stop():
    from classifiers.timeline_scores import timeline_scores, truth_labels

    rec = read_recording(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial03_repetition01.txt"))
    t = np.array([100.0, 130.0, 160.0])
    assert list(truth_labels(rec, t)) == ["walking", "standing", "walking"]  # landmark 7 passed twice, 118-154 s
    fig = timeline_scores([rec])
    hand = fig["groups"]["hand"]
    assert hand["per_class"]["standing"]["support"] == pytest.approx(154 - 118, abs=1.0)
    assert hand["per_class"]["standing"]["recall"] > 0.7 and hand["per_class"]["walking"]["f1"] > 0.9


def test_step_timeline_label_at():
    from classifiers.step_timeline import StepTimeline

    tl = StepTimeline(np.zeros(0), np.zeros(0), np.zeros(0, dtype=object), (),
                      ((0.0, "walking"), (5.0, "standing"), (9.0, "walking")))
    assert list(tl.label_at(np.array([-1.0, 0.0, 4.9, 5.0, 8.0, 20.0]))) == [
        "", "walking", "walking", "standing", "standing", "walking"]


def test_step_timeline_spans_end_a_stop_at_its_own_end_and_the_rest_at_the_next_entry():
    from classifiers.step_timeline import StepTimeline
    from classifiers.timeline import ModeEntry

    stop = ModeEntry(5.0, 8.0, "standing")
    tl = StepTimeline(np.zeros(0), np.zeros(0), np.zeros(0, dtype=object), (stop,),
                      ((0.0, "walking"), (5.0, "standing"), (9.0, "walking")))
    assert tl.spans(20.0) == [(0.0, 5.0, "walking"), (5.0, 8.0, "standing"), (9.0, 20.0, "walking")]
    assert tl.spans(3.0)[-1] == (9.0, 9.0, "walking")          # an end before the last entry: an empty span
