"""Error budget (pdr.evaluation.error_budget, ``pdr eval ipin --budget``) and re-walking a track
(pdr.phone.track.redo_steps).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.evaluation.error_budget import BUDGET_TRACKS, budget_tracks, leg_headings
from pdr.evaluation.scoring import landmark_errors
from pdr.phone.track import dead_reckon, redo_steps

# An L-shaped route: 10 m east, then 10 m north, one 1-m step per second; landmarks at the corners.
T_TRUTH = np.array([0.0, 10.0, 20.0])
EN_TRUTH = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])


def _track(heading_error_deg: float, length_m: float) -> list[dict[str, Any]]:
    """The route walked with every heading off by ``heading_error_deg`` and steps of ``length_m`` (a first row of
    no length at the first landmark's time)."""
    heading = np.where(np.arange(21) <= 10, 90.0, 0.0) + heading_error_deg
    yaw = np.radians(90.0 - heading)
    length = np.r_[0.0, np.full(20, length_m)]
    en = dead_reckon(length, yaw)
    return [{"t_s": float(k), "east_m": float(en[k, 0]), "north_m": float(en[k, 1]),
             "heading_deg": float(heading[k]), "step_length_m": float(length[k])} for k in range(21)]


def _errors(rows: list[dict[str, Any]]) -> np.ndarray:
    t = np.array([r["t_s"] for r in rows])
    en = np.array([[r["east_m"], r["north_m"]] for r in rows])
    return landmark_errors(t, en, T_TRUTH, EN_TRUTH, "none")


def test_leg_headings_are_the_straight_lines_between_landmarks() -> None:
    t = np.array([0.0, 5.0, 10.0, 15.0, 25.0])
    h = leg_headings(t, T_TRUTH, EN_TRUTH)
    np.testing.assert_allclose(h[1:4], [90.0, 90.0, 0.0])     # a step ending at a landmark belongs to its leg
    assert np.isnan(h[0]) and np.isnan(h[4])                  # before the first, after the last landmark
    # A leg across floors or shorter than min_leg_m has no heading.
    assert np.isnan(leg_headings(t, T_TRUTH, EN_TRUTH, floors=np.array([0.0, 1.0, 1.0]))[1])
    assert np.isnan(leg_headings(t, T_TRUTH, EN_TRUTH, min_leg_m=11.0)).all()


def test_truth_heading_and_scale_remove_both_errors() -> None:
    rows = _track(heading_error_deg=8.0, length_m=1.1)
    tracks = budget_tracks(rows, T_TRUTH, EN_TRUTH)
    assert list(tracks) == list(BUDGET_TRACKS)
    assert _errors(rows).max() > 2.0
    np.testing.assert_allclose(_errors(tracks["truth_heading_and_scale"]), 0.0, atol=1e-9)
    # Truth heading alone leaves the 10 % of length; truth scale alone the route turned by 8 degrees about its
    # start (a chord of 2 sin(4 deg) times the 14.1 m from start to end).
    np.testing.assert_allclose(_errors(tracks["truth_heading"]), [1.0, math.hypot(1.0, 1.0)], atol=1e-9)
    assert _errors(tracks["truth_scale"])[-1] == pytest.approx(math.hypot(10, 10) * 2 * math.sin(math.radians(4.0)))
    assert budget_tracks(rows[:1], T_TRUTH, EN_TRUTH) == {}


def test_redo_steps_keeps_position_fixes_and_checks_shapes() -> None:
    rows = _track(heading_error_deg=0.0, length_m=1.0)
    rows[12]["position_fix"] = True
    yaw = np.radians(90.0 - np.array([r["heading_deg"] for r in rows]) + 5.0)
    out = redo_steps(rows, yaw, np.full(21, 0.9))
    # Up to the fix the shifts add up. The pipeline sets a fix before the step's own displacement: the fix's row
    # is the landmark plus its new step, and the later rows go on from there.
    assert out[11]["east_m"] != rows[11]["east_m"]
    landmark = np.array([rows[12]["east_m"], rows[12]["north_m"]]) - np.array([0.0, 1.0])
    for k in (12, 13):
        walked = sum(0.9 * np.array([math.cos(yaw[j]), math.sin(yaw[j])]) for j in range(12, k + 1))
        np.testing.assert_allclose([out[k]["east_m"], out[k]["north_m"]], landmark + walked, atol=1e-12)
    assert out[5]["step_length_m"] == 0.9 and out[5]["heading_deg"] == pytest.approx(rows[5]["heading_deg"] - 5.0)
    with pytest.raises(InputError, match="one yaw and one length per step"):
        redo_steps(rows, yaw[:-1])
