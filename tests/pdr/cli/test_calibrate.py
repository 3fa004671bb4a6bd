"""``pdr calibrate`` helpers (landmark walk, calibration on other logs) and ``pdr eval ipin --calibrate``."""

import json
import re

import numpy as np
import pytest

from pdr.cli import main
from pdr.cli.calibrate import CalibrationWalk, calibrate_on_walks, calibration_partners, landmark_walk, trial_key
from pdr.errors import InputError
from pdr.phone.step_length import StepLengthModel
from tests.conftest import data_path


def _rows(t_end, p1, mode="walking"):
    return [{"t_s": float(t), "patterns": [float(p), 0, 0, 0, 0, 0], "mode": mode}
            for t, p in zip(t_end, p1, strict=True)]


def test_landmark_walk_keeps_the_intervals_on_one_floor():
    # Landmarks: 10 m east on floor 0, then a floor change (stairs), then 6 m north on floor 1.
    t_truth = np.array([0.0, 10.0, 30.0, 40.0])
    pos = np.array([[0.0, 0.0], [10.0, 0.0], [12.0, 3.0], [12.0, 9.0]])
    floor = np.array([0.0, 0.0, 1.0, 1.0])
    t_end = np.arange(0.5, 40.01, 0.5)
    rows = _rows(t_end, np.full(t_end.size, 2.0))
    w = landmark_walk(rows, t_truth, pos, floor)
    assert w is not None
    assert w.length_m == pytest.approx(16.0)
    assert w.patterns.shape[0] == 20 + 20           # steps ending in (0, 10] and (30, 40]
    assert not w.on_stairs.any()
    one_floor = landmark_walk(rows, t_truth, pos, None)   # all intervals, including the straight 3.6 m
    assert one_floor is not None and one_floor.length_m == pytest.approx(16.0 + np.hypot(2.0, 3.0))
    assert landmark_walk(rows[:3], t_truth, pos, floor) is None


def test_calibrating_on_other_walks_recovers_the_walkers_k():
    """Two walks of one walker whose steps follow eq. 19 with K = 0.55: the scale of a third is predicted."""
    rng = np.random.default_rng(1)
    walker = StepLengthModel(k=0.55)
    walks = []
    for n in (40, 70):
        pats = rng.uniform(1.4, 2.0, (n, 6))
        stairs = np.zeros(n, bool)
        stairs[5:12] = True
        walks.append(CalibrationWalk(pats, stairs, float(np.sum(walker.length(pats, stairs)))))
    got = calibrate_on_walks(StepLengthModel(), walks)
    assert got.k == pytest.approx(0.55, rel=1e-9)
    # A walk that turns covers less ground per step (pdr.phone.step_length turn factor): its rows' turn_deg count.
    t_end = np.arange(0.5, 30.01, 0.5)
    rows = _rows(t_end, rng.uniform(1.4, 2.0, t_end.size))
    for i, r in enumerate(rows):
        r["turn_deg"] = 40.0 if i % 5 == 0 else 0.0
    turns = np.radians([r["turn_deg"] for r in rows])
    walked = float(np.sum(walker.length(np.array([r["patterns"] for r in rows]), False, turns)))
    turning = landmark_walk(rows, np.array([0.0, 30.0]), np.array([[0.0, 0.0], [walked, 0.0]]))
    assert turning is not None and np.allclose(turning.turns(), turns)
    assert calibrate_on_walks(StepLengthModel(), [turning]).k == pytest.approx(0.55, rel=1e-9)
    with pytest.raises(InputError, match="no calibration walk"):
        calibrate_on_walks(StepLengthModel(), [])


def test_partners_are_never_the_evaluated_log():
    routes = ["T1", "T1", "T2", "T2", "T3"]
    phones = ["A", "A", "A", "B", "A"]
    usable = [True, True, True, True, False]
    assert calibration_partners(0, routes, phones, usable, "cross") == [2]       # T3 has no walk, T2/B other phone
    assert calibration_partners(0, routes, phones, usable, "cross-rep") == [1]
    assert calibration_partners(3, routes, phones, usable, "cross") == []
    assert calibration_partners(2, routes, phones, usable, "cross-rep") == []
    assert trial_key("IPIN2023_T3_TrainingTrial21_repetition02.txt") == "Trial21"
    assert trial_key("walk.csv") == "walk.csv"
    with pytest.raises(InputError):
        calibration_partners(0, routes, phones, usable, "self")


@pytest.mark.slow
def test_eval_ipin_cross_calibration_fixes_the_other_walker(tmp_path, capsys):
    """SM-G930F logs (another actor, longer strides): the default model is 12-19 % short on trial 21;
    K calibrated on that phone's trial 26 (never on trial 21) brings it within 10 %."""
    logdir = data_path("ipin2023_t3", "logfiles")
    for name in ("IPIN2023_T3_TrainingTrial21_repetition01.txt", "IPIN2023_T3_TrainingTrial26_repetition01.txt",
                 "IPIN2023_T3_TrainingTrial26_repetition02.txt"):
        (tmp_path / name).symlink_to(logdir / name)
    assert main(["eval", "ipin", str(tmp_path), "--placement", "hand", "--calibrate", "cross", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    by = {f["file"]: f for f in out["files"]}
    t21 = by["IPIN2023_T3_TrainingTrial21_repetition01.txt"]
    assert t21["phone"] == "SM-G930F"
    assert sorted(t21["calibrated"]["calibrated_on"]) == ["IPIN2023_T3_TrainingTrial26_repetition01.txt",
                                                         "IPIN2023_T3_TrainingTrial26_repetition02.txt"]
    assert t21["distance_ratio_same_floor"] < 0.88
    assert abs(t21["calibrated"]["distance_ratio_same_floor"] - 1) < 0.10
    for f in out["files"]:
        m = re.search(r"Trial\d+", f["file"])
        assert m is not None
        route = m.group(0)
        assert all(route not in c for c in f["calibrated"]["calibrated_on"])
    assert out["overall"]["calibrated"]["files"] == 3
    # The calibrated tracks are also scored after the offline heading smoother (pdr track's default); the
    # smoother leaves the step lengths, so the distance ratio is the calibrated one.
    sm = t21["calibrated"]["smoothed"]
    assert sm["distance_ratio_same_floor"] == pytest.approx(t21["calibrated"]["distance_ratio_same_floor"], rel=0.02)
    assert out["overall"]["calibrated"]["smoothed"]["files"] == 3 and "_abs" not in sm
