import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr.errors import InputError
from pdr.fusion.marginalization import marginalize


def random_gaussian(rng, m):
    a = rng.normal(size=(m, m))
    return rng.normal(size=m) * 50.0, a @ a.T + 0.1 * np.eye(m)


def literal_eq12(z, p, n1, z1p, c1p):
    """Eq. 12 of seed 001 term by term (second moment C, U, V, Z)."""
    z1, z2 = z[:n1], z[n1:]
    p1, p12, p2 = p[:n1, :n1], p[:n1, n1:], p[n1:, n1:]
    u = p12.T @ np.linalg.inv(p1)
    v = z2 - u @ z1
    zz = u @ np.outer(z1p, v) + np.outer(v, z1p) @ u.T
    z2p = v + u @ z1p
    p1p = c1p - np.outer(z1p, z1p)
    p2p = p2 - u @ p12 + np.outer(v, v) + zz + u @ c1p @ u.T - np.outer(z2p, z2p)
    p12p = np.outer(z1p, v) + c1p @ u.T - np.outer(z1p, z2p)
    return np.concatenate([z1p, z2p]), np.block([[p1p, p12p], [p12p.T, p2p]])


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 3), st.integers(1, 6))
def test_matches_the_literal_equation_12(seed, n1, n2):
    rng = np.random.default_rng(seed)
    z, p = random_gaussian(rng, n1 + n2)
    z1p = z[:n1] + rng.normal(size=n1)
    b = rng.normal(size=(n1, n1))
    c1p_central = b @ b.T + 0.01 * np.eye(n1)
    got_z, got_p = marginalize(z, p, n1, z1p, c1p_central)
    want_z, want_p = literal_eq12(z, p, n1, z1p, c1p_central + np.outer(z1p, z1p))
    np.testing.assert_allclose(got_z, want_z, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(got_p, want_p, rtol=1e-6, atol=1e-6)


def test_linear_gaussian_information_equals_a_kalman_update():
    # Sec. 4.1: "If pi is linearly dependent on z1 and with Gaussian errors, this will be equivalent with a
    # Kalman filter measurement update."
    rng = np.random.default_rng(3)
    z, p = random_gaussian(rng, 7)
    n1 = 3
    r = np.diag([0.5, 1.0, 2.0])
    y = z[:n1] + rng.normal(size=n1)
    h = np.zeros((n1, 7))
    h[:, :n1] = np.eye(n1)
    k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
    want_z = z + k @ (y - z[:n1])
    want_p = (np.eye(7) - k @ h) @ p
    k1 = p[:n1, :n1] @ np.linalg.inv(p[:n1, :n1] + r)
    z1p = z[:n1] + k1 @ (y - z[:n1])
    p1p = (np.eye(n1) - k1) @ p[:n1, :n1]
    got_z, got_p = marginalize(z, p, n1, z1p, p1p)
    np.testing.assert_allclose(got_z, want_z, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got_p, want_p, rtol=1e-9, atol=1e-9)


def test_unchanged_moments_leave_the_state_unchanged():
    rng = np.random.default_rng(5)
    z, p = random_gaussian(rng, 6)
    got_z, got_p = marginalize(z, p, 2, z[:2], p[:2, :2])
    np.testing.assert_allclose(got_z, z)
    np.testing.assert_allclose(got_p, p, atol=1e-9)


def test_singular_prior_of_z1_uses_the_pseudo_inverse():
    z = np.array([1.0, 2.0, 3.0])
    p = np.diag([0.0, 1.0, 1.0])
    got_z, got_p = marginalize(z, p, 1, np.array([1.5]), np.zeros((1, 1)))
    np.testing.assert_allclose(got_z, [1.5, 2.0, 3.0])
    np.testing.assert_allclose(got_p, p)


def test_bad_sizes_are_input_errors():
    with pytest.raises(InputError, match="leading components"):
        marginalize(np.zeros(3), np.eye(3), 4, np.zeros(4), np.eye(4))
