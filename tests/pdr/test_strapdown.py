import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2
from pdr.strapdown import (
    GRAVITY_N,
    NavState,
    initial_attitude_from_gravity,
    integrate,
    propagate_attitude,
    rotation_increment,
    step,
)

FS = 100.0


def _times(n: int) -> np.ndarray:
    return np.arange(n) / FS


def test_constant_rotation_rate_matches_analytic_attitude() -> None:
    n = 501
    t = _times(n)
    w = np.array([0.3, -0.2, 1.1])
    q0 = quat.from_euler(0.1, -0.2, 0.5)
    # Specific force that keeps the body at rest while it spins: f_b = C_bn (0, 0, g) at each sample time.
    q_true = quat.multiply(q0, quat.from_rotvec(w[None, :] * t[:, None]))
    f_b = quat.rotate(quat.conjugate(q_true), -GRAVITY_N)
    pos, vel, q = integrate(q0, np.zeros(3), np.zeros(3), t, f_b, np.tile(w, (n, 1)))
    assert np.max(quat.angle_between(q, q_true)) < 1e-7
    assert np.max(np.abs(vel)) < 1e-9 and np.max(np.abs(pos)) < 1e-9


def test_constant_acceleration_matches_analytic_kinematics() -> None:
    n = 1001
    t = _times(n)
    a_n = np.array([0.4, -0.3, 0.2])
    q0 = quat.from_euler(0.3, 0.1, -1.0)
    f_b = np.tile(quat.rotate(quat.conjugate(q0), a_n - GRAVITY_N), (n, 1))
    v0 = np.array([1.0, 0.5, 0.0])
    p0 = np.array([3.0, -2.0, 1.0])
    pos, vel, q = integrate(q0, v0, p0, t, f_b, np.zeros((n, 3)))
    np.testing.assert_allclose(vel, v0 + a_n * t[:, None], atol=1e-9)
    np.testing.assert_allclose(pos, p0 + v0 * t[:, None] + 0.5 * a_n * t[:, None] ** 2, atol=1e-9)
    assert np.max(quat.angle_between(q, q0)) < 1e-7


def test_at_rest_with_yaw_rotation_stays_put() -> None:
    n = 300
    t = _times(n)
    f_b = np.tile([0.0, 0.0, GRAVITY_MPS2], (n, 1))
    gyro = np.tile([0.0, 0.0, 0.7], (n, 1))
    pos, vel, q = integrate(quat.IDENTITY, np.zeros(3), np.zeros(3), t, f_b, gyro)
    assert np.max(np.abs(pos)) < 1e-12
    _, _, yaw = quat.to_euler(q[-1])
    assert yaw == pytest.approx(0.7 * t[-1])


def test_step_agrees_with_integrate() -> None:
    rng = np.random.default_rng(4)
    n = 50
    t = np.cumsum(rng.uniform(0.005, 0.015, n))
    f_b = rng.normal(0, 2, (n, 3)) + [0, 0, 9.8]
    w_b = rng.normal(0, 1, (n, 3))
    q0 = quat.from_euler(0.2, 0.1, 2.0)
    pos, vel, q = integrate(q0, [0.1, 0, 0], [0, 0, 0], t, f_b, w_b)
    s = NavState(np.zeros(3), np.array([0.1, 0, 0]), q0)
    for k in range(1, n):
        s = step(s, f_b[k], w_b[k], t[k] - t[k - 1], acc_prev_b=f_b[k - 1], gyro_prev_b=w_b[k - 1])
    np.testing.assert_allclose(s.pos_n, pos[-1], atol=1e-10)
    np.testing.assert_allclose(s.vel_n, vel[-1], atol=1e-10)
    assert quat.angle_between(s.q_nb, q[-1]) < 1e-7


@settings(max_examples=50, deadline=None)
@given(st.floats(-1.4, 1.4), st.floats(-1.4, 1.4), st.floats(-3.1, 3.1))
def test_initial_attitude_recovers_roll_pitch(roll: float, pitch: float, yaw: float) -> None:
    q = quat.from_euler(roll, pitch, yaw)
    f_b = quat.rotate(quat.conjugate(q), [0.0, 0.0, GRAVITY_MPS2])
    q_est = initial_attitude_from_gravity(f_b, yaw=yaw)
    assert quat.angle_between(q_est, q) < 1e-7


def test_bad_input_is_reported() -> None:
    with pytest.raises(InputError, match="not at rest"):
        initial_attitude_from_gravity([0.0, 0.0, 1.0])
    with pytest.raises(InputError, match="strictly increasing"):
        integrate(quat.IDENTITY, np.zeros(3), np.zeros(3), [0.0, 0.1, 0.1], np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(InputError, match="acc_b"):
        integrate(quat.IDENTITY, np.zeros(3), np.zeros(3), [0.0, 0.1], np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(InputError, match="dt_s"):
        step(NavState(np.zeros(3), np.zeros(3), quat.IDENTITY), np.zeros(3), np.zeros(3), 0.0)


def test_rotation_increment_is_exact_for_a_linearly_varying_rate_about_a_fixed_axis() -> None:
    # About a fixed axis the coning term vanishes and the trapezoid is exact.
    axis = np.array([0.6, 0.0, 0.8])
    theta = rotation_increment(0.5 * axis, 2.5 * axis, 0.1)
    np.testing.assert_allclose(theta, 0.15 * axis, atol=1e-15)


def test_coning_motion_attitude_error_falls_with_the_square_of_the_interval() -> None:
    # Coning: q(t) = exp(a sin(wt) x + a (1 - cos(wt)) y) has a known body rate; the two-sample update must be
    # second order: the error falls fourfold when the interval halves.
    a, om, dur = 0.3, 2 * np.pi * 3.0, 2.0

    def truth(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h = 1e-6
        rv = lambda tt: np.stack([a * np.sin(om * tt), a * (1 - np.cos(om * tt)), np.zeros_like(tt)], axis=1)  # noqa: E731
        q = quat.from_rotvec(rv(t))
        dq = quat.multiply(quat.conjugate(quat.from_rotvec(rv(t - h))), quat.from_rotvec(rv(t + h)))
        return q, quat.to_rotvec(dq) / (2 * h)

    errors = []
    for fs in (200.0, 400.0):
        t = np.arange(0.0, dur + 0.5 / fs, 1.0 / fs)
        q_true, w = truth(t)
        q = propagate_attitude(q_true[0], w, np.diff(t, prepend=t[0]))
        errors.append(float(np.max(quat.angle_between(q, q_true))))
    assert 3.5 < errors[0] / errors[1] < 4.5
