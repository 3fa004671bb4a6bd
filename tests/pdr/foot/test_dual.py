"""Dual-foot fusion (seed 001 Sec. 4.2): simulate both feet of one walk, fuse, compare with the truth."""

import csv
import math
from functools import cache
from typing import Any

import numpy as np
import pytest

from pdr.cli import main
from pdr.errors import InputError
from pdr.foot.dual import DualFootConfig, fuse_feet, navigate_feet
from pdr.foot.navigate import navigate
from pdr.foot.zupt import ZuptConfig
from pdr.fusion.constraints import SeparationConfig
from pdr.recording import Recording
from pdr.sim import parse_scenario, simulate

SEGMENTS = [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 35, "speed_mps": 1.4},
            {"type": "turn", "angle_deg": 90, "duration_s": 2, "speed_mps": 1.0},
            {"type": "walk", "duration_s": 15, "speed_mps": 1.4}, {"type": "stand", "duration_s": 2}]


def _scenario(side: str, mount_yaw_deg: float = 0.0) -> dict[str, Any]:
    doc: dict[str, Any] = {"name": "dual", "placement": "foot", "side": side, "rates_hz": {"acc": 200, "gyro": 200},
           "sensors": {"grade": "consumer"}, "segments": SEGMENTS}
    if mount_yaw_deg:
        doc["mount_rpy_deg"] = [0.0, 0.0, mount_yaw_deg]
    return doc


@cache
def _feet(seed_left: int, seed_right: int, mount_yaw_deg: float = 0.0) -> tuple[Recording, Recording]:
    # Same walk, independent sensor errors (different seeds) for the two shoes.
    return (simulate(parse_scenario(_scenario("left")), seed_left),
            simulate(parse_scenario(_scenario("right", mount_yaw_deg)), seed_right))


def _mean_error(rec: Recording, t_s: np.ndarray, pos: np.ndarray) -> float:
    truth = rec.truth.positions
    assert truth is not None
    gt = truth.pos_m - truth.pos_m[0]
    est = np.stack([np.interp(truth.t_s, t_s, pos[:, i]) for i in range(2)], axis=1)
    return float(np.mean(np.linalg.norm(est - gt[:, :2], axis=1)))


@pytest.mark.parametrize("seeds", [(1, 2), (3, 4)])
def test_fusion_recovers_both_feet_better_than_each_alone(seeds: tuple[int, int]) -> None:
    left, right = _feet(*seeds)
    imu_l, tr_l = navigate(left, "stepwise")
    imu_r, tr_r = navigate(right, "stepwise")
    fused = fuse_feet(tr_l, tr_r, imu_l.clock_offset_s, imu_r.clock_offset_s)
    alone = [_mean_error(left, tr_l.t_s, tr_l.pos_n), _mean_error(right, tr_r.t_s, tr_r.pos_n)]
    both = [_mean_error(left, fused.left.t_s - imu_l.clock_offset_s, fused.left.pos_n),
            _mean_error(right, fused.right.t_s - imu_r.clock_offset_s, fused.right.pos_n)]
    # The constraint averages the two feet's independent heading drifts (consumer gyro biases).
    assert np.mean(both) < np.mean(alone)
    assert max(both) < max(alone)
    assert fused.updates == len(tr_l.steps) + len(tr_r.steps)
    assert fused.constraint_active > 0
    # The fused feet respect the constraint at their resets (up to the time-difference widening).
    k = np.searchsorted(fused.right.t_s, fused.left.step_t_s)
    sep = np.linalg.norm(fused.left.step_pos_n[:, :2] - fused.right.pos_n[np.minimum(k, fused.right.t_s.size - 1),
                                                                         :2], axis=1)
    assert np.median(sep) < 1.0


def test_without_an_active_constraint_each_foot_keeps_its_own_track() -> None:
    left, right = _feet(1, 2)
    imu_l, tr_l = navigate(left, "stepwise")
    imu_r, tr_r = navigate(right, "stepwise")
    loose = DualFootConfig(separation=SeparationConfig(gamma_xy=1e4, gamma_z=1e4))
    fused = fuse_feet(tr_l, tr_r, imu_l.clock_offset_s, imu_r.clock_offset_s, loose)
    assert fused.constraint_active == 0
    np.testing.assert_allclose(fused.left.pos_n, tr_l.pos_n, atol=1e-9)
    # The right foot's frame is only turned by the initial alignment.
    c, s = math.cos(fused.heading_offset_rad), math.sin(fused.heading_offset_rad)
    turned = tr_r.pos_n[:, :2] @ np.array([[c, -s], [s, c]]).T
    np.testing.assert_allclose(fused.right.pos_n[:, :2], turned, atol=1e-9)
    # The dead-reckoned covariance of the left foot is that of its own step-wise dead reckoning.
    assert np.all(np.linalg.eigvalsh(fused.left.step_cov) > -1e-12)


