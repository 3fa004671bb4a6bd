"""Rauch-Tung-Striebel (RTS) fixed-interval smoother, for direct and for error-state (indirect) Kalman filters.

Offline only: the backward pass needs the whole recording, so it serves file processing (``pdr foot``,
``pdr eval foot``); an online navigator keeps the causal filter.

Direct form (Rauch, Tung, Striebel 1965; Särkkä, "Bayesian Filtering and Smoothing", 2013, Theorem 8.2). With
the forward filter's filtered ``x_k|k, P_k|k``, predicted ``x_k+1|k, P_k+1|k`` and the transition ``F_k+1``
from sample ``k`` to ``k + 1``, from the last sample backwards::

    C_k      = P_k|k F_k+1^T P_k+1|k^-1                                  (smoother gain)
    x_k|N    = x_k|k + C_k (x_k+1|N - x_k+1|k)
    P_k|N    = P_k|k + C_k (P_k+1|N - P_k+1|k) C_k^T

Error-state form (indirect filter with feedback, e.g. the ZUPT-aided INS of seed 001 eq. 5; Colomar, Nilsson,
Händel 2012, "Smoothing for ZUPT-aided INSs"): after every update the estimated error ``dx_k`` is fed back into
the nominal state and reset to zero. Relative to the corrected nominal state the filtered error is therefore
zero and the predicted error is ``-dx_k`` (to first order, also for an attitude error composed by ``exp``), so
the same recursion gives the smoothed error ``e_k|N`` relative to the corrected nominal state at sample ``k``::

    e_k|N    = C_k (e_k+1|N + dx_k+1)

and the smoothed state is the nominal state corrected by ``e_k|N`` the way the filter applies its own
corrections. Anything the caller changes in the nominal state outside the filter's error model (e.g. a
heading-drift correction) is not smoothed: the smoothed error is relative to the nominal state as stored.

API: :func:`rts_smooth` (whole arrays, direct form), :func:`error_state_rts` (whole arrays, error-state form),
and :func:`rts_step`, the compiled single backward step that a filter with its own compact storage (such as
:func:`pdr.foot.zupt.run_zupt`, which rebuilds ``F`` and ``P_k+1|k`` instead of storing them) calls in its
own backward loop.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.filters.compiled import kernel
from pdr.filters.small_linalg import cholesky_solve, matmul

Array = NDArray[np.float64]


@kernel
def rts_step(x_f: Array, P_f: Array, F_next: Array, x_p_next: Array, P_p_next: Array, x_s_next: Array,
             P_s_next: Array, x_s: Array, P_s: Array) -> None:  # pragma: no cover - compiled
    """One backward RTS step from sample ``k + 1`` to ``k``, results written into ``x_s`` and ``P_s``.

    Parameters
    ----------
    x_f, P_f
        (n,), (n, n) filtered mean and covariance at ``k``.
    F_next
        (n, n) transition from ``k`` to ``k + 1``.
    x_p_next, P_p_next
        (n,), (n, n) predicted mean and covariance at ``k + 1`` (before its update), positive definite.
    x_s_next, P_s_next
        (n,), (n, n) smoothed mean and covariance at ``k + 1``.
    x_s, P_s
        (n,), (n, n) outputs: smoothed mean and covariance at ``k`` (may alias ``x_f``/``P_f``).
    """
    n = x_f.shape[0]
    # C^T = P_p^-1 F P_f (P_p, P_f symmetric).
    ct = cholesky_solve(P_p_next, matmul(F_next, P_f))
    d = x_s_next - x_p_next
    DC = matmul(P_s_next - P_p_next, ct)  # D C^T
    for i in range(n):
        acc = x_f[i]
        for k in range(n):
            acc += ct[k, i] * d[k]
        x_s[i] = acc
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(n):
                acc += ct[k, i] * DC[k, j]
            v = 0.5 * (P_f[i, j] + P_f[j, i]) + acc
            P_s[i, j] = v
            P_s[j, i] = v


@kernel
def _rts_kernel(x_f: Array, P_f: Array, x_p: Array, P_p: Array, F: Array, x_s: Array,
                P_s: Array) -> None:  # pragma: no cover - compiled
    n = x_f.shape[0]
    x_s[n - 1] = x_f[n - 1]
    P_s[n - 1] = P_f[n - 1]
    for k in range(n - 2, -1, -1):
        rts_step(x_f[k], P_f[k], F[k + 1], x_p[k + 1], P_p[k + 1], x_s[k + 1], P_s[k + 1], x_s[k], P_s[k])


def _check(name: str, arr: Array, shape: tuple[int, ...]) -> None:
    if arr.shape != shape:
        raise InputError(f"expected shape {shape}, got {arr.shape}", field=name)
    if not np.all(np.isfinite(arr)):
        raise InputError("must be finite", field=name)


def rts_smooth(x_filt: ArrayLike, P_filt: ArrayLike, x_pred: ArrayLike, P_pred: ArrayLike,
               F: ArrayLike) -> tuple[Array, Array]:
    """Fixed-interval RTS smoother over the outputs of a forward Kalman filter (direct form).

    Parameters
    ----------
    x_filt, P_filt
        (N, n), (N, n, n) filtered means and covariances ``x_k|k, P_k|k``.
    x_pred, P_pred
        (N, n), (N, n, n) predicted means and covariances ``x_k|k-1, P_k|k-1`` (row 0 unused).
    F
        (N, n, n) transitions: ``F[k]`` maps sample ``k - 1`` to ``k`` (row 0 unused).

    Returns
    -------
    (N, n) smoothed means ``x_k|N`` and (N, n, n) smoothed covariances ``P_k|N``.
    """
    xf = np.ascontiguousarray(x_filt, dtype=np.float64)
    if xf.ndim != 2 or xf.shape[0] < 1:
        raise InputError(f"expected shape (N, n), got {xf.shape}", field="x_filt")
    N, n = xf.shape
    Pf = np.ascontiguousarray(P_filt, dtype=np.float64)
    xp = np.ascontiguousarray(x_pred, dtype=np.float64)
    Pp = np.ascontiguousarray(P_pred, dtype=np.float64)
    Fa = np.ascontiguousarray(F, dtype=np.float64)
    _check("x_filt", xf, (N, n))
    _check("P_filt", Pf, (N, n, n))
    _check("x_pred", xp, (N, n))
    _check("P_pred", Pp, (N, n, n))
    _check("F", Fa, (N, n, n))
    x_s = np.empty_like(xf)
    P_s = np.empty_like(Pf)
    _rts_kernel(xf, Pf, xp, Pp, Fa, x_s, P_s)
    return x_s, P_s


def error_state_rts(P_filt: ArrayLike, P_pred: ArrayLike, F: ArrayLike, dx: ArrayLike) -> tuple[Array, Array]:
    """RTS smoother of an error-state filter whose error estimate is fed back and reset after every update.

    Parameters
    ----------
    P_filt, P_pred
        (N, n, n) covariances after and before the update at each sample (equal where nothing was measured).
    F
        (N, n, n) error transitions: ``F[k]`` maps sample ``k - 1`` to ``k`` (row 0 unused).
    dx
        (N, n) error estimate fed back into the nominal state at each sample (zero where nothing was
        measured).

    Returns
    -------
    (N, n) smoothed errors relative to the corrected nominal state at each sample (apply them as the filter
    applies its corrections) and (N, n, n) their covariances.
    """
    d = np.asarray(dx, dtype=np.float64)
    if d.ndim != 2:
        raise InputError(f"expected shape (N, n), got {d.shape}", field="dx")
    return rts_smooth(np.zeros_like(d), P_filt, -d, P_pred, F)
