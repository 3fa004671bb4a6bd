"""Unscented transform and unscented Kalman filter with hooks for states on manifolds.

Implements the scaled unscented transform of seed 003 Sec. 4.3 (eqs. 35-37: sigma points
``xi_0 = x``, ``xi_i = x +/- (sqrt((L + lambda) P))_i``, weights ``w_0^m = lambda / (L + lambda)``,
``w_0^c = w_0^m + 1 - alpha^2 + beta``, ``w_i = 1 / (2 (L + lambda))``, ``lambda = alpha^2 (L + kappa) - L``)
and the UKF measurement update (eqs. 38-40). Seed 003 eq. 36 prints ``w_i = lambda / (2 (L + lambda))``;
that is a typo (the weights would not sum to one) and the standard ``1 / (2 (L + lambda))`` is used.

The hooks follow filterpy's ``UnscentedKalmanFilter`` vocabulary, which is what a quaternion state
needs (the mean of quaternions is not an arithmetic mean):

``state_add(x, dx)``
    apply a correction (default ``x + dx``); a quaternion filter normalises here;
``residual_x(a, b)`` / ``residual_z(a, b)``
    differences of states / measurements (default ``a - b``; angles wrap here);
``x_mean_fn(sigmas, wm)`` / ``z_mean_fn(sigmas, wm)``
    weighted means (default ``wm @ sigmas``; circular mean for angles, eigenvector mean for quaternions).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]
MeanFn = Callable[[FloatArray, FloatArray], FloatArray]
ResidualFn = Callable[[FloatArray, FloatArray], FloatArray]


def _mean(sigmas: FloatArray, wm: FloatArray) -> FloatArray:
    return np.asarray(wm @ sigmas, dtype=np.float64)


def _add(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.asarray(a + b, dtype=np.float64)


def _sub(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.asarray(a - b, dtype=np.float64)


@dataclass(frozen=True)
class SigmaPoints:
    """Scaled symmetric sigma points (seed 003 eqs. 35-37).

    Parameters
    ----------
    n
        State dimension ``L``.
    alpha, beta, kappa
        Spread, prior-knowledge and secondary scaling parameters; the paper uses
        ``alpha = 1e-3``, ``beta = 2`` (Gaussian prior) and ``kappa = 0``.
    """

    n: int
    alpha: float = 1e-3
    beta: float = 2.0
    kappa: float = 0.0

    def __post_init__(self) -> None:
        if self.n < 1:
            raise InputError(f"state dimension must be at least 1, got {self.n}", field="n")
        if not self.alpha > 0:
            raise InputError(f"alpha must be positive, got {self.alpha}", field="alpha")
        if self.n + self.lam <= 0:
            raise InputError("L + lambda must be positive (choose a larger alpha or kappa)", field="kappa")

    @property
    def lam(self) -> float:
        """``lambda = alpha^2 (L + kappa) - L`` (eq. 37)."""
        return self.alpha**2 * (self.n + self.kappa) - self.n

    def weights(self) -> tuple[FloatArray, FloatArray]:
        """(wm, wc), each (2L + 1,) (eq. 36)."""
        c = self.n + self.lam
        wm = np.full(2 * self.n + 1, 0.5 / c)
        wc = wm.copy()
        wm[0] = self.lam / c
        wc[0] = self.lam / c + (1.0 - self.alpha**2 + self.beta)
        return wm, wc

    def sigma_points(self, x: FloatArray, p: FloatArray,
                     state_add: Callable[[FloatArray, FloatArray], FloatArray] | None = None) -> FloatArray:
        """(2L + 1, L) sigma points around ``x`` with covariance ``p`` (eq. 35).

        The matrix square root is the lower Cholesky factor of ``(L + lambda) P``; its columns are the
        offsets. ``state_add`` applies each offset (default: addition).
        """
        add = state_add or _add
        try:
            s = np.asarray(np.linalg.cholesky((self.n + self.lam) * p), dtype=np.float64)
        except np.linalg.LinAlgError:
            raise InputError("covariance is not positive definite", field="P") from None
        out = np.empty((2 * self.n + 1, x.size))
        out[0] = x
        for i in range(self.n):
            out[1 + i] = add(x, s[:, i])
            out[1 + self.n + i] = add(x, -s[:, i])
        return out


def unscented_transform(sigmas: FloatArray, wm: FloatArray, wc: FloatArray, noise: FloatArray | None = None,
                        mean_fn: MeanFn | None = None, residual_fn: ResidualFn | None = None
                        ) -> tuple[FloatArray, FloatArray]:
    """Mean and covariance of transformed sigma points (eq. 38), plus additive ``noise`` covariance."""
    mean = np.asarray((mean_fn or _mean)(sigmas, wm), dtype=np.float64)
    d = (residual_fn or _sub)(sigmas, mean[None, :])
    cov = (d * wc[:, None]).T @ d
    if noise is not None:
        cov = cov + noise
    return mean, cov


class UnscentedKalmanFilter:
    """Additive-noise UKF with filterpy-style hooks (seed 003 eqs. 34-40).

    Parameters
    ----------
    fx
        State transition ``fx(x, **kw) -> x`` applied to every sigma point in :meth:`predict`.
    hx
        Measurement function ``hx(x, **kw) -> z``.
    points
        Sigma point parameters (``alpha``, ``beta``, ``kappa``).
    x0, p0
        Initial state (L,) and covariance (L, L).
    x_mean_fn, z_mean_fn, residual_x, residual_z, state_add
        Hooks for non-Euclidean states and measurements (see the module docstring).

    Attributes
    ----------
    x, P
        Current estimate and covariance; ``x_prior``/``P_prior`` and ``x_post``/``P_post`` are kept.
    y, S, nis
        Innovation, its covariance and normalised innovation squared of the last update.
    """

    def __init__(self, fx: Callable[..., FloatArray], hx: Callable[..., FloatArray], points: SigmaPoints,
                 x0: FloatArray, p0: FloatArray, x_mean_fn: MeanFn | None = None, z_mean_fn: MeanFn | None = None,
                 residual_x: ResidualFn | None = None, residual_z: ResidualFn | None = None,
                 state_add: Callable[[FloatArray, FloatArray], FloatArray] | None = None) -> None:
        self.fx, self.hx, self.points = fx, hx, points
        self.x = np.array(x0, dtype=np.float64)
        self.P = np.array(p0, dtype=np.float64)
        if self.x.shape != (points.n,) or self.P.shape != (points.n, points.n):
            raise InputError(f"x0 must be ({points.n},) and p0 ({points.n}, {points.n})", field="x0")
        self.x_mean_fn = x_mean_fn or _mean
        self.z_mean_fn = z_mean_fn or _mean
        self.residual_x = residual_x or _sub
        self.residual_z = residual_z or _sub
        self.state_add = state_add or (lambda a, b: a + b)
        self.wm, self.wc = points.weights()
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        self.y = np.zeros(0)
        self.S = np.zeros((0, 0))
        self.nis = float("nan")

    def predict(self, q: FloatArray, **fx_args: object) -> None:
        """Propagate sigma points through ``fx`` and add process noise ``q`` (eq. 34 in UT form)."""
        sig = self.points.sigma_points(self.x, self.P, self.state_add)
        fs = np.array([self.fx(s, **fx_args) for s in sig])
        self.x, self.P = unscented_transform(fs, self.wm, self.wc, q, self.x_mean_fn, self.residual_x)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()

    def update(self, z: FloatArray, r: FloatArray, **hx_args: object) -> tuple[FloatArray, float]:
        """Measurement update (eqs. 38-40); returns (innovation, NIS)."""
        sig = self.points.sigma_points(self.x, self.P, self.state_add)
        zs = np.array([np.atleast_1d(self.hx(s, **hx_args)) for s in sig])
        zm, s_zz = unscented_transform(zs, self.wm, self.wc, r, self.z_mean_fn, self.residual_z)
        dx = self.residual_x(sig, self.x[None, :])
        dz = self.residual_z(zs, zm[None, :])
        p_xz = (dx * self.wc[:, None]).T @ dz                    # eq. 39
        k = np.linalg.solve(s_zz.T, p_xz.T).T                   # K = P_xz S^-1 (eq. 39)
        y = self.residual_z(np.atleast_1d(z)[None, :], zm[None, :])[0]
        self.x = self.state_add(self.x, k @ y)                  # eq. 40
        self.P = self.P - k @ s_zz @ k.T                        # eq. 40
        self.P = 0.5 * (self.P + self.P.T)
        self.y, self.S = y, s_zz
        self.nis = float(y @ np.linalg.solve(s_zz, y))
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        return y, self.nis
