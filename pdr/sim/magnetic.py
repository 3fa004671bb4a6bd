"""The magnetic field a device sees indoors: Earth field plus building disturbances.

* Earth field in ENU from intensity ``B``, inclination ``I`` (down positive) and declination ``D``:
  ``m_n = B (cos I sin D, cos I cos D, -sin I)``.
* Static indoor anomalies (steel, wiring): Gaussian blobs ``v_j exp(-|p - c_j|^2 / (2 r^2))`` placed along
  the walked path, one every ``disturbance_spacing_m``, with random vectors ``v_j`` (per-component
  standard deviation ``indoor_disturbance_ut``). They depend on position only, so a still device sees a
  constant field.
* Elevator cabin: inside, the field is scaled by ``elevator_field_scale``; the change happens over about
  a second at the doors (the magnitude drop on entering and rise on leaving used by seed 003 to time the
  elevator landmark).
* Escalator: the moving steel steps make the field fluctuate (seed 003: magnetic variance separates riding
  an escalator from standing) by ``escalator_disturbance_ut`` at about 1 Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.sim.scenario import MagneticSpec
from pdr.sim.smooth import StepProfile
from pdr.sim.trajectory import Path

Array = NDArray[np.float64]

_DOOR_TRANSITION_S = 1.0
#: Distance (in anomaly radii) beyond which an anomaly is left out: its weight is below exp(-32) = 1.3e-14.
_ANOMALY_REACH_RADII = 8.0


def earth_field_n(spec: MagneticSpec) -> Array:
    """(3,) Earth magnetic field in uT, ENU."""
    ci, si = math.cos(spec.inclination_rad), math.sin(spec.inclination_rad)
    return spec.total_ut * np.array([ci * math.sin(spec.declination_rad), ci * math.cos(spec.declination_rad), -si])


@dataclass(frozen=True)
class MagneticEnvironment:
    """The field along one scenario: see the module docstring. Build with :func:`build_environment`."""

    earth_n: Array
    centres_n: Array
    vectors_n: Array
    radius_m: float
    cabin_scale: StepProfile
    escalator_amp: StepProfile
    escalator_freq_hz: Array
    escalator_phase_rad: Array

    def field_n(self, t_s: Array, pos_n: Array) -> Array:
        """(N, 3) field in uT, ENU, at times ``t_s`` (N,) and positions ``pos_n`` (N, 3)."""
        t = np.asarray(t_s, dtype=np.float64)
        p = np.asarray(pos_n, dtype=np.float64)
        out = np.tile(self.earth_n, (t.size, 1))
        reach = _ANOMALY_REACH_RADII * self.radius_m
        for lo in range(0, t.size, 4096):
            chunk = p[lo:lo + 4096]
            # Only anomalies near this stretch of the path: one beyond reach adds less than exp(-reach^2 / 2r^2)
            # of its vector, so the cost stays linear in the recording's length.
            near = np.all((self.centres_n > chunk.min(axis=0) - reach) & (self.centres_n < chunk.max(axis=0) + reach),
                          axis=1)
            d2 = np.sum((chunk[:, None, :] - self.centres_n[None, near, :]) ** 2, axis=-1)
            out[lo:lo + 4096] += np.exp(-0.5 * d2 / self.radius_m**2) @ self.vectors_n[near]
        out *= self.cabin_scale.value(t).value[:, None]
        wave = np.sin(2.0 * math.pi * self.escalator_freq_hz[None, :] * t[:, None] + self.escalator_phase_rad[None, :])
        return out + self.escalator_amp.value(t).value[:, None] * wave


def build_environment(path: Path, spec: MagneticSpec, rng: np.random.Generator) -> MagneticEnvironment:
    """Draw the disturbances of ``path`` (anomaly positions and vectors, escalator wobble) from ``rng``."""
    duration = path.duration_s
    t = np.arange(0.0, duration + 0.25, 0.25)
    p = path.position(t).value
    dist = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    marks = np.arange(0.0, dist[-1] + spec.disturbance_spacing_m, spec.disturbance_spacing_m)
    anchor = np.column_stack([np.interp(marks, dist, p[:, k]) for k in range(3)])
    m = anchor.shape[0]
    offset = np.column_stack([rng.uniform(-1.0, 1.0, (m, 2)) * spec.disturbance_radius_m,
                              rng.uniform(0.3, 1.5, m)])
    vectors = rng.normal(0.0, 1.0, (m, 3)) * spec.indoor_disturbance_ut
    segs = path.scenario.segments
    b = path.scenario.boundaries_s
    cabin = StepProfile.from_levels(b, [spec.elevator_field_scale if s.kind == "elevator" else 1.0 for s in segs],
                                    _DOOR_TRANSITION_S)
    esc = StepProfile.from_levels(b, [spec.escalator_disturbance_ut if s.kind == "escalator" else 0.0
                                      for s in segs], _DOOR_TRANSITION_S)
    return MagneticEnvironment(earth_field_n(spec), anchor + offset, vectors, spec.disturbance_radius_m, cabin, esc,
                               rng.uniform(0.7, 1.5, 3), rng.uniform(0.0, 2.0 * math.pi, 3))
