"""Dual-foot separation constraint by sigma-point projection (seed 001 Sec. 4.2, eqs. 13-15, Algorithm 2).

The two feet ``x_a``, ``x_b`` of one agent cannot be further apart than ``gamma_xy`` horizontally and
``gamma_z`` vertically: ``||D_gamma (x_a - x_b)|| <= gamma_xy`` with ``D_gamma = diag(1, 1, gamma_xy/gamma_z)``
(eq. 13). After the transformation ``T_gamma`` of eq. 14, ``z_1 = D_gamma (x_a - x_b)`` must lie in a ball of
radius ``gamma_xy``. Sigma points of the prior of ``z_1`` (from the Cholesky factor of ``P_{z1}``) that fall
outside are projected onto the sphere (eq. 15); their weighted moments are the conditional moments of
``z_1``, and eq. 12 spreads the correction over the whole state (feet positions and headings, other agents).

This is the one implementation of the constraint: the fusion centre imposes it on the global state at every
step update, and a single agent's dual-foot fusion (its two feet only) calls :func:`separation_constraint`
on its 8-dimensional state the same way.

Since the feet are updated asynchronously (one foot's state refers to its last reset), ``gamma_xy`` and
``gamma_z`` grow by ``speed_bound_mps * (|t_a - t_b| - grace_s)`` when the two states are more than
``grace_s`` apart in time (Sec. 4.2: "adjusting gamma_xy by the time difference of the states").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.fusion.marginalization import condition_on_transformed
from pdr.fusion.state import FootKey, GlobalState
from pdr.fusion.transforms import pair_transform

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SeparationConfig:
    """Parameters of the separation constraint.

    Attributes
    ----------
    gamma_xy
        Largest horizontal distance between the two feet's reset positions, m (eq. 13).
    gamma_z
        Largest vertical distance, m (eq. 13).
    eta
        Sigma-point spread ``eta`` (points at ``+-sqrt(eta)`` Cholesky columns, centre weight ``1 - n/eta``);
        must be at least the dimension (3) so that no weight is negative.
    speed_bound_mps
        Upper speed used to widen the constraint for states far apart in time, m/s.
    grace_s
        Time difference covered by ``gamma_xy``/``gamma_z`` themselves, s (a normal step alternation).
    """

    gamma_xy: float = 1.0
    gamma_z: float = 0.5
    eta: float = 4.0
    speed_bound_mps: float = 1.5
    grace_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("gamma_xy", "gamma_z"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"must be a positive distance in m, got {v}", field=name)
        if not (math.isfinite(self.eta) and self.eta >= 3.0):
            raise InputError(f"eta must be >= 3 (the dimension), got {self.eta}", field="eta")
        for name in ("speed_bound_mps", "grace_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"must be a non-negative number, got {v}", field=name)

    def bounds(self, dt_s: float) -> tuple[float, float]:
        """``(gamma_xy, gamma_z)`` widened for states ``dt_s`` apart in time."""
        extra = self.speed_bound_mps * max(0.0, abs(dt_s) - self.grace_s)
        return self.gamma_xy + extra, self.gamma_z + extra


def psd_factor(cov: Array) -> Array:
    """``L`` with ``L L^T = cov``: Cholesky, or the symmetric square root when ``cov`` is singular."""
    try:
        return np.asarray(np.linalg.cholesky(cov))
    except np.linalg.LinAlgError:
        lam, q = np.linalg.eigh(0.5 * (cov + cov.T))
        return np.asarray(q * np.sqrt(np.clip(lam, 0.0, None)))


def sigma_points(mean: Array, cov: Array, eta: float) -> tuple[Array, Array]:
    """Sigma points and weights of Sec. 4.2: ``{z_1, 1 - n/eta}``, ``{z_1 +- sqrt(eta) l_i, 1/(2 eta)}``.

    Returns (2n+1, n) points (centre first, then ``+`` columns, then ``-`` columns) and (2n+1,) weights.
    """
    n = mean.size
    spread = math.sqrt(eta) * psd_factor(cov).T                       # rows are sqrt(eta) l_i
    points = np.vstack([mean[None, :], mean + spread, mean - spread])
    weights = np.full(2 * n + 1, 1.0 / (2.0 * eta))
    weights[0] = 1.0 - n / eta
    return points, weights


def project_to_ball(points: Array, radius: float) -> Array:
    """Eq. 15: points outside the ball of ``radius`` are scaled onto its surface."""
    norms = np.linalg.norm(points, axis=1)
    scale = np.where(norms > radius, radius / np.maximum(norms, 1e-300), 1.0)
    return points * scale[:, None]


def constrained_moments(z1: Array, cov_z1: Array, radius: float, eta: float) -> tuple[Array, Array] | None:
    """Conditional mean and covariance of ``z_1`` given ``||z_1|| <= radius`` (Algorithm 2 lines 2-4).

    ``None`` when every sigma point already satisfies the constraint (the prior is left unchanged).
    """
    points, weights = sigma_points(z1, cov_z1, eta)
    if np.all(np.linalg.norm(points, axis=1) <= radius):
        return None
    projected = project_to_ball(points, radius)
    mean = weights @ projected
    d = projected - mean
    return mean, (weights[:, None] * d).T @ d                         # C_{z1|gamma} - mean mean^T


def separation_constraint(mean: Array, cov: Array, index_a: ArrayLike, index_b: ArrayLike,
                          gamma_xy: float, gamma_z: float, eta: float = 4.0) -> tuple[Array, Array, bool]:
    """Impose ``||D_gamma (x_a - x_b)|| <= gamma_xy`` on a Gaussian state (Algorithm 2).

    Parameters
    ----------
    mean, cov
        (m,) and (m, m) state moments.
    index_a, index_b
        (3,) state indices of the two positions (m, ENU).
    gamma_xy, gamma_z
        Horizontal and vertical bounds, m (eq. 13).
    eta
        Sigma-point spread.

    Returns
    -------
    mean, cov, active
        Conditional moments and whether the constraint changed anything.
    """
    transform = pair_transform(index_a, index_b, mean.size, scale=[1.0, 1.0, gamma_xy / gamma_z])  # eq. 14
    active = False

    def posterior(z1: Array, cov_z1: Array) -> tuple[Array, Array] | None:
        nonlocal active
        out = constrained_moments(z1, cov_z1, gamma_xy, eta)
        active = out is not None
        return out

    x, p = condition_on_transformed(mean, cov, transform, posterior)
    return x, p, active


def impose_separation(state: GlobalState, foot_a: FootKey, foot_b: FootKey, config: SeparationConfig) -> bool:
    """Algorithm 2 on the global state, in place, for two feet of one agent; returns whether it was active."""
    dt = float(state.t_s[state.foot(foot_a)] - state.t_s[state.foot(foot_b)])
    gamma_xy, gamma_z = config.bounds(dt)
    state.mean, state.cov, active = separation_constraint(
        state.mean, state.cov, state.position_indices(foot_a), state.position_indices(foot_b),
        gamma_xy, gamma_z, config.eta)
    return active
