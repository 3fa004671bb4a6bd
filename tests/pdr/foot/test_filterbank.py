"""Filter bank (seed 002): analytic checks, simulate-then-recover, transition learning."""

from typing import Any

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.foot.detectors import detect
from pdr.foot.filterbank import (
    PI_DEFAULT,
    PI_INIT,
    FilterBankConfig,
    check_transition,
    learn_swing_noise,
    learn_transition,
    polar_rotation,
    run_filterbank,
    transition_at_rate,
    transition_log_likelihood,
)
from pdr.foot.zupt import ZuptConfig, run_zupt
from pdr.frames import GRAVITY_MPS2
from tests.pdr.foot.gait import Gait, simulate_gait


def test_polar_decomposition_gives_the_chordal_mean_rotation() -> None:
    rng = np.random.default_rng(0)
    base = quat.from_euler(0.3, -0.2, 1.0)
    qs = quat.multiply(quat.from_rotvec(rng.normal(0, 0.1, (9, 3))), base)
    w = rng.dirichlet(np.ones(9))
    c = polar_rotation(np.einsum("i,ijk->jk", w, quat.to_rotmat(qs)))
    np.testing.assert_allclose(c @ c.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(c) == pytest.approx(1.0, abs=1e-12)
    # Close to the base rotation the leaves scatter around, and exact for identical leaves.
    assert quat.angle_between(quat.from_rotmat(c), base) < 0.1
    same = polar_rotation(quat.to_rotmat(base) * 1.0)
    np.testing.assert_allclose(same, quat.to_rotmat(base), atol=1e-12)
    # A reflection-like input still gives a proper rotation.
    assert np.linalg.det(polar_rotation(np.diag([1.0, 1.0, -1.0]))) == pytest.approx(1.0)


def test_transition_at_rate_keeps_dwell_times() -> None:
    pi = check_transition([[0.99, 0.02, 0.0], [0.01, 0.96, 0.05], [0.0, 0.02, 0.95]])
    np.testing.assert_allclose(transition_at_rate(pi, 100.0, 100.0), pi)
    fast = transition_at_rate(pi, 100.0, 200.0)
    np.testing.assert_allclose(fast.sum(axis=0), 1.0)
    # Mean dwell time 1 / (1 - p_ii) samples doubles when the rate doubles.
    np.testing.assert_allclose((1 - np.diag(pi)) / (1 - np.diag(fast)), 2.0, rtol=1e-9)
    with pytest.raises(InputError, match="sum to 1"):
        check_transition(np.full((3, 3), 0.5))


@pytest.mark.parametrize("variant", ["speed", "height"])
def test_filter_bank_recovers_a_simulated_walk(variant: str) -> None:
    g = simulate_gait(n_strides=8, stride_m=1.3, turn_rad=np.radians(10.0), sigma_acc=0.02, sigma_gyro=0.002,
                      seed=2)
    zv = detect(g.acc_b, g.gyro_b, 200.0)
    tr = run_filterbank(g.t_s, g.acc_b, g.gyro_b, zv, FilterBankConfig(variant=variant))
    zupt = run_zupt(g.t_s, g.acc_b, g.gyro_b, zv)
    err = np.linalg.norm(tr.pos_n[-1, :2] - g.pos_n[-1, :2])
    assert err < 0.01 * 8 * 1.3
    assert err < 2.0 * np.linalg.norm(zupt.pos_n[-1, :2] - g.pos_n[-1, :2]) + 0.02
    # The most probable mode finds the stances and the swings.
    core = g.stance & (np.convolve(g.stance, np.ones(21), "same") >= 21)
    swing = ~g.stance & (np.convolve(~g.stance, np.ones(61), "same") >= 61)
    assert tr.zero_velocity[core].mean() > 0.95
    assert tr.zero_velocity[swing].mean() < 0.05
    # Merged covariances (eqs. 7b, 9) are PSD, mode probabilities a distribution.
    assert np.all(tr.pos_var >= 0) and np.all(tr.vel_var >= 0) and np.all(tr.att_var >= 0)
    np.testing.assert_allclose(tr.mode_prob[tr.start_index + 1:].sum(axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(tr.q_nb, axis=1), 1.0, atol=1e-12)
    assert np.isfinite(tr.log_likelihood)
    if variant == "height":
        assert abs(tr.pos_n[-1, 2] - g.pos_n[-1, 2]) < 0.02


def _jump_markov_rotation(pi: np.ndarray, n: int, rate_hz: float, seed: int) -> tuple[np.ndarray, ...]:
    """IMU at rest on a turntable whose yaw rate follows a Markov chain of the speed variant's modes (eq. 3e):
    5 rad/s (unconstrained), 0.6 rad/s (almost stationary: within sigma_omega = 0.5 of eq. 12e, far outside the
    stationary 0.05), 0 (stationary); 1 s stationary first for the initialisation. Gravity stays along the body
    z axis, so the kinematics are exact; returns t, acc, gyro, stationary flags and the mode sequence."""
    rng = np.random.default_rng(seed)
    m = np.full(n, 2)
    for k in range(int(rate_hz), n):
        m[k] = rng.choice(3, p=pi[:, m[k - 1]])
    gyro = rng.normal(0.0, 0.01, (n, 3))
    gyro[:, 2] += np.array([5.0, 0.6, 0.0])[m]
    acc = rng.normal(0.0, 0.05, (n, 3)) + [0.0, 0.0, GRAVITY_MPS2]
    return np.arange(n) / rate_hz, acc, gyro, m == 2, m


def test_learning_recovers_the_transition_matrix_of_a_simulated_jump_markov_model() -> None:
    # Simulate-then-recover for eq. 11a: Pi of the simulated chain (per sample at 50 Hz), learned from the seed's
    # initial matrix (PI_INIT) by the bounded likelihood search.
    truth = np.array([[0.98, 0.05, 0.0], [0.02, 0.85, 0.04], [0.0, 0.10, 0.96]])
    t, acc, gyro, zv, m = _jump_markov_rotation(truth, 900, 50.0, seed=1)
    cfg = FilterBankConfig(max_leaves=3)
    seqs = [(t, acc, gyro, zv)]
    res = learn_transition(seqs, cfg, rate_hz=50.0, max_evaluations=36)
    assert res.log_likelihood.size == 36
    assert res.log_likelihood[0] == pytest.approx(transition_log_likelihood(seqs, cfg, PI_INIT["speed"], 50.0))
    best = res.best_so_far
    assert np.all(np.diff(best) >= 0) and best[-1] > best[0] + 500.0
    assert transition_log_likelihood(seqs, cfg, res.transition, 50.0) == pytest.approx(best[-1])
    # Close to the chain's own transition frequencies (their ML estimate) and to the truth, far closer than the
    # initial matrix; within a few nats of the truth's likelihood.
    counts = np.zeros((3, 3))
    np.add.at(counts, (m[1:], m[:-1]), 1.0)
    assert np.abs(res.transition - counts / counts.sum(axis=0)).max() < 0.06
    assert np.abs(res.transition - truth).max() < 0.1 < 0.5 < np.abs(np.array(PI_INIT["speed"]) - truth).max()
    assert best[-1] > transition_log_likelihood(seqs, cfg, truth, 50.0) - 10.0
    # Stochastic columns, Fig. 1a's structural zeros (no direct 1 <-> 3 jump) kept.
    np.testing.assert_allclose(res.transition.sum(axis=0), 1.0)
    assert res.transition[2, 0] == 0.0 and res.transition[0, 2] == 0.0


def test_learning_keeps_the_height_diagram_and_checks_the_initial_matrix() -> None:
    t, acc, gyro, zv, _ = _jump_markov_rotation(np.array(PI_DEFAULT["speed"][0]), 200, 50.0, seed=2)
    res = learn_transition([(t, acc, gyro, zv)], FilterBankConfig(variant="height", max_leaves=3), rate_hz=50.0,
                           max_evaluations=6)
    assert res.log_likelihood.size == 6 and res.best_so_far[-1] >= res.log_likelihood[0]
    # Fig. 1b: mode 2 (stationary at a new height) always goes on to mode 3; mode 3 never returns to mode 2.
    np.testing.assert_array_equal(res.transition[:, 1], [0.0, 0.0, 1.0])
    assert res.transition[1, 2] == 0.0 and np.all(res.transition[:, 0] > 0)
    with pytest.raises(InputError, match="diagram"):
        learn_transition([(t, acc, gyro, zv)], FilterBankConfig(), rate_hz=50.0, initial=np.full((3, 3), 1 / 3))


def test_bad_configuration() -> None:
    with pytest.raises(InputError, match="variant"):
        FilterBankConfig(variant="fast")
    with pytest.raises(InputError, match="sigma_v"):
        FilterBankConfig(sigma_v=(0.0, -1.0, 0.1))
    with pytest.raises(InputError, match="max_leaves"):
        FilterBankConfig(max_leaves=0)
    with pytest.raises(InputError, match="zero angular-rate") as err:
        FilterBankConfig(zupt=ZuptConfig(zaru=True))
    assert err.value.field == "zaru"


@pytest.mark.parametrize("interval", [False, True])
def test_sample_timing_of_an_acceleration_pulse(interval: bool) -> None:
    """The ZUPT-INS's sample timing (``ZuptConfig.interval_samples``, see its pulse test) in the bank's prediction.

    A pulse of 300 m/s^2 over one interval of a level IMU that rested before: the unconstrained mode takes over
    at once, and the bank integrates the samples as the ZUPT-INS does: as interval means the velocity is complete
    at the pulse's sample and the position is ahead by ``a dt^2 / 2``; as instants half the velocity comes a
    sample later.
    """
    rate, a, m = 100.0, 300.0, 80
    dt = 1.0 / rate
    t = np.arange(200) * dt
    acc = np.tile([0.0, 0.0, GRAVITY_MPS2], (t.size, 1))
    acc[m, 0] = a
    cfg = FilterBankConfig(zupt=ZuptConfig(interval_samples=interval, hde_directions=0))
    tr = run_filterbank(t, acc, np.zeros_like(acc), t < 0.5, cfg)
    assert np.all(tr.mode[m:] == 0)
    assert tr.vel_n[m, 0] == pytest.approx(a * dt * (1.0 if interval else 0.5), rel=1e-9)
    assert tr.vel_n[m + 1, 0] == pytest.approx(a * dt, rel=1e-9)
    lead = a * dt * (t[-1] - t[m])
    assert tr.pos_n[-1, 0] == pytest.approx(lead + (0.5 * a * dt**2 if interval else 0.0), rel=1e-9)


def test_height_variant_regains_stance_after_a_swing_velocity_error() -> None:
    # Issue #5: a swing-time accelerometer disturbance (1.5 m/s^2 for 0.4 s: up to 0.6 m/s of velocity error
    # at foot-down, as the worst real walking swings show) must not make the eq. 13 bank lose the stances. With
    # the ZUPT INS's per-sample process noise the leaf covariance says ~0.03 m/s, the stationary likelihood
    # (eq. 6c) vanishes and the unconstrained mode absorbs the rest of the walk; the calibrated acc_psd keeps them.
    g = simulate_gait(n_strides=8, stride_m=1.3, sigma_acc=0.02, sigma_gyro=0.002, seed=5)
    acc = g.acc_b.copy()
    swing = ~g.stance & (np.convolve(~g.stance, np.ones(41), "same") >= 41)
    acc[swing, 0] += 1.5
    zv = detect(acc, g.gyro_b, 200.0)
    core = g.stance & (np.convolve(g.stance, np.ones(21), "same") >= 21) & (g.t_s > 2.0)
    tr = run_filterbank(g.t_s, acc, g.gyro_b, zv, FilterBankConfig(variant="height"))
    assert tr.zero_velocity[core].mean() > 0.9
    assert np.max(np.linalg.norm(tr.vel_n, axis=1)) < 6.0             # true swing peak: 4.4 m/s
    # The lost-stance recovery (max_swing_s) off: this is about the likelihoods alone.
    small_q: dict[str, Any] = {"variant": "height", "acc_psd": 0.5**2 / 200.0, "sigma_nc": 1.0, "max_swing_s": 0.0}
    old = run_filterbank(g.t_s, acc, g.gyro_b, zv, FilterBankConfig(**small_q, nc_state_spread=False))
    assert old.zero_velocity[core].mean() < 0.5
    # Scoring the unconstrained mode with the leaf's spread (nc_state_spread, the default) keeps them even so.
    spread = run_filterbank(g.t_s, acc, g.gyro_b, zv, FilterBankConfig(**small_q))
    assert spread.zero_velocity[core].mean() > 0.9
    with pytest.raises(InputError, match="positive"):
        FilterBankConfig(acc_psd=0.0)


def _running_gait(disturbance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Gait]:
    # Short stances, 2.5 m strides and a swing-time accelerometer disturbance (m/s^2, 0.2 s per swing).
    g = simulate_gait(n_strides=12, stride_m=2.5, stance_s=0.15, swing_s=0.4, sigma_acc=0.02, sigma_gyro=0.002,
                      seed=5)
    acc = g.acc_b.copy()
    swing = ~g.stance & (np.convolve(~g.stance, np.ones(41), "same") >= 41)
    acc[swing, 0] += disturbance
    return g.t_s, acc, g.gyro_b, detect(acc, g.gyro_b, 200.0), g


def test_swing_noise_is_learned_from_zupt_runs() -> None:
    # Issue #5: the velocity error at foot-down grows with the disturbance, q with its square.
    learned = []
    for d in (2.0, 4.0):
        t, acc, gyro, zv, _ = _running_gait(d)
        z = run_zupt(t, acc, gyro, zv)
        learned.append(learn_swing_noise([(t, z.vel_n, z.q_nb, acc, gyro, zv)]))
    assert learned[0].swings == learned[1].swings >= 10
    assert 2.5 < learned[1].acc_psd / learned[0].acc_psd < 6.0
    assert learned[1].rms[0] > 1.0                                  # forward swing velocity, m/s
    with pytest.raises(InputError, match="no swing"):
        t = np.arange(100) / 100.0
        learn_swing_noise([(t, np.zeros((100, 3)), np.tile([1.0, 0, 0, 0], (100, 1)), np.zeros((100, 3)),
                            np.zeros((100, 3)), np.ones(100, dtype=bool))])


def test_height_variant_keeps_running_stances_with_the_learned_swing_noise() -> None:
    # Issue #5 regression: learned acc_psd and sigma_nc (ACC_PSD_DEFAULT, SIGMA_NC_DEFAULT) are the defaults.
    t, acc, gyro, zv, g = _running_gait(4.0)
    cfg = FilterBankConfig(variant="height")
    assert cfg.unconstrained_sigma() > 2.0 and cfg.acc_noise_var(200.0) > 0.3 * 200.0
    core = g.stance & (np.convolve(g.stance, np.ones(9), "same") >= 9) & (g.t_s > 1.0)
    tr = run_filterbank(t, acc, gyro, zv, cfg)
    assert tr.zero_velocity[core].mean() > 0.95
    assert np.linalg.norm(tr.pos_n[-1, :2] - g.pos_n[-1, :2]) < 0.15
    with pytest.raises(InputError, match="sigma_nc"):
        FilterBankConfig(sigma_nc=-1.0)
