"""Walking-direction and attitude scoring against motion capture (pdr.evaluation.heading)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.cli import main
from pdr.errors import InputError
from pdr.evaluation import heading as ev
from pdr.frames import yaw_to_heading_deg
from pdr.io import tyrex
from pdr.phone.pipeline import PipelineConfig
from tests.pdr.io.dataset_samples import sample_path
from tests.pdr.io.test_tyrex import ALIGN_TRUE, DURATION, T_START, WALK_YAW, write_recording


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A synthetic benchmark recording (tests.pdr.io.test_tyrex): a straight walk at 30 degrees ENU yaw."""
    return tyrex.read(write_recording(tmp_path_factory.mktemp("bench"), align_file=ALIGN_TRUE))


def _rows(yaw_rad: float, period_s: float = 0.5) -> list[dict]:
    t0 = np.arange(T_START + 2.0, T_START + DURATION - 2.0, period_s)
    return [{"t_start_s": float(a), "t_s": float(a + period_s), "heading_deg": float(yaw_to_heading_deg(yaw_rad))}
            for a in t0]


def test_step_errors_score_the_walking_direction(synthetic):
    right = ev.step_errors(_rows(WALK_YAW), synthetic).summary()
    assert right["n"] > 40 and right["mean_deg"] < 1.0 and right["within_10_deg"] == 1.0
    wrong = ev.step_errors(_rows(WALK_YAW + math.radians(90)), synthetic).summary()
    assert wrong["mean_deg"] == pytest.approx(90.0, abs=1.0) and wrong["within_20_deg"] == 0.0
    # A heading referenced to true north with a declination: removed before scoring.
    east_decl = ev.step_errors(_rows(WALK_YAW - math.radians(3.0)), synthetic, declination_deg=3.0).summary()
    assert east_decl["mean_deg"] < 1.0


def test_steps_outside_the_truth_are_not_scored(synthetic):
    rows = [{"t_start_s": T_START - 20.0, "t_s": T_START - 19.5, "heading_deg": 0.0},    # before the mocap
            {"t_start_s": T_START + 5.0, "t_s": T_START + 5.05, "heading_deg": 0.0}]     # 6 cm: too short
    assert ev.step_errors(rows, synthetic).summary()["n"] == 0


def test_attitude_errors_of_the_truth_and_of_a_rotated_copy(synthetic):
    t = synthetic.origin_ns / 1e9 + synthetic.t_s("orientation")
    q = synthetic.values("orientation")
    yaw, tilt = ev.attitude_errors(t, q, synthetic)
    assert yaw.summary()["n"] > 1000 and yaw.summary()["mean_deg"] < 0.5 and tilt.summary()["mean_deg"] < 0.1
    turned = quat.multiply(np.array([math.cos(math.radians(5)), 0, 0, math.sin(math.radians(5))]), q)  # 10 deg
    yaw, tilt = ev.attitude_errors(t, turned, synthetic)
    assert yaw.summary()["mean_deg"] == pytest.approx(10.0, abs=0.5) and tilt.summary()["mean_deg"] < 0.1
    # Estimates far from every frame are not compared.
    yaw, _ = ev.attitude_errors(t + 100.0, q, synthetic)
    assert yaw.summary()["n"] == 0


def test_yaw_and_tilt_errors_separate_heading_from_tilt():
    true = quat.from_euler(np.array([1.4, 0.2]), np.array([0.1, -1.5]), np.array([2.0, -0.5]))  # one near lock
    tilted = quat.multiply(quat.from_euler(math.radians(4), 0.0, 0.0), true)   # about a horizontal axis
    yawed = quat.multiply(quat.from_euler(0.0, 0.0, math.radians(7)), true)
    yaw, tilt = ev.yaw_tilt_error(yawed, true)
    np.testing.assert_allclose(np.degrees(yaw), 7.0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(tilt), 0.0, atol=1e-6)
    yaw, tilt = ev.yaw_tilt_error(tilted, true)
    np.testing.assert_allclose(np.degrees(tilt), 4.0, atol=1e-6)
    np.testing.assert_allclose(np.degrees(yaw), 0.0, atol=1e-6)


