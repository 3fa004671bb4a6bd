"""PDR mechanization (seed 004 Sec. 3.4, eqs. 20-22): position per step, 3-D with floor, growing covariance.

``x_k = x_{k-1} + Delta s_k cos(psi_k)``, ``y_k = y_{k-1} + Delta s_k sin(psi_k)`` (eq. 22) with the yaw
``psi_k`` averaged over the step (eq. 21; the heading stage supplies it) and ``Delta s_k`` the step length.
Internal yaw is counter-clockwise from east, so x is east and y north (ENU, :mod:`pdr.frames`).

Covariance: the first-order propagation of step-length variance ``var_s`` and heading variance ``var_psi``
through eq. 22, ``P_k = P_{k-1} + J diag(var_s, var_psi) J^T`` with ``J = [[cos, -s sin], [sin, s cos]]``,
so the horizontal uncertainty grows with every step. A position fix (a landmark of the site) resets it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]


@dataclass
class TrackState:
    """Current horizontal position (m, ENU), its 2x2 covariance (m^2) and the step count."""

    east_m: float = 0.0
    north_m: float = 0.0
    P: FloatArray = field(default_factory=lambda: np.zeros((2, 2)))
    n_steps: int = 0

    def step(self, length_m: float, yaw_rad: float, var_length: float, var_yaw: float) -> None:
        """Advance by one step (eq. 22) and propagate the covariance."""
        if not (math.isfinite(length_m) and math.isfinite(yaw_rad)):
            raise InputError("step length and yaw must be finite", source="track")
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        self.east_m += length_m * c
        self.north_m += length_m * s
        j = np.array([[c, -length_m * s], [s, length_m * c]])
        self.P = self.P + j @ np.diag([var_length, var_yaw]) @ j.T
        self.n_steps += 1

    def fix(self, east_m: float, north_m: float, var_m2: float) -> None:
        """Reset the position to a known point (a site landmark) with isotropic variance ``var_m2``."""
        self.east_m, self.north_m = float(east_m), float(north_m)
        self.P = np.eye(2) * var_m2

    def to_dict(self) -> dict[str, Any]:
        return {"east_m": self.east_m, "north_m": self.north_m, "P": self.P.tolist(), "n_steps": self.n_steps}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrackState:
        try:
            return cls(float(d["east_m"]), float(d["north_m"]), np.array(d["P"], dtype=np.float64),
                       int(d["n_steps"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad track state ({exc})", source="track state") from None


def dead_reckon(length_m: FloatArray, yaw_rad: FloatArray, start_en_m: tuple[float, float] = (0.0, 0.0)
                ) -> FloatArray:
    """Positions after each step (K, 2) from step lengths and step yaws (eq. 22), vectorised."""
    s = np.asarray(length_m, dtype=np.float64)
    y = np.asarray(yaw_rad, dtype=np.float64)
    if s.shape != y.shape or s.ndim != 1:
        raise InputError(f"length and yaw must be (K,) arrays of one shape, got {s.shape} and {y.shape}",
                         source="track")
    d = np.stack([s * np.cos(y), s * np.sin(y)], axis=1)
    return np.asarray(start_en_m, dtype=np.float64) + np.cumsum(d, axis=0)
