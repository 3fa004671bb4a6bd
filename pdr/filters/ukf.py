"""Scaled symmetric sigma points of the unscented transform, with a hook for states on manifolds.

Implements the sigma points and weights of seed 003 Sec. 4.3 (eqs. 35-37: sigma points
``xi_0 = x``, ``xi_i = x +/- (sqrt((L + lambda) P))_i``, weights ``w_0^m = lambda / (L + lambda)``,
``w_0^c = w_0^m + 1 - alpha^2 + beta``, ``w_i = 1 / (2 (L + lambda))``, ``lambda = alpha^2 (L + kappa) - L``)
used by the unscented transforms of the heading (:mod:`pdr.phone.heading`). Seed 003 eq. 36 prints
``w_i = lambda / (2 (L + lambda))``; that is a typo (the weights would not sum to one) and the standard
``1 / (2 (L + lambda))`` is used. The one UKF measurement update (eqs. 38-40) is the attitude filter's compiled
:func:`pdr.phone.attitude.kernel.ukf_update`.

``state_add(x, dx)`` applies an offset to the mean (default ``x + dx``); a quaternion state normalises there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]


def _add(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.asarray(a + b, dtype=np.float64)


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
