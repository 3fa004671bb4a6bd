"""Finite-difference checks of the EKF measurement Jacobians: each analytic ``H`` against central differences of
its measurement function ``h(x)`` at random states (errors injected in the filter's own error-state convention)."""

import math

import numpy as np
import pytest

from pdr.foot.bc import A_, BF, BW, TH, W_, _imu_rows
from pdr.foot.bc import N_ERR as BC_N_ERR
from pdr.foot.filterbank import N_ERR, XI, _constraint_rows
from pdr.fusion.ranging import kalman_range_moments


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
