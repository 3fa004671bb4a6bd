import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pdr import frames
from pdr import quaternion as quat

finite = st.floats(-3.0, 3.0, allow_nan=False)
rotvecs = arrays(np.float64, (3,), elements=finite)
vectors = arrays(np.float64, (3,), elements=st.floats(-100, 100, allow_nan=False))


def test_rotation_about_z_maps_east_to_north():
    q = quat.from_rotvec([0, 0, np.pi / 2])
    np.testing.assert_allclose(quat.rotate(q, [1, 0, 0]), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(quat.to_rotmat(q) @ [1, 0, 0], [0, 1, 0], atol=1e-12)


def test_composition_order_is_hamilton():
    q_ab = quat.from_rotvec([0, 0, np.pi / 2])
    q_bc = quat.from_rotvec([np.pi / 2, 0, 0])
    v_c = np.array([0.0, 1.0, 0.0])
    expected = quat.rotate(q_ab, quat.rotate(q_bc, v_c))
    np.testing.assert_allclose(quat.rotate(quat.multiply(q_ab, q_bc), v_c), expected, atol=1e-12)


@given(rotvecs, vectors)
def test_rotation_preserves_norm_and_matches_matrix(phi, v):
    q = quat.from_rotvec(phi)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    r = quat.rotate(q, v)
    assert np.linalg.norm(r) == pytest.approx(np.linalg.norm(v), abs=1e-9)
    np.testing.assert_allclose(quat.to_rotmat(q) @ v, r, atol=1e-9)


@given(rotvecs)
def test_exp_log_and_matrix_round_trips(phi):
    q = quat.from_rotvec(phi)
    assert quat.angle_between(quat.from_rotvec(quat.to_rotvec(q)), q) < 1e-7
    assert quat.angle_between(quat.from_rotmat(quat.to_rotmat(q)), q) < 1e-7
    assert quat.angle_between(q, -q) < 1e-7


@given(rotvecs, arrays(np.float64, (3,), elements=st.floats(-1, 1)))
def test_boxplus_boxminus_round_trip(phi, delta):
    q = quat.from_rotvec(phi)
    np.testing.assert_allclose(quat.boxminus(quat.boxplus(q, delta), q), delta, atol=1e-8)


@settings(max_examples=50)
@given(st.floats(-3, 3), st.floats(-1.5, 1.5), st.floats(-3, 3))
def test_euler_round_trip(r, p, y):
    q = quat.from_euler(r, p, y)
    assert quat.angle_between(quat.from_euler(*quat.to_euler(q)), q) < 1e-6


def test_yaw_from_euler_is_counterclockwise_from_east():
    q = quat.from_euler(0.0, 0.0, np.pi / 2)  # body x points north
    np.testing.assert_allclose(quat.rotate(q, [1, 0, 0]), [0, 1, 0], atol=1e-12)
    assert frames.yaw_to_heading_deg(quat.to_euler(q)[2]) == pytest.approx(0.0, abs=1e-9)


def test_from_two_vectors_and_average():
    q = quat.from_two_vectors([0, 0, 1], [1, 0, 0])
    np.testing.assert_allclose(quat.rotate(q, [0, 0, 1]), [1, 0, 0], atol=1e-12)
    q = quat.from_two_vectors([0, 0, 1], [0, 0, -1])
    np.testing.assert_allclose(quat.rotate(q, [0, 0, 1]), [0, 0, -1], atol=1e-12)
    base = quat.from_rotvec([0.1, 0.2, 0.3])
    spread = quat.multiply(quat.from_rotvec(np.array([[0, 0, 0.05], [0, 0, -0.05]])), base)
    assert quat.angle_between(quat.average(np.vstack([spread, -spread])), base) < 1e-9


def test_integrate_gyro_constant_rate():
    q = quat.integrate_gyro(quat.IDENTITY, np.tile([0, 0, 0.5], (100, 1)), np.full(100, 0.01))
    assert quat.to_euler(q[-1])[2] == pytest.approx(0.5)


def test_log_of_half_turn_with_denormal_scalar_part():
    q = np.array([5e-324, 1.0, 0.0, 0.0])  # a rotation by pi about x
    np.testing.assert_allclose(quat.to_rotvec(q), [np.pi, 0.0, 0.0])
