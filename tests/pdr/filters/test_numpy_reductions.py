"""pdr.filters.numpy_reductions: numpy's reductions, compiled, give numpy's bits."""

from __future__ import annotations

import numpy as np

from pdr.filters.numpy_reductions import all_finite, column_sums, pairwise_sum, segment_sum


def _values(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Values of mixed magnitudes, so that another summation order rounds differently."""
    return rng.normal(size=shape) * 10.0 ** rng.integers(-4, 5, size=shape)


def test_pairwise_sum_is_numpys_on_every_length_contiguous_and_strided() -> None:
    rng = np.random.default_rng(3)
    lengths = [*range(0, 300), 511, 512, 513, 1000, 1031, 4099, 20000]
    for n in lengths:
        x = _values(rng, (n, 3))
        for a in (np.ascontiguousarray(x[:, 0]), x[:, 2], x[::-1, 1]):
            assert pairwise_sum(a).hex() == float(np.add.reduce(a)).hex(), n


def test_pairwise_sum_keeps_numpys_signed_zero_and_non_finite_values() -> None:
    for a in ([], [-0.0], [-0.0] * 9, [-0.0] * 300, [1.0, np.inf], [np.inf, -np.inf], [np.nan, 1.0] * 70):
        x = np.array(a, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            expected = float(np.add.reduce(x))
        assert repr(pairwise_sum(x)) == repr(expected), a


def test_column_sums_are_numpys_over_the_first_axis() -> None:
    rng = np.random.default_rng(4)
    for n in [*range(0, 140), 1000]:
        x = _values(rng, (n, 4))
        for v in (x, x[:, :2], x[:, 1:]):
            assert column_sums(v).tobytes() == np.add.reduce(v, axis=0).tobytes(), n
    zero = np.array([[-0.0, -0.0]])
    assert column_sums(zero).tobytes() == np.add.reduce(zero, axis=0).tobytes()


def test_all_finite_is_numpys_on_any_shape_and_layout() -> None:
    x = np.arange(24.0).reshape(6, 4)
    for bad in (np.nan, np.inf, -np.inf):
        y = x.copy()
        y[4, 1] = bad
        for v in (y, y[:, :2], y[:, 2:], y[::-1], y[:, 1], y.T):
            assert all_finite(v) == bool(np.isfinite(v).all())
    assert all_finite(x[:, :2]) and all_finite(np.zeros(0)) and all_finite(np.zeros((0, 3)))


def test_segment_sums_are_numpys_reduceat() -> None:
    rng = np.random.default_rng(6)
    for n in (1, 2, 7, 8, 9, 50, 129, 300, 1000):
        x = _values(rng, (n, 3))
        for a in (np.ascontiguousarray(x[:, 0]), x[:, 1]):
            for starts in (np.arange(0, n, 50), np.arange(n), np.array([0]),
                           np.unique(np.concatenate([[0], rng.integers(0, n, 6)]))):
                ends = np.r_[starts[1:], n]
                got = np.array([segment_sum(a, int(s), int(e - s)) for s, e in zip(starts, ends, strict=True)])
                assert got.tobytes() == np.add.reduceat(a, starts).tobytes(), n
    for z in ([-0.0], [-0.0, -0.0], [0.0, -0.0], [-0.0] * 9):
        a = np.array(z)
        assert repr(segment_sum(a, 0, a.size)) == repr(float(np.add.reduceat(a, [0])[0])), z
