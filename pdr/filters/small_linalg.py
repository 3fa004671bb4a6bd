"""Compiled dense linear algebra for the small matrices of navigation filters (n up to about 30).

For a 4x4 attitude covariance or a 6x6 innovation covariance, a LAPACK or BLAS call through numba costs more in
argument checks, copies and allocation than the arithmetic itself; these plain loops do the same work in place
of ``np.linalg.cholesky``, ``np.linalg.solve`` and ``np.linalg.inv`` on a symmetric (normally positive-definite)
matrix, and of ``@``. The ``solve_symmetric`` and ``symmetric_inverse`` variants fall back to LAPACK's LU when the
Cholesky factorisation fails, so they accept what ``np.linalg.solve`` and ``np.linalg.inv`` accepted.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic
from numpy.typing import NDArray

from pdr.filters.compiled import kernel

Array = NDArray[np.float64]


@intrinsic
def _fma(typingctx: Any, a: Any, b: Any, c: Any) -> Any:  # pragma: no cover - compiled
    """The typing and code of :data:`fma`: LLVM's ``llvm.fma.f64``."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        f64 = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [f64], ir.FunctionType(f64, [f64, f64, f64]))
        return builder.call(fn, args)

    return sig, codegen


#: ``fma(a, b, c)``: ``a * b + c`` with one rounding (IEEE 754 fusedMultiplyAdd) of float64 scalars, in compiled
#: code only.
fma = cast(Callable[[float, float, float], float], _fma)


@kernel
def matvec3_into(A: Array, x: Array, out: Array) -> None:  # pragma: no cover - compiled
    """``A x`` for a (3, 3) ``A`` and a (3,) ``x`` into ``out`` (not ``x``): the values of ``A @ x`` in compiled
    code, which calls BLAS ``dgemv`` (the bundled OpenBLAS sums ``a1 x1``, then ``a0 x0``, then ``a2 x2`` with fused
    multiply-adds; ``tests/pdr/filters/test_small_linalg.py`` pins the equality), without the call's checks,
    allocation and dispatch.
    """
    for i in range(3):
        out[i] = fma(A[i, 2], x[2], fma(A[i, 0], x[0], A[i, 1] * x[1]))


@kernel
def cholesky_lower(A: Array, L: Array) -> bool:  # pragma: no cover - compiled
    """Lower Cholesky factor of the symmetric (n, n) ``A`` (only its lower triangle is read) written into ``L``.

    Returns False, with ``L`` partly written, when ``A`` is not numerically positive definite.
    """
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            L[i, j] = 0.0
        for j in range(i + 1):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                if not acc > 0.0:
                    return False
                L[i, i] = math.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return True


@kernel
def substitute(L: Array, X: Array) -> None:  # pragma: no cover - compiled
    """``X <- (L L^T)^-1 X`` in place, for a lower Cholesky factor ``L`` (n, n) and (n, m) ``X``."""
    # Row by row over all columns at once: each column's chain of divisions is independent of the others', so
    # the processor overlaps them (the same operations on each entry as column by column).
    n, m = X.shape
    for i in range(n):  # L y = b
        d = L[i, i]
        for c in range(m):
            acc = X[i, c]
            for k in range(i):
                acc -= L[i, k] * X[k, c]
            X[i, c] = acc / d
    for i in range(n - 1, -1, -1):  # L^T x = y
        d = L[i, i]
        for c in range(m):
            acc = X[i, c]
            for k in range(i + 1, n):
                acc -= L[k, i] * X[k, c]
            X[i, c] = acc / d


@kernel
def _solve_factored(L: Array, B: Array) -> Array:  # pragma: no cover - compiled
    """``(L L^T)^-1 B`` for a lower Cholesky factor ``L`` (n, n) and (n, m) ``B``."""
    X = B.copy()
    substitute(L, X)
    return X


@kernel
def cholesky_solve(A: Array, B: Array) -> Array:  # pragma: no cover - compiled
    """``A^-1 B`` for a symmetric positive-definite (n, n) ``A`` and (n, m) ``B``.

    Raises ``np.linalg.LinAlgError`` when ``A`` is not positive definite.
    """
    n = A.shape[0]
    L = np.empty((n, n))
    if not cholesky_lower(A, L):
        raise np.linalg.LinAlgError("matrix is not positive definite")
    return _solve_factored(L, B)


@kernel
def solve_symmetric(A: Array, B: Array) -> Array:  # pragma: no cover - compiled
    """``A^-1 B`` for a symmetric (n, n) ``A`` that is positive definite in all but corner cases (an innovation
    covariance): by Cholesky, or by LU (``np.linalg.solve``) when the factorisation fails.
    """
    n = A.shape[0]
    L = np.empty((n, n))
    if cholesky_lower(A, L):
        return _solve_factored(L, B)
    return np.linalg.solve(A, B)  # type: ignore[return-value]  # float64 in, float64 out