def test_protocol_pools_steps_by_carriage_walker_and_field():
    def score(walker, carriage, dist, errs):
        e = {k: ev.ErrorSet() for k in ev.ERROR_SETS}
        e["walk_causal"] = ev.ErrorSet(np.array(errs, dtype=float))
        return ev.RecordingScore(f"{walker}_{carriage}", walker, carriage, dist, "pocket", len(errs), e, [])

    scores = [score("Guillaume", "FrontPocket", False, [2, 4]), score("Jakob", "FrontPocket", True, [30]),
              score("Jakob", "Texting", False, [5, 15, 25])]
    agg = ev.protocol(scores)
    assert agg["by_carriage"]["FrontPocket"]["walk_causal"] == pytest.approx(
        {"n": 3, "mean_deg": 12.0, "median_deg": 4.0, "within_10_deg": 2 / 3, "within_20_deg": 2 / 3})
    assert agg["by_walker"]["Guillaume"]["half"] == "tuning" and agg["by_walker"]["Jakob"]["half"] == "confirmation"
    assert agg["by_walker"]["Jakob"]["walk_causal"]["n"] == 4
    assert agg["by_walker_and_carriage"]["Jakob Texting"]["walk_causal"]["median_deg"] == 15.0
    assert agg["by_field"]["Dist"]["walk_causal"]["mean_deg"] == 30.0
    assert list(agg["by_carriage"]) == ["FrontPocket", "Texting"]
    assert agg["all"]["recordings"] == 3 and agg["all"]["walk_causal"]["n"] == 6
    assert math.isnan(agg["all"]["att_yaw"]["mean_deg"])
    lines = ev.report_lines(scores, agg)
    assert any(line.startswith("ALL (3 rec.)") for line in lines)
    # Jakob's front pocket (30 deg) is over the 15 deg bar; his texting (15 deg) and Guillaume's (3 deg) are not.
    assert ("recordings whose causal walking direction is off by more than 15 deg on average: 1 of 3 "
            "(Jakob_FrontPocket 30.0)") in lines
    assert "recordings whose smoothed walking direction is off by more than 15 deg on average: 0 of 3" in lines


def test_disturbed_stretches_split_the_attitude_yaw_against_the_walkers_clean_field():
    def score(walker, dist, field_ut, dip_deg, att, rv):
        e = {k: ev.ErrorSet() for k in ev.ERROR_SETS}
        frames = {"field_uT": np.array(field_ut, float), "dip_deg": np.array(dip_deg, float),
                  "att_yaw_deg": np.array(att, float), "rv_yaw_deg": np.array(rv, float)}
        return ev.RecordingScore(f"{walker}_{dist}", walker, "Texting", dist, "hand", 0, e, [], frames=frames)

    # Walker A's clean recording sets the reference (44 uT, 59 deg); its disturbed one is mostly off it. Walker B
    # has no clean recording: its own median is the reference.
    clean = score("A", False, [44, 44, 44, 45], [59, 59, 60, 59], [1, 2, 3, 4], [5, 6, 7, 8])
    disturbed = score("A", True, [44, 60, 70, 44, np.nan], [59, 59, 59, 70, 59], [1, 20, 30, 40, 9], [2, 3, 4, 5, 6])
    other = score("B", True, [80, 80, 80, 90], [40, 40, 40, 40], [1, 2, 3, 4], [np.nan, 1, 1, 1])
    ev.split_disturbed([clean, disturbed, other])
    assert clean.errors["att_yaw_dist"].deg.size == 0 and clean.errors["att_yaw_clean"].deg.tolist() == [1, 2, 3, 4]
    assert disturbed.errors["att_yaw_dist"].deg.tolist() == [20, 30, 40]       # magnitude, magnitude, dip
    assert disturbed.errors["att_yaw_clean"].deg.tolist() == [1]               # the unknown field is in neither
    assert disturbed.errors["rv_yaw_dist"].deg.tolist() == [3, 4, 5]
    assert other.errors["att_yaw_dist"].deg.tolist() == [4] and other.errors["rv_yaw_clean"].deg.tolist() == [1, 1]
    agg = ev.protocol([clean, disturbed, other])
    assert agg["all"]["att_yaw_dist"]["n"] == 4
    assert any("disturbed stretches" in line for line in ev.report_lines([clean, disturbed, other], agg))


