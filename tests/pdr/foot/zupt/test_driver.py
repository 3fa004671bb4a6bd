import numpy as np
import pytest
from scipy.stats import chi2

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.foot.bc import run_bc
from pdr.foot.detectors import detect
from pdr.foot.filterbank import run_filterbank
from pdr.foot.stepwise import dead_reckon
from pdr.foot.zupt import Segmentation, ZuptConfig, run_zupt
from pdr.frames import wrap_angle
from tests.pdr.foot.gait import Gait, gyro_drift_walk, simulate_gait


def _horizontal(a: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a[..., :2], axis=-1)


def test_straight_walk_is_recovered_noise_free() -> None:
    g = simulate_gait(n_strides=10, stride_m=1.4)
    tr = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance)
    # 14 m walked: final position within 1 cm, vertical back on the floor within 1 cm.
    assert _horizontal(tr.pos_n[-1] - g.pos_n[-1]) < 0.01
    assert abs(tr.pos_n[-1, 2]) < 0.01
    np.testing.assert_allclose(tr.pos_n[:, :2], g.pos_n[:, :2], atol=0.02)
    # Roll and pitch found by the coarse self-initialisation.
    roll, pitch, _ = quat.to_euler(tr.q_nb[-1])
    assert roll == pytest.approx(0.1, abs=1e-3) and pitch == pytest.approx(-0.2, abs=1e-3)


def test_turning_walk_with_noise_and_detected_stances() -> None:
    g = simulate_gait(n_strides=12, stride_m=1.2, turn_rad=np.radians(15.0), sigma_acc=0.02, sigma_gyro=0.002,
                      seed=3)
    zv = detect(g.acc_b, g.gyro_b, 200.0)
    tr = run_zupt(g.t_s, g.acc_b, g.gyro_b, zv)
    dist = 12 * 1.2
    assert _horizontal(tr.pos_n[-1] - g.pos_n[-1]) < 0.01 * dist
    assert abs(wrap_angle(tr.yaw[-1] - g.yaw[-1])) < np.radians(1.0)


def test_attitude_and_velocity_errors_are_consistent_with_the_covariance() -> None:
    # NEES of roll/pitch/velocity at the end of the last stance, over Monte Carlo runs: within chi-square bounds.
    cfg = ZuptConfig(sigma_acc=0.05, sigma_gyro=0.005)
    nees = []
    for seed in range(20):
        g = simulate_gait(n_strides=4, sigma_acc=0.05, sigma_gyro=0.005, seed=seed)
        tr = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance, cfg)
        roll, pitch, _ = quat.to_euler(tr.q_nb[-1])
        e = np.array([roll - 0.1, pitch + 0.2])
        nees.append(float(e @ e / np.mean(tr.att_var[-1, :2])))
    lo, hi = chi2.ppf([0.005, 0.995], 2 * len(nees)) / len(nees)
    assert lo < np.mean(nees) < hi


def test_position_error_stays_inside_the_reported_uncertainty() -> None:
    misses = 0
    for seed in range(10):
        g = simulate_gait(n_strides=8, sigma_acc=0.05, sigma_gyro=0.005, seed=100 + seed)
        tr = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance, ZuptConfig(sigma_acc=0.05, sigma_gyro=0.005))
        err = tr.pos_n[-1, :2] - g.pos_n[-1, :2]
        misses += int(np.linalg.norm(err) > 3.0 * np.sqrt(tr.pos_var[-1, :2].sum()))
    assert misses <= 2


def test_stepwise_dead_reckoning_reproduces_the_full_filter() -> None:
    g = simulate_gait(n_strides=10, turn_rad=np.radians(20.0), sigma_acc=0.02, sigma_gyro=0.002, seed=5)
    full = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance)
    sw = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance, segmentation=Segmentation())
    # A reset at each stance's end (the first opens the first swing), and the end of the recording closes the 10th
    # stride, whose stance never ends, at the last sample.
    assert len(sw.steps) == 11 and sw.step_strides == (False,) + (True,) * 10
    assert sw.steps[-1].index == g.t_s.size - 1
    np.testing.assert_allclose(sw.pos_n, full.pos_n, atol=0.01)
    dr = dead_reckon(sw.steps)
    np.testing.assert_allclose(dr.pos_n[-1], sw.pos_n[sw.steps[-1].index], atol=1e-9)
    # Accumulated position variance of the dead reckoning matches the full filter's within 10 %.
    k = sw.steps[-1].index
    assert np.trace(dr.cov[-1, :2, :2]) == pytest.approx(full.pos_var[k, :2].sum(), rel=0.1)
    assert np.angle(np.exp(1j * (dr.heading[-1] - full.yaw[k]))) == pytest.approx(0.0, abs=1e-3)  # past 180 deg


