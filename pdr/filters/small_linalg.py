"""Compiled dense linear algebra for the small matrices of navigation filters (n up to about 30).

For a 4x4 attitude covariance or a 6x6 innovation covariance, a LAPACK or BLAS call through numba costs more in
argument checks, copies and allocation than the arithmetic itself; these plain loops do the same work in place
of ``np.linalg.cholesky``, ``np.linalg.solve`` on a symmetric positive-definite matrix, and ``A @ B @ A.T``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]


@njit(cache=True)
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


@njit(cache=True)
def cholesky_solve(A: Array, B: Array) -> Array:  # pragma: no cover - compiled
    """``A^-1 B`` for a symmetric positive-definite (n, n) ``A`` and (n, m) ``B``.

    Raises ``np.linalg.LinAlgError`` when ``A`` is not positive definite.
    """
    n = A.shape[0]
    m = B.shape[1]
    L = np.empty((n, n))
    if not cholesky_lower(A, L):
        raise np.linalg.LinAlgError("matrix is not positive definite")
    X = B.copy()
    for c in range(m):
        for i in range(n):  # L y = b
            acc = X[i, c]
            for k in range(i):
                acc -= L[i, k] * X[k, c]
            X[i, c] = acc / L[i, i]
        for i in range(n - 1, -1, -1):  # L^T x = y
            acc = X[i, c]
            for k in range(i + 1, n):
                acc -= L[k, i] * X[k, c]
            X[i, c] = acc / L[i, i]
    return X


@njit(cache=True)
def congruence(F: Array, P: Array) -> Array:  # pragma: no cover - compiled
    """``F P F^T`` for an (n, k) ``F`` and a symmetric (k, k) ``P``; the result is exactly symmetric."""
    n, k = F.shape
    FP = np.zeros((n, k))
    for i in range(n):
        for a in range(k):
            f = F[i, a]
            if f != 0.0:
                for b in range(k):
                    FP[i, b] += f * P[a, b]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(i + 1):
            acc = 0.0
            for b in range(k):
                acc += FP[i, b] * F[j, b]
            out[i, j] = acc
            out[j, i] = acc
    return out
