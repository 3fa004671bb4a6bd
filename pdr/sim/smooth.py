"""Smooth building blocks with analytic time derivatives, from which the simulator composes motion.

Every kinematic signal of the simulator is a :class:`Jet`: its value and first two time derivatives,
evaluated analytically at the requested times. Accelerations and angular rates are therefore exact
derivatives of the truth positions and attitudes, not finite differences.

Transitions use the quintic smoothstep ``S(x) = 6x^5 - 15x^4 + 10x^3`` (value, slope and curvature
continuous at both ends, so accelerations are continuous). A :class:`StepProfile` is a piecewise-constant
level (speed, step frequency, gait amplitude, ...) whose changes are smoothed by such transitions; its
running integral is analytic too (distance from speed, gait phase from step frequency).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Jet:
    """A signal and its first two time derivatives at N times.

    Attributes
    ----------
    value, d1, d2
        Arrays of equal shape ``(N, ...)``: the signal, its first and its second time derivative
        (units: the signal's unit, per s, per s^2).
    """

    value: Array
    d1: Array
    d2: Array

    @staticmethod
    def constant(value: ArrayLike, n: int) -> Jet:
        """A constant signal (zero derivatives) broadcast to N samples."""
        v = np.broadcast_to(np.asarray(value, dtype=np.float64), (n, *np.shape(value))).copy()
        return Jet(v, np.zeros_like(v), np.zeros_like(v))

    def __add__(self, other: Jet | float | Array) -> Jet:
        if isinstance(other, Jet):
            return Jet(self.value + other.value, self.d1 + other.d1, self.d2 + other.d2)
        return Jet(self.value + other, self.d1, self.d2)

    def __sub__(self, other: Jet | float | Array) -> Jet:
        return self + (-1.0) * other if isinstance(other, Jet) else self + (-other)

    def __mul__(self, other: Jet | float | Array) -> Jet:
        if isinstance(other, Jet):  # product rule
            return Jet(self.value * other.value,
                       self.d1 * other.value + self.value * other.d1,
                       self.d2 * other.value + 2.0 * self.d1 * other.d1 + self.value * other.d2)
        return Jet(self.value * other, self.d1 * other, self.d2 * other)

    __rmul__ = __mul__

    def sin(self) -> Jet:
        s, c = np.sin(self.value), np.cos(self.value)
        return Jet(s, c * self.d1, c * self.d2 - s * self.d1**2)

    def cos(self) -> Jet:
        s, c = np.sin(self.value), np.cos(self.value)
        return Jet(c, -s * self.d1, -s * self.d2 - c * self.d1**2)

    def stack(self, *others: Jet) -> Jet:
        """Scalar jets ``(N,)`` stacked into a vector jet ``(N, 1 + len(others))``."""
        parts = (self, *others)
        return Jet(np.stack([p.value for p in parts], axis=-1), np.stack([p.d1 for p in parts], axis=-1),
                   np.stack([p.d2 for p in parts], axis=-1))

    def take(self, index: int) -> Jet:
        """Component ``index`` of a vector jet."""
        return Jet(self.value[:, index], self.d1[:, index], self.d2[:, index])


def smoothstep(x: ArrayLike) -> tuple[Array, Array, Array]:
    """Quintic smoothstep ``S`` and its derivatives ``dS/dx``, ``d2S/dx2``; 0 for x <= 0, 1 for x >= 1."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    s = x**3 * (10.0 - 15.0 * x + 6.0 * x**2)
    ds = 30.0 * x**2 * (1.0 - x) ** 2
    dds = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)
    return s, ds, dds


def smoothstep_integral(x: ArrayLike) -> Array:
    """``R(x) = integral_0^x S(u) du``: 0 for x <= 0, ``x - 1/2`` for x >= 1."""
    x = np.asarray(x, dtype=np.float64)
    xc = np.clip(x, 0.0, 1.0)
    inside = xc**6 - 3.0 * xc**5 + 2.5 * xc**4
    return np.where(x >= 1.0, x - 0.5, inside)