def test_bad_input_is_reported() -> None:
    g = simulate_gait(n_strides=2)
    with pytest.raises(InputError, match="never comes to rest"):
        run_zupt(g.t_s, g.acc_b, g.gyro_b, np.zeros(g.t_s.size, dtype=bool))
    with pytest.raises(InputError, match="strictly increasing"):
        run_zupt(g.t_s[::-1], g.acc_b, g.gyro_b, g.stance)
    with pytest.raises(InputError, match="zero_velocity"):
        run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance[:-1])
    bad = g.acc_b.copy()
    bad[5, 0] = np.nan
    with pytest.raises(InputError, match="not finite"):
        run_zupt(g.t_s, bad, g.gyro_b, g.stance)


def test_start_in_motion_is_reported() -> None:
    g = simulate_gait(n_strides=4, stance_s=0.5)
    zv = g.stance.copy()
    zv[:100] = False   # detector misses the initial stance: first rest found later
    tr = run_zupt(g.t_s, g.acc_b, g.gyro_b, zv)
    assert any("starts in motion" in w for w in tr.warnings)


@pytest.mark.parametrize("run", [run_zupt, run_filterbank, run_bc])
def test_every_navigator_reports_a_start_in_motion_even_a_short_one(run) -> None:
    g = simulate_gait(n_strides=3, stance_s=0.5)
    assert not any("starts in motion" in w for w in run(g.t_s, g.acc_b, g.gyro_b, g.stance).warnings)
    zv = g.stance.copy()
    zv[:60] = False   # the first 0.3 s (60 samples at 200 Hz) not flagged at rest: navigation starts there
    tr = run(g.t_s, g.acc_b, g.gyro_b, zv)
    assert tr.start_index == 60
    assert [w for w in tr.warnings if "starts in motion" in w] == [
        "recording starts in motion: first stationary period at 0.30 s; navigation starts there and the motion "
        "before it is not tracked"]


def test_heading_drift_of_a_gyro_bias_is_removed_on_a_straight_walk() -> None:
    # Simulate then recover: 0.15 deg/s of heading drift over a 56 m, 45 s straight walk turns the heading by about
    # 7 deg and leaves the end 3.2 m off without the drift elimination; with it the final heading is within 1 deg
    # and the end within 1.5 % of the distance (what is left is walked while the drift rate is being learnt).
    g, gyro = gyro_drift_walk(0.15)
    dist = 40 * 1.4
    off = run_zupt(g.t_s, g.acc_b, gyro, g.stance, ZuptConfig(hde_directions=0))
    on = run_zupt(g.t_s, g.acc_b, gyro, g.stance)
    err_off = _horizontal(off.pos_n[-1] - g.pos_n[-1])
    err_on = _horizontal(on.pos_n[-1] - g.pos_n[-1])
    assert abs(np.degrees(wrap_angle(off.yaw[-1] - g.yaw[-1]))) > 5.0
    assert err_off > 0.03 * dist
    assert abs(np.degrees(wrap_angle(on.yaw[-1] - g.yaw[-1]))) < 1.0
    assert err_on < 0.015 * dist and err_on < 0.25 * err_off, (err_on, err_off)


def test_drift_elimination_leaves_curved_walks_and_clean_gyros_alone() -> None:
    # A walk turning 15 deg every stride has no straight stretch: no measurement, the same track as without it.
    g = simulate_gait(n_strides=12, stride_m=1.2, turn_rad=np.radians(15.0), sigma_acc=0.02, sigma_gyro=0.002,
                      seed=3)
    on = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance)
    off = run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance, ZuptConfig(hde_directions=0))
    np.testing.assert_allclose(on.pos_n, off.pos_n, atol=1e-9)
    # A straight walk with an unbiased gyroscope stays as good as without it.
    g2, gyro = gyro_drift_walk(0.0)
    on2 = run_zupt(g2.t_s, g2.acc_b, gyro, g2.stance)
    assert _horizontal(on2.pos_n[-1] - g2.pos_n[-1]) < 0.005 * 40 * 1.4


def test_drift_elimination_settings_are_checked() -> None:
    with pytest.raises(InputError, match="hde_directions"):
        ZuptConfig(hde_directions=-1)
    with pytest.raises(InputError, match="hde_min_strides"):
        ZuptConfig(hde_min_strides=0)
    with pytest.raises(InputError, match="hde_sigma_dir"):
        ZuptConfig(hde_sigma_dir=0.0)


