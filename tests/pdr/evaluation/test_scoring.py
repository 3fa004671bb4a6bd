"""The scorers of pdr.evaluation.scoring on tracks whose errors are known by construction."""

import math

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.evaluation.scoring import (
    alternating_contacts,
    alternating_step_count,
    bounce_free_step_count,
    distance_ratio,
    distance_ratio_same_floor,
    floors_at,
    landmark_errors,
    leg_direction_errors,
    match_steps,
    plain_step_count,
    step_count_error_pct,
    unmatched_by_phase,
    waypoint_errors,
)

# An L-shaped route through four landmarks at t = 0, 10, 20, 30 s: 10 m east, 10 m north, 10 m east.
TRUTH_T = np.array([0.0, 10.0, 20.0, 30.0])
TRUTH_EN = np.array([[5.0, 5.0], [15.0, 5.0], [15.0, 15.0], [25.0, 15.0]])


def _track(rotate_deg: float = 0.0, scale: float = 1.0, offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """The true route sampled every 0.5 s, rotated about its start, scaled and shifted."""
    t = np.arange(0.0, 30.01, 0.5)
    en = np.column_stack([np.interp(t, TRUTH_T, TRUTH_EN[:, 0]), np.interp(t, TRUTH_T, TRUTH_EN[:, 1])])
    a = math.radians(rotate_deg)
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return t, (en - TRUTH_EN[0]) @ r.T * scale + TRUTH_EN[0] + np.asarray(offset)


def test_a_perfect_track_anywhere_scores_zero():
    t, en = _track(offset=(100.0, -40.0))                 # translation to the first landmark is part of the score
    np.testing.assert_allclose(landmark_errors(t, en, TRUTH_T, TRUTH_EN), 0.0, atol=1e-12)
    np.testing.assert_allclose(waypoint_errors(t, en, TRUTH_T, TRUTH_EN), 0.0, atol=1e-12)
    assert distance_ratio(t, en, TRUTH_T, TRUTH_EN) == pytest.approx(1.0)


def test_a_rotated_track_costs_the_chord_unless_aligned():
    t, en = _track(rotate_deg=10.0)
    err = landmark_errors(t, en, TRUTH_T, TRUTH_EN)
    dist = np.linalg.norm(TRUTH_EN[1:] - TRUTH_EN[0], axis=1)
    np.testing.assert_allclose(err, 2 * dist * math.sin(math.radians(5.0)), rtol=1e-9)   # chord of 10 deg
    np.testing.assert_allclose(landmark_errors(t, en, TRUTH_T, TRUTH_EN, align="first-segment"), 0.0, atol=1e-9)
    np.testing.assert_allclose(waypoint_errors(t, en, TRUTH_T, TRUTH_EN), 0.0, atol=1e-9)   # least-squares rotation
    with pytest.raises(InputError, match="align must be"):
        landmark_errors(t, en, TRUTH_T, TRUTH_EN, align="best")


def test_leg_direction_errors_are_the_tracks_turn_away_from_each_true_leg():
    t, en = _track(rotate_deg=10.0, offset=(7.0, -3.0))    # counter-clockwise: each leg's bearing 10 deg less
    legs = leg_direction_errors(t, en, TRUTH_T, TRUTH_EN)
    assert [leg["true_deg"] for leg in legs] == pytest.approx([90.0, 0.0, 90.0])
    assert [leg["error_deg"] for leg in legs] == pytest.approx([-10.0, -10.0, -10.0])
    np.testing.assert_allclose([(leg["t0_s"], leg["t1_s"], leg["length_m"]) for leg in legs],
                               [(0.0, 10.0, 10.0), (10.0, 20.0, 10.0), (20.0, 30.0, 10.0)])
    # Across a bearing of north the error wraps into [-180, 180): a track 10 deg clockwise of north is +10.
    t2, en2 = _track(rotate_deg=-10.0)
    assert leg_direction_errors(t2, en2, TRUTH_T, TRUTH_EN)[1]["error_deg"] == pytest.approx(10.0)
    # A leg across floors, or shorter than min_leg_m, is no leg.
    floors = np.array([0.0, 0.0, 1.0, 1.0])
    assert [leg["t0_s"] for leg in leg_direction_errors(t, en, TRUTH_T, TRUTH_EN, floors)] == [0.0, 20.0]
    assert leg_direction_errors(t, en, TRUTH_T, TRUTH_EN, min_leg_m=10.5) == []


def test_the_hindsight_rotation_and_scale_undo_a_constant_heading_offset_and_step_scale():
    t, en = _track(rotate_deg=-25.0, scale=0.8, offset=(3.0, 4.0))
    dist = np.linalg.norm(TRUTH_EN[1:] - TRUTH_EN[0], axis=1)
    np.testing.assert_allclose(waypoint_errors(t, en, TRUTH_T, TRUTH_EN), 0.2 * dist, rtol=1e-9)   # rotation only
    np.testing.assert_allclose(waypoint_errors(t, en, TRUTH_T, TRUTH_EN, scale=True), 0.0, atol=1e-9)
    still = np.full_like(en, 7.0)                           # a track that never moves: no factor to fit
    np.testing.assert_allclose(waypoint_errors(t, still, TRUTH_T, TRUTH_EN, scale=True), dist, rtol=1e-12)


def test_scale_shows_in_the_distance_ratios_and_floor_changes_are_left_out():
    t, en = _track(scale=1.1)
    assert distance_ratio(t, en, TRUTH_T, TRUTH_EN) == pytest.approx(1.1)
    floors = np.array([0.0, 0.0, 1.0, 1.0])                # the middle interval climbs a floor
    assert distance_ratio_same_floor(t, en, TRUTH_T, TRUTH_EN, floors) == pytest.approx(1.1)
    # A detour inside the floor-changing interval does not count; one on a floor does.
    wiggle = en.copy()
    mid = (t > 10.0) & (t < 20.0)
    wiggle[mid, 0] += np.where(np.arange(mid.sum()) % 2 == 0, 1.0, -1.0)
    assert distance_ratio_same_floor(t, wiggle, TRUTH_T, TRUTH_EN, floors) == pytest.approx(1.1)
    assert distance_ratio(t, wiggle, TRUTH_T, TRUTH_EN) > 1.5
    assert math.isnan(distance_ratio_same_floor(t, en, TRUTH_T, TRUTH_EN, np.arange(4.0)))
    with pytest.raises(InputError, match="zero length"):
        distance_ratio(t, en, TRUTH_T, np.zeros((4, 2)))
    with pytest.raises(InputError, match="fewer than two positions"):
        landmark_errors(t[:1], en[:1], TRUTH_T, TRUTH_EN)


def test_contact_bounces_are_removed_and_the_step_count_error_is_in_percent():
    left = np.arange(0.0, 20.0, 1.0)
    right = np.concatenate([np.arange(0.5, 20.0, 1.0), [3.7, 9.62]])     # two bounces 0.2 and 0.12 s late
    assert bounce_free_step_count([left, np.sort(right)]) == 40
    assert bounce_free_step_count([np.array([1.0, 1.1])]) == 2          # too few edges to judge: all kept
    assert step_count_error_pct(103, 100) == pytest.approx(3.0)
    assert step_count_error_pct(95, 100) == pytest.approx(-5.0)
    with pytest.raises(InputError, match="must be positive"):
        step_count_error_pct(3, 0)


def test_a_switch_drop_out_is_filled_from_the_other_foot_and_nothing_else_is():
    left = np.arange(0.0, 30.0, 1.1)
    right = left + 0.55
    assert alternating_step_count(left, right) == 2 * left.size
    # The left switch silent for one stride, then for two (three contacts missed): the right foot kept walking.
    dropped = np.delete(left, [5, 12, 13])
    assert bounce_free_step_count([dropped, right]) == 2 * left.size - 3
    assert alternating_step_count(dropped, right) == 2 * left.size
    # With bounces too: removed first, then the drop-outs filled.
    bouncy = np.sort(np.concatenate([right, right[[3, 20]] + 0.15]))
    assert alternating_step_count(dropped, bouncy) == 2 * left.size
    # A foot missing before its first or after its last contact, or both switches silent together: not invented.
    assert alternating_step_count(left[3:-2], right) == 2 * left.size - 5
    both = np.arange(left.size) != 7
    assert alternating_step_count(left[both], right[both]) == 2 * left.size - 2
    # A stop: both feet stand still (no contacts of either), so the walk on each side is counted as it is.
    stop_l = np.concatenate([left, left + 40.0])
    stop_r = np.concatenate([right, right + 40.0])
    assert alternating_step_count(stop_l, stop_r) == 4 * left.size


def test_filled_contacts_sit_midway_between_the_other_foots():
    left = np.arange(0.0, 30.0, 1.1)
    right = left + 0.55
    dropped = np.delete(left, [5, 12, 13])
    got = alternating_contacts(dropped, right)
    assert got.size == alternating_step_count(dropped, right) == 2 * left.size
    # The missed left contacts come back halfway between the right foot's contacts around them: where they were.
    assert np.allclose(got, np.sort(np.concatenate([left, right])))


def test_unmatched_steps_are_placed_at_the_walk_start_middle_or_end():
    true = np.arange(0.0, 60.0, 0.55)
    det = true - 0.1                                     # the starts lead the contacts by 0.1 s
    none = {f"{k}_{p}": 0 for k in ("extra", "missed") for p in ("first", "mid", "last")}
    assert unmatched_by_phase(det, true) == none
    # The first contact missed, a push-off crossing 0.6 s before the walk, a double crossing mid-walk, the last missed.
    det2 = np.concatenate([[det[0] - 0.6], det[1:-1], [30.2]])
    u = unmatched_by_phase(det2, true)
    assert (u["missed_first"], u["extra_first"], u["extra_mid"], u["missed_mid"], u["missed_last"], u["extra_last"]) \
        == (1, 1, 1, 0, 1, 0)
    hit, used, lag = match_steps(det2, true, 0.35)
    assert lag == pytest.approx(0.1) and hit.sum() == used.sum() == true.size - 2
    assert unmatched_by_phase(det, np.zeros(0))["extra_mid"] == det.size


def test_the_plain_peak_counter_counts_a_clean_gait_signal():
    rate = 100.0
    t = np.arange(0.0, 20.0, 1.0 / rate)
    acc = np.column_stack([np.zeros(t.size), np.zeros(t.size), 9.81 + 2.0 * np.sin(2 * np.pi * 1.8 * t)])
    assert abs(plain_step_count(t, acc) - 36) <= 1
    assert plain_step_count(t[:1], acc[:1]) == 0


def test_floors_at_is_the_floor_in_effect_at_each_time():
    got = floors_at(np.array([0.0, 9.9, 10.0, 30.0, 50.0]), 0.0, np.array([10.0, 40.0]), np.array([-2.0, 0.0]))
    np.testing.assert_array_equal(got, [0.0, 0.0, -2.0, -2.0, 0.0])