def bump(x: ArrayLike) -> tuple[Array, Array, Array]:
    """``B(x) = 64 x^3 (1 - x)^3`` on [0, 1] (peak 1 at x = 1/2), zero outside; C2 at both ends.

    Returns B and its first two derivatives with respect to x.
    """
    x = np.asarray(x, dtype=np.float64)
    inside = (x > 0.0) & (x < 1.0)
    xc = np.where(inside, x, 0.0)
    u = xc * (1.0 - xc)
    b = 64.0 * u**3
    db = 192.0 * u**2 * (1.0 - 2.0 * xc)
    ddb = 384.0 * u * (1.0 - 2.0 * xc) ** 2 - 384.0 * u**2
    return (np.where(inside, b, 0.0), np.where(inside, db, 0.0), np.where(inside, ddb, 0.0))


def shock(x: ArrayLike) -> tuple[Array, Array, Array]:
    """``sin(2 pi x) B(x)`` on [0, 1] and its x-derivatives: a shock wavelet with no net displacement.

    Value, slope and curvature vanish at both ends, so adding it to a position leaves the velocity
    before and after unchanged. Peak |second derivative| is :data:`SHOCK_PEAK_D2`.
    """
    bv, bd, bdd = bump(x)
    w = 2.0 * np.pi
    xs = np.asarray(x, dtype=np.float64)
    sn, cs = np.sin(w * xs), np.cos(w * xs)
    return (sn * bv, w * cs * bv + sn * bd, -w * w * sn * bv + 2.0 * w * cs * bd + sn * bdd)


#: max |d2/dx2 shock(x)| on [0, 1].
SHOCK_PEAK_D2 = float(np.max(np.abs(shock(np.linspace(0.0, 1.0, 20001))[2])))


def ringing(x: ArrayLike, cycles: float) -> tuple[Array, Array, Array]:
    """A damped oscillation ``sin(2 pi c x) E(x)`` on [0, 1] and its x-derivatives; zero outside.

    ``E(x) = x^3 (1 - x)^9 / E_max`` rises fast (peak 1 at ``x = 1/4``) and decays slowly, like a soft-tissue
    mass ringing after a heel strike; value, slope and curvature vanish at both ends, so adding it to a
    position or an angle changes nothing before and after it. ``c``: number of oscillations over [0, 1].
    """
    xs = np.asarray(x, dtype=np.float64)
    inside = (xs > 0.0) & (xs < 1.0)
    u = np.where(inside, xs, 0.0)
    v = 1.0 - u
    norm = 1.0 / (0.25**3 * 0.75**9)
    e = norm * u**3 * v**9
    de = norm * (3.0 * u**2 * v**9 - 9.0 * u**3 * v**8)
    dde = norm * (6.0 * u * v**9 - 54.0 * u**2 * v**8 + 72.0 * u**3 * v**7)
    w = 2.0 * np.pi * cycles
    sn, cs = np.sin(w * u), np.cos(w * u)
    f = sn * e
    df = w * cs * e + sn * de
    ddf = -w * w * sn * e + 2.0 * w * cs * de + sn * dde
    return (np.where(inside, f, 0.0), np.where(inside, df, 0.0), np.where(inside, ddf, 0.0))


def scaled(f: tuple[Array, Array, Array], duration: float | Array) -> Jet:
    """Jet in time of a shape function of ``x = (t - t0) / duration`` given as (f, df/dx, d2f/dx2)."""
    return Jet(f[0], f[1] / duration, f[2] / duration**2)


