"""Truth stops of the modes-timeline figures (classifiers.timeline_eval) without the shared data."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from classifiers.artifacts import load_model
from classifiers.model import WindowResults
from classifiers.timeline_eval import coverage, mode_truth_stops, still_windows, timeline_figures
from pdr.io import read_recording
from pdr.recording import Labels
from tests.conftest import REPO_ROOT

SIM = REPO_ROOT / "mobile_logs" / "sim"


def _with_modes(spans: list[tuple[float, float, str]]):
    rec = read_recording(SIM / "pocket_office.zip")
    modes = Labels(np.array([a for a, _, _ in spans]), np.array([b for _, b, _ in spans]),
                   tuple(lab for *_, lab in spans))
    return replace(rec, truth=replace(rec.truth, modes=modes))


def test_mode_truth_stops_merge_still_spans_and_drop_short_ones():
    rec = _with_modes([(0.0, 1.5, "standing"), (1.5, 3.0, "sitting"), (3.0, 10.0, "walking"),
                       (10.0, 11.5, "stationary"), (11.5, 20.0, "walking"), (20.0, 22.5, "standing")])
    assert mode_truth_stops(rec) == [(0.0, 3.0, "standing"), (20.0, 22.5, "standing")]
    assert mode_truth_stops(rec, min_s=2.6) == [(0.0, 3.0, "standing")]


def test_still_windows_hold_the_hop_around_their_centre():
    t0 = np.array([0.0, 1.0, 2.0, 3.0])
    res = WindowResults(t0, t0 + 2.0, ("stationary", "walking", "sitting", "sitting"), np.ones(4),
                        np.zeros((4, 2)), np.zeros((4, 2)), ("a", "b"))
    stops = still_windows(res, hop_s=1.0)
    assert [(s.t_start_s, s.t_end_s) for s in stops] == [(0.5, 1.5), (2.5, 3.5), (3.5, 4.5)]
    assert coverage(stops, 2.5, 4.5) == pytest.approx(1.0)
    assert coverage(stops, 0.5, 2.5) == pytest.approx(0.5)


def test_stops_of_simulated_walks_judged_on_the_timeline_of_their_placement():
    recs = [read_recording(SIM / f"{n}.zip") for n in ("pocket_office", "torso_elevator", "foot_walk_run")]
    fig = timeline_figures(load_model("motion_mode"), recs)
    by_rec = {(s["recording"], round(s["t0_s"])): s for s in fig["stops"]}
    # The pocket phone's stops are the model's still windows, the torso phone's the step timeline's entries;
    # the shoe IMU has no phone timeline and no stop row.
    assert {k[0] for k in by_rec} == {"pocket_office.zip", "torso_elevator.zip"}
    assert by_rec[("pocket_office.zip", 0)]["timeline"] == "model"
    assert by_rec[("torso_elevator.zip", 9)]["timeline"] == "steps"
    assert fig["short_stops"] == 5 and fig["short_stops_found"] == 5
    assert fig["truth_stops"] == 0  # no landmark walk: the 5 s target has no case
