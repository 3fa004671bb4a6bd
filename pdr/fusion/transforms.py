"""State-space transformations that put the information-bearing part first (seed 001 eq. 14).

A constraint or measurement that involves two navigation points ``x_a``, ``x_b`` depends on
``z_1 = D (x_a - x_b)`` only. Eq. 14 maps the global state to ``z = T x = [z_1, z_2]`` with

``T_gamma = ([[D, -D], [D, D]] (+) I_{m-6}) Pi``,

where ``Pi`` moves ``x_a`` and ``x_b`` to the front and ``(+)`` is the direct sum; ``z_2 = [D (x_a + x_b),
rest of x]``. ``D = diag(1, 1, gamma_xy / gamma_z)`` for the separation constraint (eq. 13) and ``D = I``
(``T_1``) for ranging (Sec. 4.3). For anchors and position fixes ``z_1 = D (x_a - x_c)`` with a known point
``x_c`` (Sec. 4.3, last paragraph), ``T`` is the permutation plus a shift. The same class also handles a
single coordinate (a vertical difference for pressure).

:class:`SubsetTransform` applies ``T`` and ``T^{-1}`` to a mean and a covariance without forming the (m, m)
matrix: only the selected rows and columns are mixed, O(m^2) for the covariance copy and O(k m) for the
mixing. :meth:`SubsetTransform.matrix` builds the dense ``T`` of eq. 14 (for tests and documentation).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class SubsetTransform:
    """Affine transformation ``z = [M x[sel] + offset, x[rest]]`` with ``z_1 = z[:n1]``.

    Attributes
    ----------
    selected
        (s,) state indices mixed by ``mixing`` (``Pi`` of eq. 14 moves them to the front).
    mixing
        (s, s) invertible matrix ``M`` (``[[D, -D], [D, D]]`` for a pair, ``D`` for an anchor).
    offset
        (s,) added after mixing (``-D x_c`` for an anchor, zeros for a pair).
    n1
        Size of ``z_1`` (the first ``n1`` rows of ``M x[sel] + offset``).
    dim
        Size ``m`` of the state.
    """

    selected: IntArray
    mixing: Array
    offset: Array
    n1: int
    dim: int

    @cached_property
    def rest(self) -> IntArray:
        """(m - s,) indices that ``T`` passes through unchanged, in state order."""
        keep = np.ones(self.dim, dtype=bool)
        keep[self.selected] = False
        return np.flatnonzero(keep).astype(np.int64)

    def matrix(self) -> Array:
        """Dense (m, m) linear part of ``T`` (eq. 14: the mixing block (+) identity, times ``Pi``)."""
        s = self.selected.size
        order = np.concatenate([self.selected, self.rest])
        perm = np.zeros((self.dim, self.dim))
        perm[np.arange(self.dim), order] = 1.0                  # Pi x = x[order]
        block = np.eye(self.dim)
        block[:s, :s] = self.mixing
        return block @ perm

    def leading(self, mean: Array, cov: Array) -> tuple[Array, Array]:
        """Mean and covariance of ``z_1`` alone, O(k^2) (no full transformation)."""
        sel = self.selected
        m1 = self.mixing[: self.n1]
        return m1 @ mean[sel] + self.offset[: self.n1], m1 @ cov[np.ix_(sel, sel)] @ m1.T

    def forward(self, mean: Array, cov: Array) -> tuple[Array, Array]:
        """``z = T x`` and ``P_z = T P_x T^T``."""
        sel, rest = self.selected, self.rest
        order = np.concatenate([sel, rest])
        s = sel.size
        z = mean[order].copy()
        z[:s] = self.mixing @ mean[sel] + self.offset
        pz = cov[np.ix_(order, order)]
        pz[:s, :] = self.mixing @ pz[:s, :]
        pz[:, :s] = pz[:, :s] @ self.mixing.T
        return z, pz

    def inverse(self, z: Array, cov_z: Array) -> tuple[Array, Array]:
        """``x = T^{-1} z`` and ``P_x = T^{-1} P_z T^{-T}``."""
        sel, rest = self.selected, self.rest
        order = np.concatenate([sel, rest])
        s = sel.size
        m_inv = np.linalg.inv(self.mixing)
        zz = z.copy()
        zz[:s] = m_inv @ (z[:s] - self.offset)
        pz = cov_z.copy()
        pz[:s, :] = m_inv @ pz[:s, :]
        pz[:, :s] = pz[:, :s] @ m_inv.T
        x = np.empty(self.dim)
        x[order] = zz
        px = np.empty((self.dim, self.dim))
        px[np.ix_(order, order)] = pz
        return x, px


def _indices(idx: ArrayLike, dim: int, field: str) -> IntArray:
    out = np.asarray(idx, dtype=np.int64).reshape(-1)
    if out.size == 0 or out.min() < 0 or out.max() >= dim or len(set(out.tolist())) != out.size:
        raise InputError(f"state indices must be distinct and in [0, {dim})", field=field)
    return out


def _scale(scale: ArrayLike | None, k: int) -> Array:
    d = np.ones(k) if scale is None else np.asarray(scale, dtype=np.float64).reshape(-1)
    if d.shape != (k,) or not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise InputError(f"the scaling D must be {k} positive numbers", field="scale")
    return d


def pair_transform(index_a: ArrayLike, index_b: ArrayLike, dim: int, scale: ArrayLike | None = None) -> SubsetTransform:
    """``T_gamma`` of eq. 14: ``z_1 = D (x_a - x_b)``, ``z_2 = [D (x_a + x_b), rest]``.

    Parameters
    ----------
    index_a, index_b
        (k,) state indices of the two points (k = 3 for positions, 1 for a vertical coordinate).
    dim
        State size ``m``.
    scale
        (k,) diagonal of ``D`` (``[1, 1, gamma_xy / gamma_z]`` in eq. 13); ``None`` for ``T_1`` (identity).
    """
    a = _indices(index_a, dim, "index_a")
    b = _indices(index_b, dim, "index_b")
    if a.size != b.size or set(a.tolist()) & set(b.tolist()):
        raise InputError("the two points must have as many, and different, state indices", field="index_b")
    d = np.diag(_scale(scale, a.size))
    mixing = np.block([[d, -d], [d, d]])
    return SubsetTransform(np.concatenate([a, b]), mixing, np.zeros(2 * a.size), a.size, dim)


def anchor_transform(index_a: ArrayLike, point: ArrayLike, dim: int, scale: ArrayLike | None = None) -> SubsetTransform:
    """``z_1 = D (x_a - x_c)`` for a known point ``x_c`` (anchor or position fix, Sec. 4.3), ``z_2`` = rest."""
    a = _indices(index_a, dim, "index_a")
    c = np.asarray(point, dtype=np.float64).reshape(-1)
    if c.shape != a.shape or not np.all(np.isfinite(c)):
        raise InputError(f"the known point must have {a.size} finite coordinates (m)", field="point")
    d = _scale(scale, a.size)
    return SubsetTransform(a, np.diag(d), -d * c, a.size, dim)
