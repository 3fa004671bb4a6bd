"""Markov smoothing of per-window class posteriors (seed 004 Sec. 4.1: transition probabilities
``P(C_t = h | C_{t-1} = k)`` for sequential data).

The window classes form a hidden Markov chain with transition matrix ``A[k, h] = P(C_t = h | C_{t-1} = k)``
and initial distribution ``pi``. A window classifier gives posteriors ``P(C_t | z_t)``; divided by the
class priors ``P(C)`` they are the emission likelihoods ``p(z_t | C_t)`` up to a factor common to all
classes (the "scaled likelihood" of hybrid HMMs). Offline the forward-backward recursion gives the
smoothed ``P(C_t | z_1..z_T)``; online the forward recursion gives the filtered ``P(C_t | z_1..z_t)``
with a state of one probability vector (:class:`ForwardFilter`).

The transition matrix comes from a mean dwell time per mode (:func:`dwell_transitions`): most training
sets hold one activity per recording, so observed transition counts would not be informative.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]


def dwell_transitions(n_classes: int, hop_s: float, mean_dwell_s: float) -> FloatArray:
    """Transition matrix of a chain that stays in a class for ``mean_dwell_s`` on average.

    ``A[k, k] = 1 - hop_s / mean_dwell_s`` (geometric dwell in windows spaced ``hop_s`` seconds);
    the rest is spread evenly over the other classes.
    """
    if n_classes < 1:
        raise InputError("need at least one class", field="n_classes")
    if not (hop_s > 0 and mean_dwell_s > hop_s):
        raise InputError(f"mean_dwell_s ({mean_dwell_s}) must exceed the window hop ({hop_s} s)",
                         field="mean_dwell_s")
    if n_classes == 1:
        return np.ones((1, 1))
    stay = 1.0 - hop_s / mean_dwell_s
    a = np.full((n_classes, n_classes), (1.0 - stay) / (n_classes - 1))
    np.fill_diagonal(a, stay)
    return a


def _log(a: ArrayLike) -> FloatArray:
    with np.errstate(divide="ignore"):
        return np.log(np.asarray(a, dtype=np.float64))


def scaled_log_likelihood(proba: ArrayLike, priors: ArrayLike) -> FloatArray:
    """``log P(C|z) - log P(C)``: emission log-likelihood up to a per-row constant; (T, r)."""
    p = np.clip(np.asarray(proba, dtype=np.float64), 1e-12, 1.0)
    return np.asarray(np.log(p) - _log(np.clip(priors, 1e-12, 1.0))[None, :])


def forward_backward(log_lik: ArrayLike, transitions: ArrayLike, initial: ArrayLike) -> FloatArray:
    """Smoothed posteriors ``P(C_t | z_1..z_T)`` of an HMM.

    Parameters
    ----------
    log_lik
        (T, r) emission log-likelihoods (up to a per-row constant).
    transitions
        (r, r) row-stochastic ``A[k, h] = P(C_t = h | C_{t-1} = k)``.
    initial
        (r,) distribution of the first window's class.

    Returns
    -------
    (T, r) posteriors, rows summing to one.
    """
    ll = np.asarray(log_lik, dtype=np.float64)
    t_len, r = ll.shape
    if t_len == 0:
        return np.zeros((0, r))
    a = np.asarray(transitions, dtype=np.float64)
    # Scaled recursions in the probability domain; emissions are normalised to a maximum of 1 per row
    # and every alpha/beta is renormalised, so nothing under- or overflows.
    e = np.exp(ll - ll.max(axis=1, keepdims=True))
    alpha = np.empty((t_len, r))
    alpha[0] = _normalise(np.asarray(initial, dtype=np.float64) * e[0])
    for t in range(1, t_len):
        alpha[t] = _normalise((alpha[t - 1] @ a) * e[t])
    beta = np.ones((t_len, r))
    for t in range(t_len - 2, -1, -1):
        beta[t] = _normalise(a @ (e[t + 1] * beta[t + 1]))
    return np.asarray(_normalise(alpha * beta))


def _normalise(p: FloatArray) -> FloatArray:
    """Rows scaled to sum to one (a tiny floor keeps an all-zero row uniform)."""
    p = np.maximum(p, 1e-300)
    return p / p.sum(axis=-1, keepdims=True)


class ForwardFilter:
    """Online forward recursion: filtered ``P(C_t | z_1..z_t)`` window by window.

    Parameters
    ----------
    transitions
        (r, r) row-stochastic transition matrix.
    initial
        (r,) distribution of the first window's class.

    The state is the last filtered distribution (``None`` before the first window); it round-trips
    through :meth:`state` / :meth:`set_state` as a JSON-able list.
    """

    def __init__(self, transitions: ArrayLike, initial: ArrayLike) -> None:
        self.transitions = np.asarray(transitions, dtype=np.float64)
        self.initial = np.asarray(initial, dtype=np.float64)
        self.alpha: FloatArray | None = None

    def update(self, log_lik: ArrayLike) -> FloatArray:
        """Filter (T, r) new emission log-likelihoods; returns (T, r) filtered posteriors."""
        ll = np.asarray(log_lik, dtype=np.float64)
        e = np.exp(ll - ll.max(axis=1, keepdims=True)) if ll.size else ll
        out = np.empty_like(ll)
        for t in range(ll.shape[0]):
            prior = self.initial if self.alpha is None else self.alpha @ self.transitions
            self.alpha = _normalise(prior * e[t])
            out[t] = self.alpha
        return out

    def state(self) -> list[float] | None:
        return None if self.alpha is None else self.alpha.tolist()

    def set_state(self, state: Any) -> None:
        if state is None:
            self.alpha = None
            return
        p = np.asarray(state, dtype=np.float64)
        if p.shape != self.initial.shape or not np.all(np.isfinite(p)) or np.any(p < 0) or p.sum() <= 0:
            raise InputError(f"filter state must be {self.initial.size} probabilities", field="state")
        self.alpha = p / p.sum()
