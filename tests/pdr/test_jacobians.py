"""Finite-difference checks of the EKF measurement Jacobians: each analytic ``H`` against central differences of
its measurement function ``h(x)`` at random states (errors injected in the filter's own error-state convention)."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.foot.bc import A_, BF, BW, TH, W_, _imu_rows
from pdr.foot.bc import N_ERR as BC_N_ERR
from pdr.foot.drift import HDE_P00, HDE_P01, HDE_P11, HDE_RATE, drift_update, initial_state
from pdr.foot.filterbank import N_ERR, XI, _constraint_rows
from pdr.foot.zupt import ZuptConfig
from pdr.foot.zupt.kernel import zupt_update
from pdr.fusion.ranging import kalman_range_moments
from pdr.phone.attitude.kernel import ekf_update as att_ekf_update
from pdr.phone.attitude.kernel import measurement as att_measurement
from pdr.phone.phone_orientation import phone_yaw_update, yaw_difference


def _rotation(phi: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    a = float(np.linalg.norm(phi))
    if a < 1e-15:
        return np.eye(3)
    k = phi / a
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * kx + (1.0 - math.cos(a)) * kx @ kx


def _fd_jacobian(h, x0: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(x0.size):
        d = np.zeros_like(x0)
        d[i] = eps
        cols.append((h(x0 + d) - h(x0 - d)) / (2 * eps))
    return np.column_stack(cols)


@pytest.mark.parametrize("seed", range(5))
def test_filter_bank_constraint_rows(seed):
    """pdr.foot.filterbank (seed 002 eqs. 12c, 13b): zero velocity, zero angular rate, specific force equal to
    minus gravity, height equal to the stored height; error state (position, velocity, navigation-frame rotation
    vector with true = exp(dtheta) est, stored height).
    """
    rng = np.random.default_rng(seed)
    p, v, w_k = rng.normal(0, 3, 3), rng.normal(0, 0.3, 3), rng.normal(0, 0.2, 3)
    f_n = np.array([0.0, 0.0, 9.81]) + rng.normal(0, 1.0, 3)
    g_n = np.array([0.0, 0.0, -9.81])
    xi = float(rng.normal(0, 1))

    def h(dx: np.ndarray) -> np.ndarray:
        # The measured quantities of the true state x = est (+) dx; the angular rate is no state: it does not move.
        f_true = _rotation(dx[6:9]) @ f_n
        return np.concatenate([v + dx[3:6], w_k, f_true + g_n, [(p[2] + dx[2]) - (xi + dx[XI])]])

    H, e = _constraint_rows(v, w_k, f_n, g_n, p[2] - xi)
    assert H.shape == (10, N_ERR)
    np.testing.assert_allclose(e, -h(np.zeros(N_ERR)), atol=1e-12)          # residual y - h with y = 0
    np.testing.assert_allclose(H, _fd_jacobian(h, np.zeros(N_ERR)), atol=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_range_update_is_the_ekf_update_with_the_range_jacobian(seed):
    """pdr.fusion.ranging (seed 001 Sec. 4.1): ``h(z) = |z|`` of the relative position; the linearised update must
    equal the Kalman update with the finite-difference Jacobian."""
    rng = np.random.default_rng(seed)
    z1 = rng.normal(0, 5, 2)
    a = rng.normal(0, 1, (2, 2))
    cov = a @ a.T + 0.1 * np.eye(2)
    r, var = float(np.linalg.norm(z1)) + rng.normal(0, 0.5), 0.09
    H = _fd_jacobian(lambda z: np.array([np.linalg.norm(z)]), z1)
    s = H @ cov @ H.T + var
    k = cov @ H.T / s
    out = kalman_range_moments(z1, cov, r, var)
    assert out is not None
    mean, new_cov = out
    np.testing.assert_allclose(mean, z1 + (k * (r - np.linalg.norm(z1))).ravel(), rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(new_cov, cov - k @ s @ k.T, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_belief_condensation_imu_rows(seed):
    """pdr.foot.bc (seed 000 eqs. 5-6): accelerometer ``C(q)^T (a - g) + b_f`` and gyroscope ``omega + b_omega`` on
    the error state (dp, dv, da, dtheta, domega, db_f, db_omega), true attitude ``exp(dtheta) C``.
    """
    rng = np.random.default_rng(seed)
    c = _rotation(rng.normal(0, 1.5, 3))
    a, w, bf, bw = (rng.normal(0, s, 3) for s in (2.0, 1.0, 0.1, 0.01))
    g_n = np.array([0.0, 0.0, -9.81])
    f_k, w_k = rng.normal(0, 10, 3), rng.normal(0, 1, 3)

    def h(dx: np.ndarray) -> np.ndarray:
        ct = (_rotation(dx[TH:TH + 3]) @ c).T
        return np.concatenate([ct @ (a + dx[A_:A_ + 3] - g_n) + bf + dx[BF:BF + 3],
                               w + dx[W_:W_ + 3] + bw + dx[BW:BW + 3]])

    H, e = _imu_rows(c, a - g_n, bf, w, bw, f_k, w_k)
    assert H.shape == (6, BC_N_ERR)
    np.testing.assert_allclose(e, np.concatenate([f_k, w_k]) - h(np.zeros(BC_N_ERR)), atol=1e-12)
    np.testing.assert_allclose(H, _fd_jacobian(h, np.zeros(BC_N_ERR)), atol=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_zupt_update_is_the_ekf_update_with_the_velocity_jacobian(seed):
    """pdr.foot.zupt (seed 001 eqs. 3-5): ``y = v = 0`` on the error state (dp, dv, dtheta) with true = est + dv;
    the update's error estimate, covariance and feedback must be the Kalman update with the finite-difference
    Jacobian of ``h(dx) = v + dv``."""
    rng = np.random.default_rng(seed)
    p, v = rng.normal(0, 3, 3), rng.normal(0, 0.2, 3)
    roll, pitch = rng.normal(0, 0.3, 2)
    q = quat.from_euler(roll, pitch, rng.uniform(-math.pi, math.pi))
    a = rng.normal(0, 0.1, (9, 9))
    cov = a @ a.T + 1e-4 * np.eye(9)
    r_var = 0.01**2
    H = _fd_jacobian(lambda dx: v + dx[3:6], np.zeros(9))
    s = H @ cov @ H.T + r_var * np.eye(3)
    k = cov @ H.T @ np.linalg.inv(s)
    dx_want = k @ (np.zeros(3) - v)
    p1, v1, q1, cov1, dx = p.copy(), v.copy(), q.copy(), cov.copy(), np.zeros(9)
    zupt_update(p1, v1, q1, cov1, r_var, dx)
    np.testing.assert_allclose(dx, dx_want, atol=1e-12)
    np.testing.assert_allclose(cov1, (np.eye(9) - k @ H) @ cov, atol=1e-10)
    np.testing.assert_allclose(np.r_[p1, v1], np.r_[p, v] + dx_want[:6], atol=1e-12)
    assert quat.angle_between(q1, quat.multiply(quat.from_rotvec(dx_want[6:9]), q)) < 1e-12


@pytest.mark.parametrize("seed", range(5))
def test_attitude_ekf_update_is_the_kalman_update_with_the_field_jacobian(seed):
    """pdr.phone.attitude (seed 003 eq. 10, the RMPCA EKF baseline): ``h(q) = [R(q)^T g; R(q)^T h]`` with ``R`` of the
    normalised ``q``. The kernel's measurement function must be that model, and its linearised update the Kalman
    update with the finite-difference Jacobian of it (written here with :mod:`pdr.quaternion`), renormalised."""
    rng = np.random.default_rng(seed)
    roll, pitch = rng.normal(0, 0.4, 2)
    q = quat.from_euler(roll, pitch, rng.uniform(-math.pi, math.pi))
    a = rng.normal(0, 0.03, (4, 4))
    cov = a @ a.T + 1e-5 * np.eye(4)
    g_ref, h_ref = np.array([0.0, 0.0, 9.81]), np.array([0.0, 18.0, -42.0])

    def h(x: np.ndarray) -> np.ndarray:
        c = quat.to_rotmat(x / np.linalg.norm(x))
        return np.concatenate([c.T @ g_ref, c.T @ h_ref])

    np.testing.assert_allclose(att_measurement(q, g_ref, h_ref, True, True, 6), h(q), atol=1e-12)
    H = _fd_jacobian(h, q)
    r = np.r_[np.full(3, 0.3), np.full(3, 4.0)]
    z = h(quat.multiply(q, quat.from_euler(0.02, -0.01, 0.05))) + rng.normal(0, 0.1, 6)
    s = H @ cov @ H.T + np.diag(r)
    k = cov @ H.T @ np.linalg.inv(s)
    q_want = q + k @ (z - h(q))
    q1, cov1 = q.copy(), cov.copy()
    att_ekf_update(q1, cov1, z, r, g_ref, h_ref, True, True)
    np.testing.assert_allclose(q1, q_want / np.linalg.norm(q_want) * np.sign(q_want[0]), atol=1e-8)
    np.testing.assert_allclose(cov1, (np.eye(4) - k @ H) @ cov, atol=1e-8)


@pytest.mark.parametrize("seed", range(5))
def test_phone_yaw_row_jacobian(seed):
    """pdr.phone.phone_orientation: the yaw pseudo-measurement's ``h = d psi / d q`` against central differences
    of the yaw difference it linearises (innovation ``psi(q_phone) - psi(q)``)."""
    rng = np.random.default_rng(seed)
    roll, pitch = rng.normal(0, 0.5, 2)
    q = quat.from_euler(roll, pitch, rng.uniform(-math.pi, math.pi))
    q_phone = quat.multiply(quat.from_euler(0.0, 0.0, 0.03), q)
    cov, var = np.eye(4) * 1e-4, 1e-3
    H = -_fd_jacobian(lambda x: np.atleast_1d(yaw_difference(q_phone, x / np.linalg.norm(x))), q)
    s = (H @ cov @ H.T).item() + var
    k = (cov @ H.T).ravel() / s
    q_want = q + k * float(yaw_difference(q_phone, q))
    q1, cov1, used = phone_yaw_update(q, cov, q_phone, var, gate_sigma=10.0)
    assert used
    np.testing.assert_allclose(q1, q_want / np.linalg.norm(q_want), atol=1e-9)
    np.testing.assert_allclose(cov1, cov - np.outer(k, k) * s, atol=1e-9)


def test_drift_elimination_update_is_the_kalman_update_of_the_heading_error():
    """pdr.foot.drift: a straight stride's deviation ``e`` from the dominant direction measures the heading error of
    the state (heading error, drift rate); the update must be the Kalman update with the finite-difference Jacobian
    of ``h(e, d) = e``."""
    par = ZuptConfig().hde_params()
    hde = initial_state(0.01)
    hde[HDE_P00], hde[HDE_P01], hde[HDE_P11] = 0.02, 0.003, 0.001
    angle = math.radians(3.0)
    n = int(par[4]) + 1
    for i in range(n):                               # straight strides along 3 deg: they set the reference
        drift_update(hde, i * math.cos(angle), i * math.sin(angle), par)
    cov = np.array([[hde[HDE_P00], hde[HDE_P01]], [hde[HDE_P01], hde[HDE_P11]]])
    rate = hde[HDE_RATE]
    e = math.radians(1.0)                            # the next stride deviates by 1 deg
    turn = drift_update(hde, (n - 1) * math.cos(angle) + math.cos(angle + e),
                        (n - 1) * math.sin(angle) + math.sin(angle + e), par)
    H = _fd_jacobian(lambda x: x[:1], np.zeros(2))
    s = (H @ cov @ H.T).item() + par[1]
    k = (cov @ H.T).ravel() / s
    assert math.isclose(turn, -k[0] * e, rel_tol=1e-9) and turn != 0.0
    assert math.isclose(hde[HDE_RATE] - rate, k[1] * e, rel_tol=1e-9)
    post = cov - np.outer(k, H @ cov)
    np.testing.assert_allclose([hde[HDE_P00], hde[HDE_P01], hde[HDE_P11]], [post[0, 0], post[0, 1], post[1, 1]],
                               atol=1e-15)
