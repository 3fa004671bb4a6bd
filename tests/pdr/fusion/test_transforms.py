import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr.errors import InputError
from pdr.fusion.transforms import anchor_transform, pair_transform


def gaussian(seed, m):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(m, m))
    return rng.normal(size=m) * 10, a @ a.T


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 1000), st.permutations(list(range(12))))
def test_structured_pair_transform_equals_the_dense_equation_14(seed, order):
    x, p = gaussian(seed, 12)
    a, b = order[:3], order[3:6]
    t = pair_transform(a, b, 12, scale=[1.0, 1.0, 2.5])
    dense = t.matrix()
    d = np.diag([1.0, 1.0, 2.5])
    np.testing.assert_allclose(dense[:3, a], d)            # z1 = D (x_a - x_b)
    np.testing.assert_allclose(dense[:3, b], -d)
    np.testing.assert_allclose(dense[3:6, a], d)           # z2 starts with D (x_a + x_b)
    np.testing.assert_allclose(dense[3:6, b], d)
    z, pz = t.forward(x, p)
    np.testing.assert_allclose(z, dense @ x, atol=1e-9)
    np.testing.assert_allclose(pz, dense @ p @ dense.T, atol=1e-8)
    z1, p1 = t.leading(x, p)
    np.testing.assert_allclose(z1, z[:3], atol=1e-9)
    np.testing.assert_allclose(p1, pz[:3, :3], atol=1e-8)
    x2, p2 = t.inverse(z, pz)
    np.testing.assert_allclose(x2, x, atol=1e-9)
    np.testing.assert_allclose(p2, p, atol=1e-8)


def test_anchor_transform_shifts_by_the_known_point():
    x, p = gaussian(1, 8)
    t = anchor_transform([4, 5, 6], [1.0, 2.0, 3.0], 8)
    z, pz = t.forward(x, p)
    np.testing.assert_allclose(z[:3], x[4:7] - [1, 2, 3])
    np.testing.assert_allclose(pz[:3, :3], p[4:7, 4:7])
    x2, p2 = t.inverse(z, pz)
    np.testing.assert_allclose(x2, x, atol=1e-12)
    np.testing.assert_allclose(p2, p, atol=1e-12)


def test_bad_indices_are_input_errors():
    with pytest.raises(InputError, match="distinct"):
        pair_transform([0, 0, 1], [2, 3, 4], 8)
    with pytest.raises(InputError, match="different"):
        pair_transform([0, 1, 2], [2, 3, 4], 8)
    with pytest.raises(InputError, match="in \\[0, 8\\)"):
        pair_transform([0, 1, 9], [2, 3, 4], 8)
    with pytest.raises(InputError, match="positive"):
        pair_transform([0, 1, 2], [3, 4, 5], 8, scale=[1, 1, 0])
    with pytest.raises(InputError, match="coordinates"):
        anchor_transform([0, 1, 2], [1.0, 2.0], 8)
