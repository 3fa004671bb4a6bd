"""RTS smoothing of the ZUPT-aided INS (pdr.filters.rts error-state form, run_zupt(smooth=True))."""

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.foot.zupt import Segmentation, ZuptConfig, run_zupt
from tests.pdr.foot.gait import Gait, simulate_gait


def _imu(g: Gait) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return g.t_s, g.acc_b, g.gyro_b, g.stance


def test_smoothed_velocity_error_is_below_the_filtered_one() -> None:
    # Swing velocity errors (from noisy tilt) are revealed by the next stance's ZUPTs; the backward pass moves
    # that information into the swing. Reference: the same walk without sensor noise through the same
    # discretisation (the noise-free filter reproduces the kinematics up to its integration error).
    sa, sg = 0.3, 0.03
    cfg = ZuptConfig(sigma_acc=sa, sigma_gyro=sg, hde_directions=0)
    ref = run_zupt(*_imu(simulate_gait(n_strides=8)), cfg)
    mse_f = mse_s = 0.0
    for seed in range(8):
        g = simulate_gait(n_strides=8, sigma_acc=sa, sigma_gyro=sg, seed=seed)
        filt = run_zupt(*_imu(g), cfg)
        smooth = run_zupt(*_imu(g), cfg, smooth=True)
        e_f = np.mean(np.sum((filt.vel_n - ref.vel_n) ** 2, axis=1))
        e_s = np.mean(np.sum((smooth.vel_n - ref.vel_n) ** 2, axis=1))
        assert e_s < e_f
        mse_f += e_f
        mse_s += e_s
        # The last sample is the filter's own estimate; smoothed variances are never larger; unit quaternions.
        np.testing.assert_allclose(smooth.pos_n[-1], filt.pos_n[-1])
        assert np.all(smooth.pos_var <= filt.pos_var + 1e-12)
        assert np.all(smooth.vel_var[filt.start_index:] <= filt.vel_var[filt.start_index:] + 1e-12)
        assert np.all(smooth.att_var[filt.start_index:] <= filt.att_var[filt.start_index:] + 1e-12)
        np.testing.assert_allclose(np.linalg.norm(smooth.q_nb, axis=1), 1.0, atol=1e-12)
    assert mse_s < 0.6 * mse_f


def test_noise_free_walk_is_unchanged_by_smoothing() -> None:
    g = simulate_gait(n_strides=6, turn_rad=np.radians(15.0))
    filt = run_zupt(*_imu(g))
    smooth = run_zupt(*_imu(g), smooth=True)
    np.testing.assert_allclose(smooth.pos_n, filt.pos_n, atol=5e-3)
    assert np.max(np.abs(smooth.pos_n[:, 2] - g.pos_n[:, 2])) <= np.max(np.abs(filt.pos_n[:, 2] - g.pos_n[:, 2]))
    roll, pitch, _ = quat.to_euler(smooth.q_nb[-1])
    assert roll == pytest.approx(0.1, abs=1e-3) and pitch == pytest.approx(-0.2, abs=1e-3)


def test_smoother_refuses_segmentation() -> None:
    g = simulate_gait(n_strides=2)
    with pytest.raises(InputError, match="without step segmentation"):
        run_zupt(g.t_s, g.acc_b, g.gyro_b, g.stance, segmentation=Segmentation(), smooth=True)


def test_eval_names_filtered_and_smoothed_runs() -> None:
    from pdr.cli.foot import eval_variants
    assert eval_variants(("zupt", "bc"), "on", "both") == ("zupt", "zupt/filtered", "bc")
    assert eval_variants(("zupt",), "both", "on") == ("zupt", "zupt/no-hde")
    assert eval_variants(("zupt",), "off", "both") == ("zupt/no-hde", "zupt/filtered/no-hde")


@pytest.mark.parametrize("segment", [2, 3, 997, 2048])
def test_checkpointed_smoothing_equals_one_pass_to_the_bit(segment: int) -> None:
    # Segments of any length (a remainder, a segment boundary inside a stance or a swing, one per sample pair)
    # reproduce the backward pass over the whole recording exactly, with the drift elimination and the zero
    # angular-rate update (both change the filter state inside the loop) on.
    g = simulate_gait(n_strides=10, stance_s=1.2, turn_rad=0.1, sigma_acc=0.05, sigma_gyro=0.003, seed=9)
    gyro = g.gyro_b + np.radians([0.2, -0.1, 0.3])
    cfg = ZuptConfig(zaru=True, zaru_min_still_s=0.3)
    one = run_zupt(g.t_s, g.acc_b, gyro, g.stance, cfg, smooth=True, segment=10**9)
    seg = run_zupt(g.t_s, g.acc_b, gyro, g.stance, cfg, smooth=True, segment=segment)
    for name in ("pos_n", "vel_n", "q_nb", "pos_var", "vel_var", "att_var", "gyro_bias"):
        np.testing.assert_array_equal(getattr(seg, name), getattr(one, name), err_msg=name)
    assert np.any(one.gyro_bias != 0.0)
    with pytest.raises(InputError, match="at least 2"):
        run_zupt(g.t_s, g.acc_b, gyro, g.stance, cfg, smooth=True, segment=1)
