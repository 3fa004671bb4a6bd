"""Robust range updates by sampling on a lattice (seed 001 Sec. 4.3, eqs. 16-20, Algorithm 3).

A range ``r~`` between the ranging devices of two agents constrains ``z_1 = x_a - x_b`` (the positions of one
foot of each agent, transformation ``T_1`` of Sec. 4.3) through ``r~ - v - gamma_r <= ||z_1|| <= r~ - v +
gamma_r`` (eq. 17): ``gamma_r`` covers the device-to-foot separations of eq. 16, the asynchrony of the two
foot states and bounded correlated errors; ``v`` is a heavy-tailed error. A uniform prior on the constraint
convolved with a Cauchy ``v`` of scale ``sigma_r`` gives the likelihood (eqs. 18, 20)

``f(r~ | s) ~ atan((r~ - ||s|| + gamma_r) / sigma_r) - atan((r~ - ||s|| - gamma_r) / sigma_r)``.

The posterior (eq. 19) moments of ``z_1`` are evaluated by sampling the Gaussian prior through its
eigen-decomposition ``P_{z1} = Q Lambda Q^T``: ``s_i = z_1 + Q Lambda^{1/2} u_i`` for the points ``u_i`` of
a square lattice, with prior weights ``exp(-||u_i||^2 / 2)`` computed once, reweighted by the likelihood
(Algorithm 3). Eq. 12 then conditions the whole state. The lattice is rescaled so that its weighted second
moment is exactly the identity: with a flat likelihood the update returns the prior.

The same machinery takes any likelihood of ``z_1``: anchors and position fixes (``z_1 = x_a - x_c``), and
vertical differences from pressure (a signed one-dimensional ``z_1``), see :mod:`pdr.fusion.aiding`.
:func:`kalman_range_moments` is the linearised Kalman (EKF) update used as the non-robust reference (Fig. 8).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.fusion.marginalization import condition_on_transformed
from pdr.fusion.state import FootKey, GlobalState
from pdr.fusion.transforms import SubsetTransform, pair_transform

Array = NDArray[np.float64]

#: A likelihood evaluated at (K, n) samples of ``z_1``, returning (K,) non-negative values.
Likelihood = Callable[[Array], Array]


@dataclass(frozen=True)
class RangeModel:
    """Uniform-Cauchy range likelihood parameters (eqs. 17-20).

    Attributes
    ----------
    gamma_m
        Half-width ``gamma_r`` of the uniform component, m.
    sigma_m
        Scale ``sigma_r`` of the Cauchy component, m.
    """

    gamma_m: float = 1.0
    sigma_m: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.gamma_m) and self.gamma_m >= 0):
            raise InputError(f"gamma must be a non-negative distance in m, got {self.gamma_m}", field="gamma_m")
        if not (math.isfinite(self.sigma_m) and self.sigma_m > 0):
            raise InputError(f"sigma must be a positive distance in m, got {self.sigma_m}", field="sigma_m")


@dataclass(frozen=True)
class Lattice:
    """Square sampling lattice of standard-Gaussian points ``u_i`` and their prior weights.

    Attributes
    ----------
    points
        (K, n) lattice points, rescaled so that ``sum_i w_i u_i u_i^T = I``.
    weights
        (K,) normalised prior weights ``exp(-||u_i||^2 / 2)``.
    """

    points: Array
    weights: Array


def points_per_axis_for(dim: int, points_per_axis_3d: int = 9) -> int:
    """Points per axis giving a ``dim``-dimensional lattice about as many samples as the 3-D one (odd)."""
    n = max(points_per_axis_3d, int(round(points_per_axis_3d ** (3.0 / max(dim, 1)))))
    return n if n % 2 else n + 1


@lru_cache(maxsize=32)
def square_lattice(dim: int, points_per_axis: int | None = None, extent: float = 4.0) -> Lattice:
    """A ``points_per_axis ** dim`` lattice on ``[-extent, extent]^dim`` (Algorithm 3's ``u_i``).

    By default 9 points per axis in 3-D (729 samples) and the same budget in fewer dimensions (729 points
    on a line, 27 x 27 in a plane), so that narrow likelihoods of one- and two-dimensional updates are resolved.
    """
    if points_per_axis is None:
        points_per_axis = points_per_axis_for(dim)
    if dim < 1 or points_per_axis < 2 or not (extent > 0):
        raise InputError("the lattice needs dim >= 1, >= 2 points per axis and a positive extent",
                         field="lattice")
    axis = np.linspace(-extent, extent, points_per_axis)
    grid = np.stack(np.meshgrid(*([axis] * dim), indexing="ij"), axis=-1).reshape(-1, dim)
    w = np.exp(-0.5 * np.sum(grid**2, axis=1))
    w /= np.sum(w)
    var = float(w @ grid[:, 0] ** 2)                    # same on every axis by symmetry
    points = grid / math.sqrt(var)
    points.setflags(write=False)
    w.setflags(write=False)
    return Lattice(points, w)


def uniform_cauchy(measured: float, predicted: Array, model: RangeModel) -> Array:
    """Eq. 20: the uniform(-gamma, gamma) * Cauchy(sigma) likelihood of ``measured`` given ``predicted``."""
    g, s = model.gamma_m, model.sigma_m
    return np.asarray(np.arctan((measured - predicted + g) / s) - np.arctan((measured - predicted - g) / s))


def range_likelihood(range_m: float, model: RangeModel) -> Likelihood:
    """Likelihood of a measured range given samples of ``z_1`` (predicted range ``||s||``, eq. 20)."""
    return lambda s: uniform_cauchy(range_m, np.linalg.norm(s, axis=1), model)


def sampled_moments(z1: Array, cov_z1: Array, likelihood: Likelihood, lattice: Lattice) -> tuple[Array, Array] | None:
    """Posterior mean and covariance of ``z_1`` by lattice sampling (Algorithm 3 lines 2-6).

    Returns ``None`` when the likelihood vanishes at every sample (no usable information).
    """
    lam, q = np.linalg.eigh(0.5 * (cov_z1 + cov_z1.T))                   # line 2
    samples = z1 + (lattice.points * np.sqrt(np.clip(lam, 0.0, None))) @ q.T    # line 3
    w = lattice.weights * likelihood(samples)                           # line 4
    total = float(np.sum(w))
    if not (math.isfinite(total) and total > 0):
        return None
    w = w / total                                                       # line 5
    mean = w @ samples                                                  # line 6
    d = samples - mean
    return mean, (w[:, None] * d).T @ d                                 # C_{z1|r} - mean mean^T


def kalman_range_moments(z1: Array, cov_z1: Array, range_m: float, variance_m2: float) -> tuple[Array, Array] | None:
    """Linearised Kalman update of ``z_1`` with a Gaussian range error of ``variance_m2`` (Fig. 8 reference).

    Through eq. 12 this equals the EKF measurement update of the whole state (Sec. 4.1).
    """
    rho = float(np.linalg.norm(z1))
    if rho < 1e-9:
        return None
    h = z1 / rho
    ph = cov_z1 @ h
    s = float(h @ ph) + variance_m2
    k = ph / s
    mean = z1 + k * (range_m - rho)
    cov = cov_z1 - np.outer(k, ph)
    return mean, 0.5 * (cov + cov.T)


def condition_on_likelihood(state: GlobalState, transform: SubsetTransform, likelihood: Likelihood,
                            lattice: Lattice) -> bool:
    """Algorithm 3 on the global state, in place, for any likelihood of ``z_1``; returns whether it applied."""
    applied = False

    def posterior(z1: Array, cov_z1: Array) -> tuple[Array, Array] | None:
        nonlocal applied
        out = sampled_moments(z1, cov_z1, likelihood, lattice)
        applied = out is not None
        return out

    state.mean, state.cov = condition_on_transformed(state.mean, state.cov, transform, posterior)
    return applied


def range_update(state: GlobalState, foot_a: FootKey, foot_b: FootKey, range_m: float, model: RangeModel,
                 lattice: Lattice | None = None) -> bool:
    """Condition the global state on a range (m) between two agents' feet (Algorithm 3, eqs. 17-20)."""
    if not (math.isfinite(range_m) and range_m >= 0):
        raise InputError(f"a range must be a non-negative distance in m, got {range_m}", field="range_m")
    transform = pair_transform(state.position_indices(foot_a), state.position_indices(foot_b), state.dim)  # T_1
    return condition_on_likelihood(state, transform, range_likelihood(range_m, model),
                                   lattice if lattice is not None else square_lattice(3))


def kalman_range_update(state: GlobalState, foot_a: FootKey, foot_b: FootKey, range_m: float,
                        variance_m2: float) -> bool:
    """The non-robust reference: EKF range update of the global state (via ``T_1`` and eq. 12)."""
    transform = pair_transform(state.position_indices(foot_a), state.position_indices(foot_b), state.dim)
    applied = False

    def posterior(z1: Array, cov_z1: Array) -> tuple[Array, Array] | None:
        nonlocal applied
        out = kalman_range_moments(z1, cov_z1, range_m, variance_m2)
        applied = out is not None
        return out

    state.mean, state.cov = condition_on_transformed(state.mean, state.cov, transform, posterior)
    return applied