@dataclass(frozen=True)
class StepProfile:
    """A level that starts at ``initial`` and changes by ``deltas[k]`` smoothly over ``[starts[k], ends[k]]``.

    Attributes
    ----------
    initial
        Level before any transition.
    starts, ends
        (K,) transition start and end times in s (``ends > starts``).
    deltas
        (K,) level change of each transition.
    """

    initial: float
    starts: Array
    ends: Array
    deltas: Array

    @staticmethod
    def build(initial: float, transitions: Sequence[tuple[float, float, float]]) -> StepProfile:
        """From ``(start_s, end_s, delta)`` triples; zero deltas are dropped."""
        kept = [tr for tr in transitions if tr[2] != 0.0]
        arr = np.array(kept, dtype=np.float64).reshape(-1, 3)
        return StepProfile(float(initial), arr[:, 0], arr[:, 1], arr[:, 2])

    @staticmethod
    def from_levels(boundaries_s: ArrayLike, levels: ArrayLike, max_transition_s: float) -> StepProfile:
        """Level ``levels[i]`` on segment ``[boundaries_s[i], boundaries_s[i+1])``.

        The change between two segments is centred on their shared boundary and lasts
        ``min(max_transition_s, half of either segment)``. Being centred and odd-symmetric, the smoothing
        leaves the integral of the level over the whole timeline exactly that of the sharp steps.
        """
        b = np.asarray(boundaries_s, dtype=np.float64)
        lv = np.asarray(levels, dtype=np.float64)
        dur = np.diff(b)
        out = []
        for i in range(1, lv.size):
            d = min(max_transition_s, 0.5 * dur[i - 1], 0.5 * dur[i])
            out.append((b[i] - 0.5 * d, b[i] + 0.5 * d, lv[i] - lv[i - 1]))
        return StepProfile.build(float(lv[0]), out)

    def _parts(self, t: Array) -> tuple[Array, Array]:
        d = self.ends - self.starts
        x = (t[:, None] - self.starts[None, :]) / d[None, :]
        return x, d

    @cached_property
    def _by_end(self) -> tuple[Array, Array, Array, float]:
        """Transition ends in increasing order with prefix sums (a leading 0) of ``delta`` and of ``delta m`` (``m``
        the transition's midpoint), and the sum over all transitions of ``delta (b - a) R(-a / (b - a))``.
        """
        order = np.argsort(self.ends, kind="stable")
        a, b, delta = self.starts[order], self.ends[order], self.deltas[order]
        offset = self.deltas * (self.ends - self.starts) * smoothstep_integral(-self.starts / (self.ends - self.starts))
        return (b, np.concatenate([[0.0], np.cumsum(delta)]), np.concatenate([[0.0], np.cumsum(delta * 0.5 * (a + b))]),
                float(np.sum(offset)))

    def _under_way(self, t: Array) -> Iterator[tuple[float, float, float, NDArray[np.intp]]]:
        """``(start, end, delta, index)`` of each transition with samples of ``t`` strictly inside it.

        On increasing ``t`` (the usual case) the samples are found by bisection, so evaluating a whole recording
        costs O(N + K log N) rather than K passes over it.
        """
        if t.size == 0:
            return
        ordered = t.ndim == 1 and bool(np.all(t[1:] >= t[:-1]))
        lo, hi = t.min(), t.max()
        cand = np.flatnonzero((self.ends > lo) & (self.starts < hi))
        for a, b, delta in zip(self.starts[cand], self.ends[cand], self.deltas[cand], strict=True):
            if ordered:
                idx = np.arange(np.searchsorted(t, a, side="right"), np.searchsorted(t, b, side="left"))
            else:
                idx = np.flatnonzero((t > a) & (t < b))
            if idx.size:
                yield float(a), float(b), float(delta), idx

    def value(self, t_s: ArrayLike) -> Jet:
        """The level and its derivatives at times ``t_s`` (N,)."""
        t = np.asarray(t_s, dtype=np.float64)
        ends, cum_delta, _, _ = self._by_end
        v = self.initial + cum_delta[np.searchsorted(ends, t, side="right")]      # transitions over at t
        d1 = np.zeros(t.shape)
        d2 = np.zeros(t.shape)
        for a, b, delta, i in self._under_way(t):
            s, ds, dds = smoothstep((t[i] - a) / (b - a))
            v[i] += delta * s
            d1[i] += delta * ds / (b - a)
            d2[i] += delta * dds / (b - a) ** 2
        return Jet(v, d1, d2)

    def integral(self, t_s: ArrayLike) -> Jet:
        """``integral_0^t`` of the level, with derivatives (the level and its slope)."""
        t = np.asarray(t_s, dtype=np.float64)
        lv = self.value(t)
        ends, cum_delta, cum_delta_mid, offset = self._by_end
        # Per transition delta (b - a) (R((t - a) / (b - a)) - R(-a / (b - a))), R(x) = x - 1/2 past its end and 0
        # before its start: a transition that is over adds delta (t - m), one not begun nothing but the constant.
        n_over = np.searchsorted(ends, t, side="right")
        total = (self.initial + cum_delta[n_over]) * t - cum_delta_mid[n_over] - offset
        for a, b, delta, i in self._under_way(t):
            total[i] += delta * (b - a) * smoothstep_integral((t[i] - a) / (b - a))
        return Jet(total, lv.value, lv.d1)