def test_the_field_at_the_frames_is_the_world_field(synthetic):
    f, d = ev.frame_field(synthetic)
    ok = np.isfinite(f)
    assert ok.mean() > 0.9
    # The synthetic recording's field is fixed in the world: one magnitude and dip at every frame.
    assert np.nanstd(f) < 0.5 and np.nanstd(d) < 0.5


def test_placement_confusion_counts_steps_per_carriage_and_walker():
    def score(walker, carriage, placements):
        e = {k: ev.ErrorSet() for k in ev.ERROR_SETS}
        return ev.RecordingScore(f"{walker}_{carriage}", walker, carriage, False, placements[0], len(placements), e,
                                 [], step_table={"placement": placements})

    scores = [score("Guillaume", "FrontPocket", ["hand", "pocket", "pocket", "pocket"]),
              score("Guillaume", "Swinging", ["swinging"] * 3 + ["pocket"]),
              score("Jakob", "Texting", ["hand", "hand"])]
    agg = ev.protocol(scores)
    conf = agg["placement_confusion"]
    assert conf["all"]["matrix"] == {"FrontPocket": {"hand": 1, "pocket": 3}, "Swinging": {"pocket": 1, "swinging": 3},
                                     "Texting": {"hand": 2}}
    assert conf["all"]["right"] == pytest.approx(8 / 10)
    assert conf["Guillaume"]["right"] == pytest.approx(6 / 8) and conf["Jakob"]["right"] == 1.0
    assert conf["Jakob"]["half"] == "confirmation"
    text = "\n".join(ev.report_lines(scores, agg))
    assert "80.0 % of steps as expected" in text


def test_placement_label_and_bad_folders(synthetic, tmp_path):
    assert ev.placement_for(synthetic, "label") == "pocket"
    assert ev.placement_for(synthetic, "auto") == "auto"
    with pytest.raises(InputError, match="no Tyrex logger recording"):
        ev.recordings_in(tmp_path)
    with pytest.raises(InputError, match="no such file or folder"):
        ev.recordings_in(tmp_path / "missing")


def test_the_pipeline_attitude_is_captured(synthetic):
    rows, _, t, q = ev.run_with_attitude(synthetic, PipelineConfig(placement="pocket"))
    start, end = synthetic.time_span_s()
    assert t.size == q.shape[0] and t.size == pytest.approx((end - start) * 50, abs=3)
    assert synthetic.origin_ns / 1e9 + start <= t[0] < t[-1] <= synthetic.origin_ns / 1e9 + end + 0.02
    yaw, tilt = ev.attitude_errors(t, q, synthetic)
    # The phone only turns about its z axis while level: the filter's tilt stays small.
    assert tilt.summary()["n"] > 1000 and tilt.summary()["mean_deg"] < 3.0


@pytest.mark.data
def test_eval_heading_on_a_real_texting_walk(capsys):
    folder = sample_path("tyrex:folder")
    assert main(["eval", "heading", str(folder), "--json", "--placement", "label"]) == 0
    out = json.loads(capsys.readouterr().out)
    (rec,) = out["recordings"]
    assert rec["carriage"] == "Texting" and rec["walker"] == "Jakob" and rec["placement"] == "hand"
    assert rec["steps"] > 150 and rec["walk_causal"]["n"] > 0.9 * rec["steps"]
    assert set(out) >= {"by_carriage", "by_walker", "by_field", "all", "declination_deg"}
    # The phone's rotation vector on a clean walk: Michel et al. report a few degrees of attitude error; held in
    # reading position its +y axis points where the walker goes.
    assert rec["rv_yaw"]["mean_deg"] < 8.0 and rec["rv_tilt"]["mean_deg"] < 4.0
    assert rec["walk_rv_y"]["median_deg"] < 20.0
    # A perfect attitude's +y trails the truth through the loops' turns as the rotation vector's does: the truth
    # is the phone's path, which a phone held ahead of the body runs on a wider circle.
    lag = rec["offset_and_lag"]
    assert lag["mocap_y"]["lag_s"] > 0.2 and lag["rv_y"]["lag_s"] > 0.2
    assert rec["walk_mocap_y"]["median_deg"] < 15.0
    for key in ("walk_causal", "walk_smoothed", "att_yaw", "att_tilt"):
        assert np.isfinite(rec[key]["mean_deg"])
    # The OS-calibrated gyro leaves a residual bias of tenths of a degree per second (the report's gyro section).
    assert len(rec["gyro_bias_dps"]) == 3 and max(abs(v) for v in rec["gyro_bias_dps"]) < 1.0
    assert abs(rec["gyro_bias_up_dps"]) <= float(np.linalg.norm(rec["gyro_bias_dps"])) + 1e-9


