"""The compiled rotation helpers agree with the vectorised conventions of pdr.quaternion and pdr.frames."""

import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.filters.rotation_kernels import quat_exp, quat_mul, rotate_yaw, rotmat, wrap_pi, yaw_of
from pdr.frames import wrap_angle


@pytest.fixture
def rotations():
    rng = np.random.default_rng(7)
    return quat.normalize(rng.normal(size=(50, 4))), rng.normal(scale=2.0, size=(50, 3))


def test_product_exponential_matrix_and_yaw_match_pdr_quaternion(rotations):
    qs, phis = rotations
    for q, p, phi in zip(qs, qs[::-1], phis, strict=True):
        np.testing.assert_allclose(quat_mul(q, p), quat.multiply(q, p), atol=1e-15)
        np.testing.assert_allclose(quat_exp(phi), quat.from_rotvec(phi), atol=1e-15)
        np.testing.assert_allclose(rotmat(q), quat.to_rotmat(q), atol=1e-15)
        assert yaw_of(q) == pytest.approx(float(quat.to_euler(q)[2]), abs=1e-12)


def test_small_rotation_vectors_use_the_series_and_stay_unit():
    for angle in (0.0, 1e-12, 1e-9, 1e-8, 1e-7):
        phi = np.array([angle, -0.5 * angle, 0.25 * angle])
        q = quat_exp(phi)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(q[1:], 0.5 * phi, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("a", [-7.0, -math.pi, -1.0, 0.0, 2.5, math.pi, 10.0, 1e6])
def test_wrap_is_the_frames_wrap(a):
    assert wrap_pi(a) == float(wrap_angle(a))
    assert -math.pi <= wrap_pi(a) < math.pi


def test_rotate_yaw_turns_about_the_navigation_vertical() -> None:
    q = quat.from_euler(0.1, -0.2, 0.3)
    turned = q.copy()
    rotate_yaw(turned, 0.25)
    np.testing.assert_allclose(turned, quat.multiply(quat.from_euler(0.0, 0.0, 0.25), q), atol=1e-15)
