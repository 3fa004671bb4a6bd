"""pdr.phone.attitude_derived: specific force in ENU and device-axis yaws from the attitude."""

from __future__ import annotations

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.phone.attitude_derived import attitude_derived


def _numpy_reference(q: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, ...]:
    """The numpy expressions the compiled loop replaced (pipeline before the kernel), element for element."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    c00, c01, c02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    c10, c11, c12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    c20, c21, c22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    ax, ay, az = acc[:, 0], acc[:, 1], acc[:, 2]
    f_n = np.column_stack([c00 * ax + c01 * ay + c02 * az, c10 * ax + c11 * ay + c12 * az,
                           c20 * ax + c21 * ay + c22 * az])
    return f_n, np.arctan2(c11, c01), np.arctan2(c12, c02), c21


def test_yaw_rotation_is_recovered() -> None:
    """A device turned by yaw psi about up: its y axis points at psi + 90 deg, its z axis is vertical."""
    psi = np.radians(np.array([-170.0, -30.0, 0.0, 45.0, 120.0]))
    q = np.column_stack([np.cos(psi / 2), np.zeros(5), np.zeros(5), np.sin(psi / 2)])
    acc = np.tile([1.0, 0.0, 9.81], (5, 1))
    f_n, yaw_y, _, y_up = attitude_derived(q, acc)
    np.testing.assert_allclose(f_n[:, :2], np.column_stack([np.cos(psi), np.sin(psi)]), atol=1e-12)
    np.testing.assert_allclose(f_n[:, 2], 9.81, atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw_y - psi - np.pi / 2))), 0.0, atol=1e-12)
    np.testing.assert_allclose(y_up, 0.0, atol=1e-12)


@pytest.mark.parametrize("n", [0, 1, 7, 1000])
def test_matches_quaternion_rotation_and_numpy_bit_for_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    q = quat.normalize(rng.normal(size=(n, 4))) if n else np.zeros((0, 4))
    acc = rng.normal(scale=5.0, size=(n, 3))
    got = attitude_derived(q, acc)
    if n:
        np.testing.assert_allclose(got[0], quat.rotate(q, acc), atol=1e-12)
    for a, b in zip(got, _numpy_reference(q, acc), strict=True):
        assert a.shape == b.shape
        assert np.array_equal(a, b)        # the same IEEE operations in the same order