def test_initial_alignment_recovers_a_turned_right_shoe() -> None:
    left, right = _feet(5, 6, mount_yaw_deg=40.0)
    imu_l, imu_r, fused = navigate_feet(left, right)
    # The right IMU is mounted 40 deg turned (CCW about the shoe's vertical): its frame sees the walk turned by
    # -40 deg, so +40 deg aligns it.
    assert math.degrees(fused.heading_offset_rad) == pytest.approx(40.0, abs=3.0)
    assert _mean_error(right, fused.right.t_s - imu_r.clock_offset_s, fused.right.pos_n) < 3.0


def test_bad_input_is_refused() -> None:
    left, right = _feet(1, 2)
    _, tr_l = navigate(left, "stepwise")
    _, tr_z = navigate(right, "zupt")
    with pytest.raises(InputError, match="no steps"):
        fuse_feet(tr_l, tr_z)
    _, tr_r = navigate(right, "stepwise")
    with pytest.raises(InputError, match="do not overlap"):
        fuse_feet(tr_l, tr_r, 0.0, 1e4)
    with pytest.raises(InputError, match="positive"):
        DualFootConfig(align_distance_m=0.0)


def test_cli_dual_foot(tmp_path, capsys) -> None:
    from pdr.io.native import write as write_native

    left, right = _feet(1, 2)
    write_native(left, tmp_path / "left")
    write_native(right, tmp_path / "right")
    out = tmp_path / "track.csv"
    assert main(["foot", "--left", str(tmp_path / "left"), "--right", str(tmp_path / "right"), "--out",
                 str(out)]) == 0
    with open(out, encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert set(rows[0]) >= {"t_s", "east_m", "north_m", "up_m", "heading_deg", "zero_velocity", "left_east_m",
                            "right_east_m"}
    end = np.array([float(rows[-1]["east_m"]), float(rows[-1]["north_m"])])
    assert left.truth.positions is not None and right.truth.positions is not None
    truth = 0.5 * (left.truth.positions.pos_m[-1, :2] + right.truth.positions.pos_m[-1, :2])
    assert np.linalg.norm(end - truth) < 5.0
    assert main(["foot", "--left", str(tmp_path / "left"), "--out", str(out)]) == 2
    assert "both --left and --right" in capsys.readouterr().err
    # The ZUPT-INS settings reach both feet (each foot's step-wise navigation), an offline-only one is refused.
    feet = ["foot", "--left", str(tmp_path / "left"), "--right", str(tmp_path / "right"), "--out"]
    assert main([*feet, str(tmp_path / "interval.csv"), "--imu-samples", "interval"]) == 0
    with open(tmp_path / "interval.csv", encoding="utf-8") as fh:
        interval_rows = list(csv.DictReader(fh))
    _, _, expected = navigate_feet(left, right, zupt=ZuptConfig(interval_samples=True))
    assert float(interval_rows[-1]["left_east_m"]) == pytest.approx(expected.left.pos_n[-1, 0], abs=1e-6)
    assert interval_rows[-1]["left_east_m"] != rows[-1]["left_east_m"]
    assert main([*feet, str(out), "--gyro-bias", "on"]) == 2
    assert "--method stepwise does not have --gyro-bias on" in capsys.readouterr().err


def test_cli_dual_foot_per_step_rows_mark_the_resets_while_a_foot_stands(tmp_path) -> None:
    """``--left/--right --per-step``: column ``stride`` as in the one-foot CSV (0: a reset while the foot stands,
    the one that starts each foot's first swing among them); it was missing, and those rows looked like strides."""
    from pdr.io.native import write as write_native

    left, right = _feet(1, 2)
    write_native(left, tmp_path / "left")
    write_native(right, tmp_path / "right")
    out = tmp_path / "steps.csv"
    assert main(["foot", "--left", str(tmp_path / "left"), "--right", str(tmp_path / "right"), "--per-step",
                 "--out", str(out)]) == 0
    with open(out, encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    _, _, fused = navigate_feet(left, right)
    for foot, est in (("0", fused.left), ("1", fused.right)):
        flags = [r["stride"] for r in rows if r["right_foot"] == foot]
        assert len(flags) == est.step_t_s.size == est.step_strides.size
        assert flags == [str(int(f)) for f in est.step_strides] and "0" in flags and "1" in flags
