"""The compiled small-matrix routines agree with numpy's LAPACK/BLAS results on random and singular input."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from pdr.filters.small_linalg import (
    cholesky_lower,
    cholesky_solve,
    congruence,
    congruence_into,
    cross3,
    fma,
    matmul,
    matmul_bt,
    matmul_into,
    matvec,
    matvec3_into,
    matvec_into,
    outer,
    quadratic_form,
    solve_symmetric,
    substitute,
    symmetric_inverse,
)


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return a @ a.T + n * 1e-3 * np.eye(n)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 8), m=st.integers(1, 5), seed=st.integers(0, 2**31 - 1))
def test_cholesky_solve_and_factor_match_numpy(n: int, m: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    a = _spd(rng, n)
    b = rng.normal(size=(n, m))
    low = np.full((n, n), np.nan)
    assert cholesky_lower(a, low)
    np.testing.assert_allclose(low, np.linalg.cholesky(a), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cholesky_solve(a, b), np.linalg.solve(a, b), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(solve_symmetric(a, b), np.linalg.solve(a, b), rtol=1e-8, atol=1e-10)
    inv, logdet = symmetric_inverse(a)
    np.testing.assert_allclose(inv, np.linalg.inv(a), rtol=1e-8, atol=1e-10)
    assert logdet == pytest.approx(np.linalg.slogdet(a)[1], rel=1e-10, abs=1e-10)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 6), k=st.integers(1, 6), seed=st.integers(0, 2**31 - 1))
def test_congruence_matches_numpy_and_is_symmetric(n: int, k: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    f = rng.normal(size=(n, k))
    f[rng.random(size=(n, k)) < 0.3] = 0.0          # the sparse transition matrices it is used with
    p = _spd(rng, k)
    out = congruence(f, p)
    np.testing.assert_allclose(out, f @ p @ f.T, rtol=1e-10, atol=1e-12)
    assert np.array_equal(out, out.T)


def test_not_positive_definite_is_reported() -> None:
    singular = np.array([[1.0, 1.0], [1.0, 1.0]])
    indefinite = np.array([[1.0, 2.0], [2.0, 1.0]])
    low = np.empty((2, 2))
    assert not cholesky_lower(indefinite, low)
    assert not cholesky_lower(np.array([[np.nan]]), np.empty((1, 1)))
    for a in (singular, indefinite):
        with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
            cholesky_solve(a, np.ones((2, 1)))


def test_symmetric_variants_fall_back_to_lu_on_indefinite_input() -> None:
    a = np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.5], [0.0, 0.5, -3.0]])
    b = np.arange(6.0).reshape(3, 2)
    np.testing.assert_allclose(solve_symmetric(a, b), np.linalg.solve(a, b), rtol=1e-12)
    inv, logdet = symmetric_inverse(a)
    np.testing.assert_allclose(inv, np.linalg.inv(a), rtol=1e-12)
    assert logdet == pytest.approx(np.linalg.slogdet(a)[1])


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 7), k=st.integers(1, 7), m=st.integers(1, 7), seed=st.integers(0, 2**31 - 1))
def test_products_match_numpy(n: int, k: int, m: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, k))
    a[rng.random(size=(n, k)) < 0.3] = 0.0
    b = rng.normal(size=(k, m))
    c = rng.normal(size=(m, k))
    x = rng.normal(size=k)
    sq = rng.normal(size=(k, k))
    np.testing.assert_allclose(matmul(a, b), a @ b, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(matmul_bt(a, c), a @ c.T, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(matvec(a, x), a @ x, rtol=1e-12, atol=1e-12)
    assert quadratic_form(x, sq) == pytest.approx(float(x @ sq @ x), rel=1e-10, abs=1e-12)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 6), k=st.integers(1, 6), seed=st.integers(0, 2**31 - 1))
def test_in_place_forms_overwrite_dirty_scratch_with_the_allocating_results(n: int, k: int, seed: int) -> None:
    """The ``_into`` forms (a filter's per-sample scratch) give bit for bit what the allocating forms give, whatever
    the scratch held before; zero entries of ``A`` are skipped in both."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, k)) * (rng.random((n, k)) > 0.3)
    p = _spd(rng, k)
    x = rng.normal(size=k)
    out, fp = np.full((n, n), np.nan), np.full((n, k), np.nan)
    congruence_into(a, p, fp, out)
    assert np.array_equal(out, congruence(a, p))
    mm = np.full((n, k), np.nan)
    matmul_into(a, p, mm)
    assert np.array_equal(mm, matmul(a, p))
    mv = np.full(n, np.nan)
    matvec_into(a, x, mv)
    assert np.array_equal(mv, matvec(a, x))
    low = np.full((k, k), np.nan)
    assert cholesky_lower(p, low)
    b = rng.normal(size=(k, n))
    xs = b.copy()
    substitute(low, xs)
    assert np.array_equal(xs, cholesky_solve(p, b))


@njit
def _fma(a: float, b: float, c: float) -> float:
    return fma(a, b, c)


@njit
def _compiled_matvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    return a @ x


def test_fma_rounds_once() -> None:
    # 0.1 * 10 rounds to 1.0; the fused operation keeps the product's rounding error.
    assert _fma(0.1, 10.0, -1.0) == float(Fraction(0.1) * 10 - 1)
    assert 0.1 * 10.0 - 1.0 == 0.0


def test_matvec3_into_equals_compiled_matmul_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    out = np.empty(3)
    for _ in range(2000):
        a, x = rng.normal(size=(3, 3)), 40.0 * rng.normal(size=3)
        matvec3_into(a, x, out)
        assert np.array_equal(out, _compiled_matvec(a, x))


def test_substitute_equals_column_by_column_solution_bit_for_bit() -> None:
    rng = np.random.default_rng(4)
    for n, m in ((4, 4), (6, 4), (3, 1), (6, 6)):
        low = np.linalg.cholesky(_spd(rng, n))
        x = rng.normal(size=(n, m))
        ref = x.copy()
        for c in range(m):        # forward then backward substitution of one column at a time
            for i in range(n):
                acc = ref[i, c]
                for k in range(i):
                    acc -= low[i, k] * ref[k, c]
                ref[i, c] = acc / low[i, i]
            for i in range(n - 1, -1, -1):
                acc = ref[i, c]
                for k in range(i + 1, n):
                    acc -= low[k, i] * ref[k, c]
                ref[i, c] = acc / low[i, i]
        substitute(low, x)
        assert np.array_equal(x, ref)


def test_outer_is_numpys_outer_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    for n, m in ((1, 1), (3, 4), (4, 4), (7, 2)):
        a = rng.normal(size=n) * 10.0 ** rng.uniform(-8, 8, n)
        b = rng.normal(size=m) * 10.0 ** rng.uniform(-8, 8, m)
        assert np.array_equal(outer(a, b), np.outer(a, b))


def test_cross3_is_numpys_cross_bit_for_bit() -> None:
    rng = np.random.default_rng(11)
    for _ in range(200):
        a = rng.normal(size=3) * 10.0 ** rng.uniform(-8, 8, 3)
        b = rng.normal(size=3) * 10.0 ** rng.uniform(-8, 8, 3)
        assert np.array_equal(np.array(cross3(a, b)), np.cross(a, b))
