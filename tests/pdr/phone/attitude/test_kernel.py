"""The attitude filter's compiled measurement updates: the UKF (seed 003 eqs. 35-40), the product's one, against
filterpy's and against the linearised (EKF) update."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.frames import GRAVITY_MPS2
from pdr.phone.attitude.kernel import (
    ekf_update,
    mag_yaw_update,
    measurement,
    ukf_update,
    ukf_update_into,
    ukf_workspace,
)


def _update_case(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A prior attitude with a few degrees of spread, and an accelerometer + magnetometer measurement of another."""
    rng = np.random.default_rng(seed)
    roll, pitch = rng.uniform(-0.5, 0.5, 2)
    q = quat.from_euler(roll, pitch, rng.uniform(-math.pi, math.pi))
    a = rng.standard_normal((4, 4)) * 0.03
    p = a @ a.T + 1e-4 * np.eye(4)
    q_true = quat.multiply(q, quat.from_euler(0.05, -0.03, 0.1))
    g_ref, h_ref = np.array([0.0, 0.0, GRAVITY_MPS2]), np.array([0.0, 20.0, -40.0])
    z = measurement(q_true, g_ref, h_ref, True, True, 6) + rng.normal(0.0, 0.1, 6)
    r = np.r_[np.full(3, 0.5**2), np.full(3, 3.0**2)]
    return q, p, z, r, g_ref, h_ref


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_product_ukf_update_matches_filterpy(seed):
    """The attitude filter's compiled UKF update (eqs. 35-40) is filterpy's unscented update on the same sigma
    points, renormalised."""
    filterpy = pytest.importorskip("filterpy.kalman")
    q, p, z, r, g_ref, h_ref = _update_case(seed)
    alpha, beta, kappa = 0.5, 2.0, 1.0
    pts = filterpy.MerweScaledSigmaPoints(4, alpha=alpha, beta=beta, kappa=kappa)
    ref = filterpy.UnscentedKalmanFilter(dim_x=4, dim_z=6, dt=0.01, fx=lambda x, dt: x, points=pts,
                                         hx=lambda x: measurement(x, g_ref, h_ref, True, True, 6))
    ref.x, ref.P, ref.R = q.copy(), p.copy(), np.diag(r)
    ref.sigmas_f = pts.sigma_points(q, p)
    ref.update(z)
    q1, p1 = q.copy(), p.copy()
    ukf_update(q1, p1, z, r, g_ref, h_ref, True, True, alpha, beta, kappa)
    expected = ref.x / np.linalg.norm(ref.x) * np.sign(ref.x[0])
    np.testing.assert_allclose(q1, expected, atol=1e-12)
    np.testing.assert_allclose(p1, ref.P, atol=1e-12)
    assert quat.angle_between(q1, q) > 0.01          # the measurement moved the attitude


def test_ukf_update_with_a_reused_workspace_equals_a_fresh_one():
    """run_kernel reuses one workspace for every sample: six rows, then the accelerometer's three, then six again
    through one dirty workspace give bit for bit what a fresh workspace per update gives."""
    ws = ukf_workspace()
    for arr in ws:
        arr[...] = np.nan
    for seed, rows in ((3, 6), (4, 3), (5, 6)):
        q, p, z, r, g_ref, h_ref = _update_case(seed)
        use_m = rows == 6
        q1, p1, q2, p2 = q.copy(), p.copy(), q.copy(), p.copy()
        ukf_update(q1, p1, z[:rows], r[:rows], g_ref, h_ref, True, use_m, 0.5, 2.0, 1.0)
        ukf_update_into(q2, p2, z[:rows], r[:rows], g_ref, h_ref, True, use_m, 0.5, 2.0, 1.0, ws)
        assert np.array_equal(q1, q2) and np.array_equal(p1, p2)
        assert not np.array_equal(q1, q)                 # the update did something


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_product_ukf_update_tends_to_the_ekf_update_for_a_small_spread(seed):
    """With the paper's alpha = 1e-3 (the centre-point subtraction keeps the -1e6 weights from cancelling) the
    unscented update differs from the linearised one by terms of second order in the spread: a prior 100x
    narrower makes them vanish against the correction."""
    q, p, z, r, g_ref, h_ref = _update_case(seed)
    for scale, bound in ((1.0, 0.1), (1e-4, 1e-3)):
        qu, pu = q.copy(), p * scale
        ukf_update(qu, pu, z, r * scale, g_ref, h_ref, True, True, 1e-3, 2.0, 0.0)
        qe, pe = q.copy(), p * scale
        ekf_update(qe, pe, z, r * scale, g_ref, h_ref, True, True)
        assert quat.angle_between(qu, qe) < bound * quat.angle_between(qu, q)
        np.testing.assert_allclose(pu, pe, atol=bound * np.abs(p * scale).max())