def test_native_conversions_are_scored_like_the_folder(synthetic, tmp_path, capsys):
    from pdr.io import native

    native.write(synthetic, tmp_path / "conv" / f"{synthetic.meta['walker']}_walk.zip")
    (tmp_path / "conv" / "notes.zip").write_bytes(b"not a zip")
    assert ev.recordings_in(tmp_path / "conv") == [tmp_path / "conv" / "Alice_walk.zip"]
    steps = tmp_path / "steps"
    assert main(["eval", "heading", str(tmp_path / "conv"), "--json", "--placement", "pocket",
                 "--steps", str(steps)]) == 0
    (rec,) = json.loads(capsys.readouterr().out)["recordings"]
    assert rec["recording"] == "Alice_walk" and rec["carriage"] == "FrontPocket" and rec["walker"] == "Alice"
    lines = (steps / "Alice_walk.csv").read_text().splitlines()
    assert lines[0] == ("t_start_s,t_s,placement,true_heading_deg,heading_deg,smoothed_heading_deg,"
                        "rv_y_heading_deg,mocap_y_heading_deg")
    assert len(lines) == rec["steps"] + 1


@pytest.mark.slow
@pytest.mark.data
def test_eval_heading_on_the_whole_benchmark_keeps_the_reference_figures(capsys, shared_data):
    """The phone's rotation vector is the fixed reference: its figures check the truth of all 18 recordings."""
    root = shared_data / "attitude_smartphones"
    if not root.exists():
        pytest.skip(f"shared dataset not available: {root}")
    assert main(["eval", "heading", str(root), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    recs = out["recordings"]
    assert len(recs) == 18 and out["all"]["recordings"] == 18
    assert {r["carriage"] for r in recs} == set(ev.CARRIAGES)
    assert set(out["by_walker"]) == {"Guillaume", "Jakob"}
    for r in recs:
        # The truth gives a direction for most steps; not for a step over which the walker moved less than
        # MIN_STEP_M. The held-phone step gate finds some of those in the disturbed texting walks (12 of 52 and 17
        # of 85 steps there match no motion-capture step: tools/walking_steps.py --only attitude), hence 0.7.
        assert r["walk_causal"]["n"] >= 0.7 * r["steps"], r["recording"]
        # Michel et al.: the rotation vector's tilt stays within a few degrees, its yaw too in a clean field.
        assert r["rv_tilt"]["mean_deg"] < 5.0, r["recording"]
        if not r["disturbed"]:
            assert r["rv_yaw"]["mean_deg"] < 8.0, r["recording"]
            assert abs(r["field_azimuth_mocap_deg"]) < 3.0, r["recording"]
        if r["carriage"] == "Texting":
            assert r["walk_rv_y"]["median_deg"] < 25.0, r["recording"]
    assert out["by_field"]["Dist"]["rv_yaw"]["mean_deg"] > out["by_field"]["NoDist"]["rv_yaw"]["mean_deg"]


@pytest.mark.data
def test_eval_heading_with_a_perfect_attitude_runs_the_pipeline_on_the_motion_capture(capsys):
    folder = sample_path("tyrex:folder")
    rec = ev.read_recording(folder)
    mocap = ev.mocap_attitude_recording(rec)
    q = np.asarray(rec.truth.extra["q_nb"])
    ok = np.all(np.isfinite(q), axis=1)
    assert np.allclose(mocap.values("orientation"), q[ok])
    assert np.allclose(mocap.t_s("orientation"), np.asarray(rec.truth.extra["trajectory_t_s"])[ok], atol=1e-9)
    assert main(["eval", "heading", str(folder), "--json", "--placement", "label", "--perfect-attitude"]) == 0
    (r,) = json.loads(capsys.readouterr().out)["recordings"]
    # Held in reading position with an exact attitude, the walking direction is about as good as with ours (a
    # clean-field walk, where our attitude's yaw is within a few degrees).
    assert r["walk_perfect"]["n"] >= 0.9 * r["walk_causal"]["n"]
    assert abs(r["walk_perfect"]["median_deg"] - r["walk_causal"]["median_deg"]) < 5.0
    assert main(["eval", "heading", str(folder), "--placement", "label"]) == 0
    assert "perfect attitude" not in capsys.readouterr().out.split("texting:")[0]   # the section needs the option


def test_mean_y_yaw_of_a_phone_turning_at_a_constant_rate_is_its_yaw_at_mid_interval():
    t = np.arange(0.0, 10.0, 0.01)
    yaw = np.radians(30.0) * t                                    # device x axis, CCW from east
    q = np.column_stack([np.cos(yaw / 2), np.zeros_like(t), np.zeros_like(t), np.sin(yaw / 2)])
    t0, t1 = np.array([1.0, 4.0, 20.0]), np.array([1.5, 5.0, 21.0])
    got = ev.mean_y_yaw(t, q, t0, t1)
    want = np.radians(30.0) * 0.5 * (t0 + t1 - 0.01) + np.pi / 2  # +y is 90 deg CCW of x; samples in [t0, t1)
    assert np.allclose(np.angle(np.exp(1j * (got[:2] - want[:2]))), 0.0, atol=1e-3)
    assert np.isnan(got[2])                                      # no sample in the interval


def _loop_table(offset_deg: float, lag_s: float, flips: int = 0) -> dict[str, np.ndarray]:
    """Steps of 0.5 s round loops whose turn rate varies (0 to 60 deg/s clockwise), with an estimate turned by
    ``offset_deg`` and trailing the path by ``lag_s``; the first ``flips`` estimates reversed."""
    t0 = 0.5 * np.arange(200)
    rate = 30.0 + 30.0 * np.sin(2 * np.pi * t0 / 17.0)                  # deg/s, clockwise
    heading = np.cumsum(rate * 0.5) % 360.0                             # the path's direction at each step
    est = (heading + offset_deg - lag_s * rate) % 360.0
    est[:flips] = (est[:flips] + 180.0) % 360.0
    return {"t_start_s": t0, "t_s": t0 + 0.5, "true_heading_deg": heading, "heading_deg": est}


def test_offset_and_turn_lag_recover_a_constant_offset_and_a_lag():
    d = ev.offset_and_turn_lag(_loop_table(-8.0, 0.25), "heading_deg")
    assert d["offset_deg"] == pytest.approx(-8.0, abs=0.3) and d["lag_s"] == pytest.approx(0.25, abs=0.01)
    assert d["residual_mean_abs_deg"] < 0.5 < d["mean_abs_deg"]
    assert d["n"] == 198 and d["excluded"] == 0           # the two end steps have no neighbours
    # Reversed steps are left out of the fit, not taken for an offset.
    flipped = ev.offset_and_turn_lag(_loop_table(-8.0, 0.25, flips=10), "heading_deg")
    assert flipped["excluded"] == 9 and flipped["offset_deg"] == pytest.approx(-8.0, abs=0.3)
    # No estimate column, or too few steps: nothing to fit.
    assert ev.offset_and_turn_lag({}, "heading_deg")["n"] == 0
    assert math.isnan(ev.offset_and_turn_lag(_loop_table(0.0, 0.0), "smoothed_heading_deg")["lag_s"])


def test_the_gyros_residual_bias_is_recovered_against_the_motion_capture(synthetic):
    # The synthetic phone turns about its z axis (up) at the rate its calibrated gyro reports, plus 0.001 rad/s about
    # x: the residual bias is that, and nothing of it lies about the vertical.
    found = ev.gyro_residual_bias(synthetic)
    assert found is not None
    bias, up = found
    np.testing.assert_allclose(bias, [math.degrees(0.001), 0.0, 0.0], atol=0.01)
    assert abs(up) < 0.01