def _stop_and_go(bias_deg_s: tuple[float, float, float]) -> tuple[Gait, np.ndarray, np.ndarray]:
    # A walk that stops for 3 s at every step (a long rest is what the zero angular-rate update needs), with a
    # constant gyroscope bias (deg/s, sensor frame) on top of light white noise.
    g = simulate_gait(n_strides=12, stride_m=1.2, stance_s=3.0, sigma_acc=0.02, sigma_gyro=0.002, seed=5)
    bias = np.radians(np.array(bias_deg_s))
    return g, bias, g.gyro_b + bias


def test_zero_angular_rate_update_recovers_a_gyro_bias_and_stops_the_heading_drift() -> None:
    # Simulate then recover: 0.3 deg/s on every axis turns the heading by about 14 deg over the 47 s walk without
    # the update; with it the bias is learnt in the first rest and the heading stays within 1 deg.
    g, bias, gyro = _stop_and_go((0.3, -0.3, 0.3))
    cfg = ZuptConfig(hde_directions=0)
    off = run_zupt(g.t_s, g.acc_b, gyro, g.stance, cfg)
    on = run_zupt(g.t_s, g.acc_b, gyro, g.stance, ZuptConfig(hde_directions=0, zaru=True))
    assert abs(np.degrees(wrap_angle(off.yaw[-1] - g.yaw[-1]))) > 5.0
    assert abs(np.degrees(wrap_angle(on.yaw[-1] - g.yaw[-1]))) < 1.0
    np.testing.assert_allclose(on.gyro_bias, bias, atol=np.radians(0.02))
    np.testing.assert_array_equal(off.gyro_bias, 0.0)
    dist = 12 * 1.2
    assert _horizontal(on.pos_n[-1] - g.pos_n[-1]) < 0.01 * dist < _horizontal(off.pos_n[-1] - g.pos_n[-1])


def test_zero_angular_rate_update_leaves_an_unbiased_gyro_and_a_walk_without_rests_alone() -> None:
    g, _, gyro = _stop_and_go((0.0, 0.0, 0.0))
    on = run_zupt(g.t_s, g.acc_b, gyro, g.stance, ZuptConfig(hde_directions=0, zaru=True))
    assert np.all(np.abs(np.degrees(on.gyro_bias)) < 0.01)
    # Stances of 0.5 s never give the 0.5 s of stillness the update waits for: the same track as without it.
    w = simulate_gait(n_strides=8, sigma_acc=0.02, sigma_gyro=0.002, seed=2)
    a = run_zupt(w.t_s, w.acc_b, w.gyro_b, w.stance, ZuptConfig(zaru=True))
    b = run_zupt(w.t_s, w.acc_b, w.gyro_b, w.stance)
    np.testing.assert_array_equal(a.pos_n, b.pos_n)


@pytest.mark.parametrize("interval", [False, True])
def test_sample_timing_of_an_acceleration_pulse(interval: bool) -> None:
    """An acceleration ``a`` held over exactly one sample interval ``(t_{m-1}, t_m]`` of a level, resting IMU.

    As interval means (``interval_samples``) the samples are that pulse exactly: the velocity reaches ``a dt`` at
    ``t_m`` and the position at the end is ``a dt (t_end - t_m) + a dt^2 / 2``. As instants the mechanization
    interpolates the samples linearly: half the velocity change at ``t_m``, the rest by ``t_{m+1}``, the same
    final velocity and a position short by the pulse's half-interval lead, ``a dt^2 / 2``.
    """
    rate, a, m = 100.0, 3.0, 80
    dt = 1.0 / rate
    t = np.arange(200) * dt
    acc = np.tile([0.0, 0.0, 9.80665], (t.size, 1))
    acc[m, 0] = a
    still = t < 0.5
    tr = run_zupt(t, acc, np.zeros_like(acc), still, ZuptConfig(interval_samples=interval, hde_directions=0))
    lead = a * dt * (t[-1] - t[m])
    np.testing.assert_allclose(tr.vel_n[m - 1], 0.0, atol=1e-12)
    assert tr.vel_n[m, 0] == pytest.approx(a * dt * (1.0 if interval else 0.5), rel=1e-9)
    assert tr.vel_n[m + 1, 0] == pytest.approx(a * dt, rel=1e-9)
    assert tr.pos_n[-1, 0] == pytest.approx(lead + (0.5 * a * dt**2 if interval else 0.0), rel=1e-9)
    np.testing.assert_allclose(tr.pos_n[-1, 1:], 0.0, atol=1e-12)