def _yaw_case(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A true tilted attitude, an estimate 10 deg off in yaw about up (tilt exact), its covariance (yaw sigma 20 deg,
    tilt 1 deg), and the yaw error (rad)."""
    rng = np.random.default_rng(seed)
    roll, pitch = rng.uniform(-0.6, 0.6, 2)
    q_true = quat.from_euler(roll, pitch, rng.uniform(-math.pi, math.pi))
    err = math.radians(10.0)
    q = quat.multiply(quat.from_rotvec([0.0, 0.0, -err]), q_true)
    g = np.array([-q[3], -q[2], q[1], q[0]])
    p = 0.25 * math.radians(20.0) ** 2 * np.outer(g, g) + 0.25 * math.radians(1.0) ** 2 * (np.eye(4) - np.outer(g, g))
    return q_true, q, p, err


def _tilt_deg(q: np.ndarray, q_true: np.ndarray) -> float:
    """Angle (deg) between the two attitudes' up directions in the device frame."""
    up = np.array([0.0, 0.0, 1.0])
    a, b = quat.rotate(quat.conjugate(q), up), quat.rotate(quat.conjugate(q_true), up)
    return math.degrees(math.acos(min(1.0, float(a @ b))))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mag_yaw_update_corrects_the_yaw_by_the_kalman_gain_and_keeps_the_tilt(seed):
    q_true, q, p, err = _yaw_case(seed)
    h_n = np.array([0.0, 20.0, -40.0])                       # magnetic north, dipping down
    m_b = quat.rotate(quat.conjugate(q_true), h_n)           # a clean field measured by the true attitude
    sigma_m = 10.0
    mag_yaw_update(q, p, m_b, 0.0, sigma_m)
    var_yaw, var_meas = math.radians(20.0) ** 2, (sigma_m / 20.0) ** 2
    expected_left = err * (1.0 - var_yaw / (var_yaw + var_meas))   # linear Kalman update of the yaw error
    left = float(quat.to_rotvec(quat.multiply(q_true, quat.conjugate(q)))[2])
    assert left == pytest.approx(expected_left, abs=math.radians(0.3))
    assert _tilt_deg(q, q_true) < 1e-6
    assert 4 * (np.array([-q[3], -q[2], q[1], q[0]]) @ p @ np.array([-q[3], -q[2], q[1], q[0]])) < var_yaw


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_tilted_disturbed_field_moves_the_three_rows_tilt_but_not_the_yaw_rows(seed):
    q_true, _q, _p, _ = _yaw_case(seed)
    h_n = np.array([0.0, 20.0, -40.0])
    disturbed = quat.rotate(quat.from_rotvec([math.radians(25.0), 0.0, 0.0]), h_n)   # the field tipped 25 deg
    m_b = quat.rotate(quat.conjugate(q_true), disturbed)
    p = 0.25 * math.radians(5.0) ** 2 * np.eye(4)
    q_rows, p_rows = q_true.copy(), p.copy()
    ukf_update(q_rows, p_rows, m_b, np.full(3, 10.0 ** 2), np.zeros(3), h_n, False, True, 0.5, 2.0, 1.0)
    q_yaw, p_yaw = q_true.copy(), p.copy()
    mag_yaw_update(q_yaw, p_yaw, m_b, 0.0, 10.0)
    assert _tilt_deg(q_rows, q_true) > 0.5                   # eq. 11's rows take the tipped field for a tilt
    assert _tilt_deg(q_yaw, q_true) < 1e-6                   # the yaw row cannot tilt the attitude
