"""Heading: PCA axis, 180-degree rule, f(q) of eqs. 27-32, second-UKF fusion, landmark attitude update."""

import json
import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import wrap_angle
from pdr.phone.heading import (
    DirectionVote,
    HeadingEstimate,
    StepDriftElimination,
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


def grid_walk(rng, n_legs=16, grid_deg=30.0, error_deg=lambda t: 0.0, off_grid=()):
    """Steps (raw yaw, length, end time, true yaw) of a walk along a rectangular building whose corridors run
    at ``grid_deg`` + k 90 deg; the raw yaw carries ``error_deg(t)`` plus a left-right sway and noise.
    Legs in ``off_grid`` run 45 deg off the grid."""
    out = []
    t = 0.0
    for leg in range(n_legs):
        true = math.radians(grid_deg + 90.0 * int(rng.integers(0, 4)) + (45.0 if leg in off_grid else 0.0))
        for k in range(int(rng.integers(14, 24))):
            t += 0.55
            raw = true + math.radians(error_deg(t) + (3.0 if k % 2 else -3.0) + rng.normal(0, 1.5))
            out.append((raw, 0.7, t, true, leg))
    return out


def run_hde(steps, hde=None):
    hde = hde or StepDriftElimination()
    return hde, np.array([hde.step(s[0], s[1], s[2]) for s in steps])


def test_drift_elimination_removes_a_varying_heading_error_on_a_grid():
    rng = np.random.default_rng(3)
    # A deflection that varies along the walk (zero mean, as the magnetometer's in a steel building).
    steps = grid_walk(rng, error_deg=lambda t: 8.0 * math.sin(t / 25.0))
    hde, out = run_hde(steps)
    true = np.array([s[3] for s in steps])
    raw = np.array([s[0] for s in steps])
    half = slice(len(steps) // 2, None)

    def stride_error(yaw):      # the sway cancels over a stride (two steps)
        e = wrap_angle(yaw - true)[half]
        return np.degrees(np.abs(e[: e.size // 2 * 2].reshape(-1, 2).mean(axis=1))).mean()

    e_raw, e_out = stride_error(raw), stride_error(out)
    assert hde.updates > 20
    assert e_out < 0.6 * e_raw         # 0.3-0.55 over seeds 0-9
    # The learnt dominant direction is the grid's (mod 90 deg).
    ref = math.degrees(math.atan2(hde.dominant[1], hde.dominant[0]) / 4)
    assert abs(((ref - 30.0) + 45.0) % 90.0 - 45.0) < 3.0


def test_drift_elimination_leaves_off_grid_legs_and_constant_offsets():
    rng = np.random.default_rng(4)
    # A constant offset cannot be told from the building's orientation: nothing to correct.
    steps = grid_walk(rng, error_deg=lambda t: 7.0)
    _, out = run_hde(steps)
    raw = np.array([s[0] for s in steps])
    assert np.degrees(np.abs(wrap_angle(out - raw))).max() < 2.0
    # A leg 45 deg off every dominant direction gives no measurement: the correction stays put through it.
    steps = grid_walk(np.random.default_rng(5), n_legs=8, error_deg=lambda t: 10.0 * math.sin(t / 20.0),
                      off_grid=(6,))
    _, out = run_hde(steps)
    leg6 = np.array([s[4] == 6 for s in steps])
    corr = np.degrees(wrap_angle(out - np.array([s[0] for s in steps])))
    assert np.ptp(corr[leg6][2:]) < 0.5      # its first stride may still close a straight run of the leg before


def test_drift_elimination_state_round_trip():
    steps = grid_walk(np.random.default_rng(6), error_deg=lambda t: 10.0 * math.sin(t / 20.0))
    _, whole = run_hde(steps)
    first, a = run_hde(steps[:150])
    again = StepDriftElimination.from_state(json.loads(json.dumps(first.state())))
    _, b = run_hde(steps[150:], again)
    np.testing.assert_array_equal(np.concatenate([a, b]), whole)


def test_a_site_grid_removes_the_offset_a_learnt_grid_keeps():
    # The walk's headings are deflected by a constant 7 deg: learnt dominant directions absorb it (nothing to
    # correct, test above), the building's grid from a site description does not.
    steps = grid_walk(np.random.default_rng(4), error_deg=lambda t: 7.0)
    true = np.array([s[3] for s in steps])
    hde, out = run_hde(steps, StepDriftElimination(grid_yaw=math.radians(30.0 + 180.0)))   # any main axis
    half = slice(len(steps) // 2, None)
    err = np.degrees(wrap_angle(out - true))[half]
    stride = err[: err.size // 2 * 2].reshape(-1, 2).mean(axis=1)
    assert hde.updates > 20
    assert np.abs(stride).mean() < 2.0                                   # raw: 7 deg
    again = StepDriftElimination.from_state(json.loads(json.dumps(hde.state())), grid_yaw=hde.grid_yaw)
    assert again.grid_yaw == hde.grid_yaw


def test_site_grid_is_read_checked_and_reaches_the_pipeline():
    from pdr.errors import InputError
    from pdr.phone.landmarks import Site
    from pdr.phone.pipeline import PdrPipeline, PipelineConfig
    site = Site.from_dict({"landmarks": [], "grid_deg": 69.5})
    assert site.grid_deg == 69.5 and Site.from_dict(site.to_dict()) == site
    assert "grid_deg" not in Site.from_dict({"landmarks": []}).to_dict()
    with pytest.raises(InputError, match="grid_deg"):
        Site.from_dict({"landmarks": [], "grid_deg": "north"})
    p = PdrPipeline(PipelineConfig(placement="hand"), site)
    assert p.drift.hde.grid_yaw == pytest.approx(math.radians(90.0 - 69.5))  # ENU yaw of a compass bearing
    from pdr import state_codec
    again = PdrPipeline.from_state(state_codec.loads(state_codec.dumps(p.state())))
    assert again.drift.hde.grid_yaw == p.drift.hde.grid_yaw


def test_pca_axis_gives_the_bits_of_numpys_centring() -> None:
    """The compiled centring of pca_axis is numpy's h - h.mean(axis=0), bit for bit, on the strided (M, 2) view of
    (M, 3) samples the pipeline passes."""
    rng = np.random.default_rng(11)
    for m in [*range(2, 130), 301]:
        f_n = rng.normal(size=(m, 3)) * 10.0 ** rng.integers(-3, 3, size=(m, 3))
        h = f_n[:, :2]
        d = h - h.mean(axis=0)
        s00, s01, _s10, s11 = (d.T @ d).ravel().tolist()
        ang = 0.5 * math.atan2(2.0 * s01, s00 - s11)
        tr, det = s00 + s11, s00 * s11 - s01 ** 2
        disc = math.sqrt(max(tr * tr / 4 - det, 0.0))
        assert pca_axis(h) == (ang, (tr / 2 + disc) / max(tr / 2 - disc, 1e-12)), m


def test_mean_yaw_gives_the_bits_of_numpys_sums() -> None:
    rng = np.random.default_rng(12)
    for m in [*range(1, 140), 400]:
        y = rng.uniform(-math.pi, math.pi, m) * rng.uniform(0.01, 1.0)
        assert mean_yaw(y) == math.atan2(float(np.sin(y).sum()), float(np.cos(y).sum())), m
