"""Heading: PCA axis, 180-degree rule, f(q) of eqs. 27-32, second-UKF fusion, landmark attitude update."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import wrap_angle
from pdr.heading import (
    DirectionVote,
    HeadingEstimate,
    axis_difference,
    f_of_q,
    flexion_rate,
    fuse_landmark,
    improved_rmpca_ut,
    landmark_attitude_update,
    mean_yaw,
    pca_axis,
    resolve_direction,
    rmpca,
    scatter_at,
    thigh_swing_evidence,
)


def step_acc(yaw, q_nb, n=40, seed=0):
    """Body-frame specific force of a step whose horizontal acceleration oscillates along ``yaw``."""
    rng = np.random.default_rng(seed)
    s = 2.0 * np.sin(np.linspace(0, 2 * np.pi, n))
    f_n = np.column_stack([s * math.cos(yaw), s * math.sin(yaw), 9.81 + 0.5 * s]) + rng.normal(0, 0.05, (n, 3))
    return quat.rotate(quat.conjugate(q_nb), f_n)


@pytest.mark.parametrize("yaw_deg", [-170, -60, 0, 45, 120])
def test_rmpca_recovers_axis_under_any_device_attitude(yaw_deg):
    q = np.tile(quat.from_euler(0.4, -0.3, 2.0), (40, 1))
    axis, ratio = rmpca(q, step_acc(math.radians(yaw_deg), q[0]))
    d = float(wrap_angle(2 * (axis - math.radians(yaw_deg)))) / 2
    assert abs(math.degrees(d)) < 2 and ratio > 10


def test_resolve_direction_and_mean_yaw():
    assert resolve_direction(0.1, math.pi) == pytest.approx(float(wrap_angle(0.1 + math.pi)))
    assert resolve_direction(0.1, 0.5) == pytest.approx(0.1)
    assert abs(mean_yaw(np.array([math.pi - 0.05, -math.pi + 0.05]))) == pytest.approx(math.pi, abs=1e-9)
    with pytest.raises(ValueError):
        pca_axis(np.zeros((1, 2)))


def test_f_of_q_zero_at_the_estimate_and_shifts_with_rcs():
    q1 = quat.from_euler(0.2, 0.1, -1.0)
    q = np.tile(q1, (40, 1))
    acc = step_acc(0.7, q1)
    m = scatter_at(q, acc, q1)
    axis, _ = rmpca(q, acc)
    assert f_of_q(q1, m, axis) == pytest.approx(0.0, abs=1e-9)
    assert f_of_q(q1, m, axis - 0.2) == pytest.approx(0.2, abs=1e-6)


def test_ut_and_landmark_fusion():
    q1 = quat.from_euler(0.0, 0.0, 0.3)
    q = np.tile(q1, (40, 1))
    acc = step_acc(1.0, q1)
    m = scatter_at(q, acc, q1)
    axis, _ = rmpca(q, acc)
    est = improved_rmpca_ut(q1, np.eye(4) * 1e-4, m, 1.0, 1e-3)
    assert est.yaw == pytest.approx(axis, abs=1e-3) and est.var > 1e-3
    fused = fuse_landmark(HeadingEstimate(1.0, 0.01), 1.2, 0.01)
    assert fused.yaw == pytest.approx(1.1) and fused.var == pytest.approx(0.005)


def test_landmark_update_rotates_attitude_towards_landmark():
    q_est = quat.from_euler(0.0, 0.0, 0.0)
    q = np.tile(q_est, (40, 1))
    acc = step_acc(0.5, q_est)
    m = scatter_at(q, acc, q_est)
    psi0, _ = rmpca(q, acc)
    q_new, p_new = landmark_attitude_update(q_est, np.eye(4) * 1e-3, m, psi0, 0.1, math.radians(2) ** 2)
    _, _, yaw = quat.to_euler(q_new)
    assert 0.05 < float(yaw) < 0.11
    assert np.trace(p_new) < 4e-3


def thigh_stride(yaw, mount, stance=0.6, rate=100.0, period=1.1, amp_deg=40.0, cycles=1):
    """Attitudes of a phone on a thigh walking along ``yaw``: the thigh extends by ``amp_deg`` at a constant
    rate over the stance share of the cycle and flexes back over the rest (smoothed), turned by ``mount``.
    """
    n = int(period * rate)
    rate_w = np.where(np.arange(n) < stance * n, -1.0 / stance, 1.0 / (1.0 - stance))
    rate_w = np.tile(np.convolve(np.concatenate([rate_w[-5:], rate_w, rate_w[:5]]), np.ones(11) / 11, "valid"), cycles)
    theta = np.cumsum(rate_w) / rate_w.size * cycles * math.radians(amp_deg)
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])           # f x u: flexion is positive about it
    q = quat.multiply(quat.from_rotvec(theta[:, None] * right), quat.from_rotvec(np.array([0, 0, yaw])))
    return quat.multiply(q, mount)


@pytest.mark.parametrize("yaw_deg", [-150, -30, 0, 80, 179])
@pytest.mark.parametrize("mount_seed", [0, 1, 2])
def test_thigh_swing_evidence_points_forward_and_is_odd(yaw_deg, mount_seed):
    mount = quat.from_euler(*np.random.default_rng(mount_seed).uniform(-math.pi, math.pi, 3))
    q = thigh_stride(math.radians(yaw_deg), mount)
    ev = thigh_swing_evidence(q, 100.0, math.radians(yaw_deg))
    # Two-level rate -1/0.6, +1/0.4 (in amp/period): sum x^3 / (sum x^2)^1.5 = 0.41 / sqrt(N), less smoothing.
    assert 0.8 * 0.41 / math.sqrt(q.shape[0]) < ev < 0.41 / math.sqrt(q.shape[0])
    assert thigh_swing_evidence(q, 100.0, math.radians(yaw_deg) + math.pi) == pytest.approx(-ev)
    # The thigh turns about the lateral axis only: across the walking axis there is no flexion rate.
    assert np.abs(flexion_rate(q, 100.0, math.radians(yaw_deg + 90))).max() < 1e-6
    assert np.abs(flexion_rate(q, 100.0, math.radians(yaw_deg))).max() > 1.0


def test_thigh_swing_evidence_vanishes_for_a_symmetric_swing():
    q = thigh_stride(0.3, quat.from_euler(0.2, 1.0, -2.0), stance=0.5, cycles=2)
    assert abs(thigh_swing_evidence(q, 100.0, 0.3)) < 0.02
    with pytest.raises(InputError, match="attitude quaternions"):
        thigh_swing_evidence(q[:2], 100.0, 0.3)


def test_direction_vote_settles_then_needs_sustained_contrary_evidence():
    v = DirectionVote()
    assert v.update(-0.1) is True and v.score == pytest.approx(0.1)      # the start follows the evidence
    for _ in range(5):
        assert v.update(0.15) is False
    assert v.update(-0.2) is False                                        # one contrary stride never flips
    n_contrary = next(k for k in range(1, 13) if v.update(-0.15))
    assert 3 <= n_contrary < 10 and v.score >= 0


def test_axis_difference_is_modulo_pi():
    assert axis_difference(math.radians(170), math.radians(-5)) == pytest.approx(math.radians(-5))
    assert axis_difference(np.array([0.2, 0.2 + math.pi]), 0.1) == pytest.approx([0.1, 0.1])
