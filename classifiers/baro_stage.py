"""Barometric second stage of the window classifier: how fast the phone climbs, as evidence for stairs.

A window's barometric altitude (:func:`pdr.frames.pressure_to_altitude_m`) is fitted with a straight line;
its slope ``v`` (m/s) and standard error ``se`` (from the fit's residuals, with the effective number of
independent samples of their lag-1 correlation: the grid interpolates the barometer's few samples and
phones low-pass them) are compared with what each class predicts:

* ``stairs_up`` / ``stairs_down``: ``v ~ N(+-STAIRS_SPEED_MPS, STAIRS_SPREAD_MPS^2 + se^2)``, a riser of
  0.15-0.19 m (building codes) climbed at 1.3-2.0 steps/s gives 0.20-0.38 m/s;
* ``walking``: ``v ~ N(0, LEVEL_SPREAD_MPS^2 + se^2)``: level floors and ramps of at most 1:12 (accessibility
  codes) at 1.2 m/s keep the vertical speed within 0.1 m/s (two standard deviations);
* every other class (standing, running, a vehicle, ...): the barometer says nothing about them; their
  density is the mixture of the three above, so they gain or lose nothing;
* each of the three densities is mixed with a uniform one over +-2 m/s (weight :data:`OUTLIER_FRACTION`):
  a door or the air conditioning moves the pressure by tenths of a hPa (metres of "altitude") within a
  second, and such a jump must not pass for a flight of stairs; far from every class's speed, the
  evidence vanishes instead of favouring the nearest class.

The log-likelihoods are added to the classifier's emissions before the Markov smoothing
(:meth:`classifiers.model.ContextModel.window_evidence`); a window without pressure data adds nothing.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from classifiers.windows import Windows
from pdr.frames import pressure_to_altitude_m

FloatArray = NDArray[np.float64]

#: Mean and spread (m/s) of the vertical speed on stairs (module docstring).
STAIRS_SPEED_MPS = 0.29
STAIRS_SPREAD_MPS = 0.09
#: Spread (m/s) of the vertical speed of level walking, ramps included.
LEVEL_SPREAD_MPS = 0.05
#: Share of windows whose pressure slope is a disturbance (doors, ventilation), and its uniform span (m/s).
OUTLIER_FRACTION = 0.05
OUTLIER_SPAN_MPS = 4.0

_SIGNED = {"stairs_up": 1.0, "stairs_down": -1.0, "walking": 0.0}


def vertical_speed(win: Windows) -> tuple[FloatArray, FloatArray] | None:
    """Barometric vertical speed (m/s) and its standard error per window; NaN where under half the window
    has pressure; None without a barometer.
    """
    baro = win.get("baro")
    if baro is None:
        return None
    h = pressure_to_altitude_m(baro[:, :, 0])
    ok = np.isfinite(h)
    n = ok.sum(axis=1)
    t = np.arange(h.shape[1]) / win.rate_hz
    with np.errstate(invalid="ignore", divide="ignore"):
        tm = np.where(ok, t, 0.0).sum(axis=1) / n
        hm = np.where(ok, h, 0.0).sum(axis=1) / n
        dt = np.where(ok, t - tm[:, None], 0.0)
        dh = np.where(ok, h - hm[:, None], 0.0)
        v = (dt * dh).sum(axis=1) / (dt * dt).sum(axis=1)
        resid = np.where(ok, dh - v[:, None] * dt, 0.0)
        var_r = (resid * resid).sum(axis=1) / np.maximum(n - 2, 1)
        # The slope's variance var_r / sum (t - tm)^2 counts independent samples only: the grid's samples
        # are interpolated and the sensors low-pass, so the sum is scaled by the effective sample fraction
        # (1 - rho) / (1 + rho) of an AR(1) process with the residuals' lag-1 correlation rho.
        rho = (resid[:, 1:] * resid[:, :-1]).sum(axis=1) / np.maximum((resid * resid).sum(axis=1), 1e-300)
        rho = np.clip(rho, 0.0, 1.0 - 1e-6)
        n_eff = np.clip(n * (1.0 - rho) / (1.0 + rho), 2.0, n)
        se = np.sqrt(var_r / ((dt * dt).sum(axis=1) * n_eff / np.maximum(n, 1)))
    bad = n < h.shape[1] / 2
    v[bad] = np.nan
    se[bad] = np.nan
    return v, se


def log_likelihood(v: FloatArray, se: FloatArray, classes: Sequence[str]) -> FloatArray:
    """(W, r) log-likelihoods of the vertical speeds ``v`` (W,) per class (module docstring); zero rows
    where ``v`` is NaN and zero columns when the classes lack walking and both stairs.
    """
    out = np.zeros((v.size, len(classes)))
    cols = [i for i, c in enumerate(classes) if c in _SIGNED]
    if not cols:
        return out
    ok = np.isfinite(v) & np.isfinite(se)
    dens = {}
    for i in cols:
        c = classes[i]
        spread = LEVEL_SPREAD_MPS if c == "walking" else STAIRS_SPREAD_MPS
        var = spread**2 + se[ok] ** 2
        gauss = np.exp(-0.5 * (v[ok] - _SIGNED[c] * STAIRS_SPEED_MPS) ** 2 / var) / np.sqrt(2 * np.pi * var)
        dens[i] = (1.0 - OUTLIER_FRACTION) * gauss + OUTLIER_FRACTION / OUTLIER_SPAN_MPS
    mixture = sum(dens.values()) / len(_SIGNED)
    floor = 1e-300
    for i in range(len(classes)):
        out[ok, i] = np.log(np.maximum(dens.get(i, mixture), floor)) - np.log(np.maximum(mixture, floor))
    return out
