"""Floors from the barometer: altitude change, floor counting with hysteresis and drift re-anchoring.

Altitude from pressure with the standard atmosphere (:func:`pdr.frames.pressure_to_altitude_m`),
low-passed causally (first order, ``smooth_s``). The floor is ``floor0 + n`` where ``n`` changes by one
when the altitude relative to the reference moves more than ``hysteresis`` floor heights past the
current floor's level. While the user walks on the flat (no stairs, elevator or escalator) the reference
follows the altitude slowly (``drift_tau_s``) so weather and ventilation drift do not count as floors.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.frames import pressure_to_altitude_m

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FloorConfig:
    """Floor height (m), hysteresis (fraction of a floor), smoothing and drift time constants (s)."""

    floor_height_m: float = 4.0
    hysteresis: float = 0.6
    smooth_s: float = 1.0
    drift_tau_s: float = 120.0

    def __post_init__(self) -> None:
        if not self.floor_height_m > 0:
            raise InputError("floor height must be positive", field="floor_height_m", source="floor config")


class FloorTracker:
    """Online floor estimate from pressure samples on a uniform grid."""

    def __init__(self, rate_hz: float, config: FloorConfig | None = None, floor0: float = 0.0) -> None:
        self.rate_hz = float(rate_hz)
        self.config = config or FloorConfig()
        self.floor0 = float(floor0)
        self.alt = math.nan          # smoothed altitude (m)
        self.ref = math.nan          # altitude of floor0 (m)
        self.n = 0                   # floors above floor0

    def update(self, p_hpa: FloatArray, flat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Smoothed altitude above the start (m) and floor per sample; ``flat`` (bool) allows re-anchoring."""
        h = pressure_to_altitude_m(np.asarray(p_hpa, dtype=np.float64))
        c = self.config
        ks = 1.0 / (1.0 + c.smooth_s * self.rate_hz)
        kd = 1.0 / (1.0 + c.drift_tau_s * self.rate_hz)
        up = np.empty(h.size)
        fl = np.empty(h.size)
        self.alt, self.ref, self.n = _track_floors(h, np.asarray(flat, dtype=np.bool_), ks, kd, c.floor_height_m,
                                                   c.hysteresis, self.floor0, self.alt, self.ref, self.n, up, fl)
        return up, fl

    def state(self) -> dict[str, Any]:
        return {"rate_hz": self.rate_hz, "config": asdict(self.config), "floor0": self.floor0, "alt": self.alt,
                "ref": self.ref, "n": self.n}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> FloorTracker:
        try:
            t = cls(float(d["rate_hz"]), FloorConfig(**d["config"]), float(d["floor0"]))
            t.alt, t.ref, t.n = float(d["alt"]), float(d["ref"]), int(d["n"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad floor state ({exc})", source="floor state") from None
        return t


@njit(cache=True)
def _track_floors(h: FloatArray, flat: NDArray[np.bool_], ks: float, kd: float, height: float, hysteresis: float,
                  floor0: float, alt: float, ref: float, n: int, up: FloatArray,
                  fl: FloatArray) -> tuple[float, float, int]:  # pragma: no cover - compiled
    """The per-sample loop of :meth:`FloorTracker.update` (module doc): altitudes ``h`` (m) in, the smoothed
    altitude above the reference ``up`` (m) and the floor ``fl`` out; returns the state ``(alt, ref, n)``.
    """
    for i in range(h.size):
        if math.isnan(alt):
            alt = ref = h[i]
        alt += ks * (h[i] - alt)
        rel = alt - ref - n * height
        if rel > hysteresis * height:
            n += 1
        elif rel < -hysteresis * height:
            n -= 1
        elif flat[i]:
            ref += kd * rel
        up[i] = alt - ref
        fl[i] = floor0 + n
    return alt, ref, n