@kernel
def congruence(F: Array, P: Array) -> Array:  # pragma: no cover - compiled
    """``F P F^T`` for an (n, k) ``F`` and a symmetric (k, k) ``P``; the result is exactly symmetric."""
    n, k = F.shape
    out = np.empty((n, n))
    congruence_into(F, P, np.empty((n, k)), out)
    return out


@kernel
def congruence_into(F: Array, P: Array, FP: Array, out: Array) -> None:  # pragma: no cover - compiled
    """:func:`congruence` into ``out`` (n, n), with ``FP`` (n, k) as scratch (no allocation)."""
    n, k = F.shape
    matmul_into(F, P, FP)
    for i in range(n):
        for j in range(i + 1):
            acc = 0.0
            for b in range(k):
                acc += FP[i, b] * F[j, b]
            out[i, j] = acc
            out[j, i] = acc


@kernel
def symmetric_inverse(A: Array) -> tuple[Array, float]:  # pragma: no cover - compiled
    """Inverse and log-determinant (of ``|A|``) of a symmetric (n, n) ``A`` that is positive definite in all but
    corner cases: from one Cholesky factor, or by LU (``np.linalg.inv``, ``np.linalg.slogdet``) when it fails.
    """
    n = A.shape[0]
    L = np.empty((n, n))
    if not cholesky_lower(A, L):
        return np.linalg.inv(A), np.linalg.slogdet(A)[1]  # type: ignore[return-value]  # float64 in and out
    logdet = 0.0
    Linv = np.zeros((n, n))                         # L^-1, lower triangular
    for i in range(n):
        logdet += 2.0 * math.log(L[i, i])
        Linv[i, i] = 1.0 / L[i, i]
        for j in range(i):
            acc = 0.0
            for k in range(j, i):
                acc -= L[i, k] * Linv[k, j]
            Linv[i, j] = acc / L[i, i]
    inv = np.empty((n, n))                          # A^-1 = L^-T L^-1
    for i in range(n):
        for j in range(i + 1):
            acc = 0.0
            for k in range(i, n):
                acc += Linv[k, i] * Linv[k, j]
            inv[i, j] = acc
            inv[j, i] = acc
    return inv, logdet


@kernel
def matmul(A: Array, B: Array) -> Array:  # pragma: no cover - compiled
    """``A B`` for an (n, k) ``A`` and a (k, m) ``B``, skipping the zero entries of ``A``."""
    out = np.empty((A.shape[0], B.shape[1]))
    matmul_into(A, B, out)
    return out


@kernel
def matmul_into(A: Array, B: Array, out: Array) -> None:  # pragma: no cover - compiled
    """:func:`matmul` into ``out`` (n, m) (no allocation)."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            out[i, j] = 0.0
        for a in range(k):
            x = A[i, a]
            if x != 0.0:
                for j in range(m):
                    out[i, j] += x * B[a, j]


@kernel
def matmul_bt(A: Array, B: Array) -> Array:  # pragma: no cover - compiled
    """``A B^T`` for an (n, k) ``A`` and an (m, k) ``B``."""
    n, k = A.shape
    m = B.shape[0]
    out = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for a in range(k):
                acc += A[i, a] * B[j, a]
            out[i, j] = acc
    return out


@kernel
def matvec(A: Array, x: Array) -> Array:  # pragma: no cover - compiled
    """``A x`` for an (n, k) ``A`` and a (k,) ``x``."""
    out = np.empty(A.shape[0])
    matvec_into(A, x, out)
    return out


@kernel
def matvec_into(A: Array, x: Array, out: Array) -> None:  # pragma: no cover - compiled
    """:func:`matvec` into ``out`` (n,), which must not be ``x`` (no allocation)."""
    n, k = A.shape
    for i in range(n):
        acc = 0.0
        for a in range(k):
            acc += A[i, a] * x[a]
        out[i] = acc


@kernel
def cross3(a: Array, b: Array) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """``a x b`` of two 3-vectors as a tuple (no allocation), each term formed as ``np.cross`` forms it, without
    numba's ``np.cross``, whose loading from the cache imports numba's array-math module (as :func:`outer`).
    """
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@kernel
def outer(a: Array, b: Array) -> Array:  # pragma: no cover - compiled
    """(n, m) ``a[i] * b[j]`` for an (n,) ``a`` and an (m,) ``b``: ``np.outer``'s products, without numba's
    ``np.outer``, whose ``np.asarray`` makes loading the caller from the cache import numba's array-math module.
    """
    out = np.empty((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            out[i, j] = a[i] * b[j]
    return out


@kernel
def quadratic_form(x: Array, A: Array) -> float:  # pragma: no cover - compiled
    """``x^T A x`` for an (n,) ``x`` and an (n, n) ``A``."""
    n = x.size
    acc = 0.0
    for i in range(n):
        row = 0.0
        for j in range(n):
            row += A[i, j] * x[j]
        acc += x[i] * row
    return acc
