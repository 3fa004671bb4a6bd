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
from pdr.frames import heading_deg_to_yaw, yaw_to_heading_deg

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
        j01, j11 = -length_m * s, length_m * c
        j = np.array([[c, j01], [s, j11]])
        # j diag(a, b): j's columns scaled, each product as numpy's j * [a, b] forms it (without the diagonal matrix:
        # the dropped terms are zeros, which cannot change a sum onto a covariance that never holds -0.0).
        jd = np.array([[c * var_length, j01 * var_yaw], [s * var_length, j11 * var_yaw]])
        self.P = self.P + jd @ j.T
        self.n_steps += 1

    def fix(self, east_m: float, north_m: float, var_m2: float) -> None:
        """Reset the position to a known point (a site landmark) with isotropic variance ``var_m2``."""
        self.east_m, self.north_m = float(east_m), float(north_m)
        self.P = np.eye(2) * var_m2

    def state(self) -> dict[str, Any]:
        return {"east_m": self.east_m, "north_m": self.north_m, "P": self.P.tolist(), "n_steps": self.n_steps}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> TrackState:
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


def redo_steps(steps: list[dict[str, Any]], yaw_rad: FloatArray, length_m: FloatArray | None = None
               ) -> list[dict[str, Any]]:
    """Copies of a finished track's step rows walked again (eq. 22) with other yaws and step lengths.

    ``steps`` carry ``east_m``, ``north_m``, ``heading_deg`` (clockwise from north), ``step_length_m`` and
    optionally ``position_fix``; ``yaw_rad`` (K,) is counter-clockwise from east, ``length_m`` (K,) in m (default:
    the rows' own). Each position moves by the sum, since the last position fix, of how much each step's
    displacement changed: a fix (a site landmark, :mod:`pdr.phone.pipeline`) is set before its step's displacement, so
    the fix's row moves by its own step's change only, and floors are kept. The copies get the new
    ``heading_deg`` and ``step_length_m``.
    """
    yaw = np.asarray(yaw_rad, dtype=np.float64)
    old_len = np.array([s["step_length_m"] for s in steps], dtype=np.float64)
    new_len = old_len if length_m is None else np.asarray(length_m, dtype=np.float64)
    if yaw.shape != (len(steps),) or new_len.shape != yaw.shape:
        raise InputError(f"need one yaw and one length per step ({len(steps)}), got {yaw.shape} and "
                         f"{new_len.shape}", source="track")
    old = np.asarray(heading_deg_to_yaw(np.array([s["heading_deg"] for s in steps], dtype=np.float64)))
    shift = (new_len[:, None] * np.column_stack([np.cos(yaw), np.sin(yaw)])
             - old_len[:, None] * np.column_stack([np.cos(old), np.sin(old)]))
    cum = np.cumsum(shift, axis=0)
    base = np.zeros_like(cum)
    for i in np.flatnonzero([bool(s.get("position_fix")) for s in steps]).tolist():
        base[i:] = cum[i - 1] if i else 0.0     # restarted at a fix, that step's own shift included
    moved = cum - base
    # The headings converted as one array (elementwise, the same bits as one step at a time), the values read as
    # Python floats once instead of a numpy scalar per step.
    heading = np.asarray(yaw_to_heading_deg(yaw)).tolist()
    return [{**s, "east_m": float(s["east_m"] + de), "north_m": float(s["north_m"] + dn), "heading_deg": h,
             "step_length_m": ln}
            for s, (de, dn), h, ln in zip(steps, moved.tolist(), heading, new_len.tolist(), strict=True)]
