"""Heuristic drift elimination (HDE) of the heading, shared by every foot navigator (issue #5).

The heading is not observable from zero-velocity constraints (seed 001 eq. 6), so a foot INS's heading drifts;
on the LORD 3DM-GX5 walks of ``foot_stride_gcp`` by about -0.2 deg per stride, a drift that is not a constant
gyroscope bias and that a foot-level magnetometer cannot remove. It is removed by heuristic drift elimination
(Borenstein, Ojeda, Kwanmuang 2009, "Heuristic reduction of gyro drift in IMU-based personnel tracking
systems"; Jimenez et al. 2012, "Improved heuristic drift elimination"): most walking indoors follows a few
dominant directions of the building, ``hde_directions`` evenly spaced ones, the first of them the direction of
the first straight stretch. After ``hde_min_strides`` consecutive strides that agree within
``hde_straight_tol``, a stride whose direction lies within ``hde_max_dev`` of a dominant direction is a
measurement of the heading error (noise ``hde_sigma_dir``). It updates a two-state Kalman filter of the heading
error and of the heading drift rate (random walks ``sigma_heading_rw`` and ``sigma_drift_rw``); the estimated
error is fed back into the attitude and the estimated drift rate is removed from the attitude at every sample,
so the correction persists through turns and curved stretches where no measurement is made. Positions already
travelled are not moved (the correction acts from the current stride on). Strides off the dominant directions,
curved walking and standing still give no measurement. The parameters are those of
:class:`pdr.foot.zupt.ZuptConfig` (packed by :meth:`~pdr.foot.zupt.ZuptConfig.hde_params`).

How a navigator uses it, the same for the ZUPT INS, the filter bank (seed 002) and belief condensation
(seed 000): at every sample turn the attitude (every leaf's, for a bank) about the vertical by
:func:`drift_predict`; at the end of each stance (the navigator's own stance decision) call
:func:`drift_update` with the foot's horizontal position (the merged or condensed estimate) and turn the
attitude(s) by the angle it returns. The turn is about the navigation-frame vertical: ``q := Rz(angle) q``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import wrap_pi

Array = NDArray[np.float64]

#: Layout of the drift-elimination state array.
HDE_RATE, HDE_P00, HDE_P01, HDE_P11, HDE_LAST_X, HDE_LAST_Y, HDE_HAVE_LAST, HDE_REF, HDE_HAVE_REF, HDE_COUNT, \
    HDE_PREV, HDE_UPDATES = range(12)
HDE_SIZE = 12


def initial_state(sigma_drift0: float) -> Array:
    """State at the start: no drift rate (standard deviation ``sigma_drift0``, rad/s), no stride yet."""
    h = np.zeros(HDE_SIZE)
    h[HDE_P11] = sigma_drift0**2
    return h


@cached_njit()
def drift_predict(hde: Array, dt: float, par: Array) -> float:  # pragma: no cover - compiled
    """Propagate the drift filter over ``dt``; returns the yaw turn (rad) that removes the estimated drift.

    State ``(e, d)``: heading error (estimate minus truth, rad) and its rate (rad/s) left after removing the
    estimated rate ``hde[HDE_RATE]``; ``e_k = e_{k-1} + d dt``, both random walks (``par[6]``, ``par[7]``).
    """
    p00, p01, p11 = hde[HDE_P00], hde[HDE_P01], hde[HDE_P11]
    hde[HDE_P00] = p00 + 2.0 * dt * p01 + dt * dt * p11 + par[6] * dt
    hde[HDE_P01] = p01 + dt * p11
    hde[HDE_P11] = p11 + par[7] * dt
    return -hde[HDE_RATE] * dt


@cached_njit()
def drift_update(hde: Array, x: float, y: float, par: Array) -> float:  # pragma: no cover - compiled
    """Drift elimination at the end of a stance with the foot at ``(x, y)`` (m, navigation frame).

    The stride since the previous stance end has direction ``psi``; after ``par[4]`` straight strides (each
    within ``par[3]`` of the previous) its deviation ``e`` from the nearest of ``par[0]`` dominant directions,
    if within ``par[2]``, is a measurement of the heading error with variance ``par[1]``. The Kalman update of
    ``(e, d)`` adds ``d_hat`` to the removed drift rate. Returns the yaw turn ``-e_hat`` (rad) that feeds the
    estimated error back into the attitude, 0.0 when no measurement was made.
    """
    if hde[HDE_HAVE_LAST] == 0.0:
        hde[HDE_LAST_X], hde[HDE_LAST_Y], hde[HDE_HAVE_LAST] = x, y, 1.0
        return 0.0
    dx, dy = x - hde[HDE_LAST_X], y - hde[HDE_LAST_Y]
    if math.hypot(dx, dy) < par[5]:
        return 0.0
    hde[HDE_LAST_X], hde[HDE_LAST_Y] = x, y
    psi = math.atan2(dy, dx)
    straight = hde[HDE_COUNT] > 0 and abs(wrap_pi(psi - hde[HDE_PREV])) <= par[3]
    hde[HDE_COUNT] = hde[HDE_COUNT] + 1.0 if straight else 1.0
    hde[HDE_PREV] = psi
    if hde[HDE_COUNT] < par[4]:
        return 0.0
    if hde[HDE_HAVE_REF] == 0.0:
        # The first straight stretch sets the dominant directions.
        hde[HDE_REF], hde[HDE_HAVE_REF] = psi, 1.0
    n_dir = par[0]
    e = wrap_pi(n_dir * (psi - hde[HDE_REF])) / n_dir
    if abs(e) > par[2]:
        return 0.0
    p00, p01, p11 = hde[HDE_P00], hde[HDE_P01], hde[HDE_P11]
    s = p00 + par[1]
    k0, k1 = p00 / s, p01 / s
    e_hat, d_hat = k0 * e, k1 * e
    hde[HDE_P00] = p00 - k0 * p00
    hde[HDE_P01] = p01 - k0 * p01
    hde[HDE_P11] = p11 - k1 * p01
    hde[HDE_RATE] += d_hat
    hde[HDE_PREV] = psi - e_hat
    hde[HDE_UPDATES] += 1.0
    return -e_hat
