"""Floors from the barometer: altitude change, floor counting with hysteresis and drift re-anchoring.

Altitude from pressure with the standard atmosphere (:func:`pdr.frames.pressure_to_altitude_m`),
low-passed causally (first order, ``smooth_s``). The floor is ``floor0 + n`` where ``n`` changes by one
when the altitude relative to the reference moves more than ``hysteresis`` of the gap to the next floor's level
past the current floor's level. A floor's level is its altitude from the site (``altitudes_m``, e.g. a mezzanine
half a storey down) relative to ``floor0``'s, else ``n * floor_height_m`` (floors beyond the site's list continue
from the nearest listed one by ``floor_height_m``). While the user walks on the flat (no stairs, elevator or
escalator) the reference follows the altitude slowly (``drift_tau_s``)
so weather and ventilation drift do not count as floors.
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
    """Floor height (m), hysteresis (fraction of a floor), smoothing and drift time constants (s), and the site's
    per-floor altitudes ``altitudes_m``: ``(floor, altitude m)`` pairs (empty: every floor ``floor_height_m`` apart).
    """

    floor_height_m: float = 4.0
    hysteresis: float = 0.6
    smooth_s: float = 1.0
    drift_tau_s: float = 120.0
    altitudes_m: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if not self.floor_height_m > 0:
            raise InputError("floor height must be positive", field="floor_height_m", source="floor config")
        try:
            alts = tuple(sorted((float(f), float(a)) for f, a in self.altitudes_m))
        except (TypeError, ValueError):
            raise InputError("altitudes_m must be [floor, altitude_m] pairs", field="altitudes_m",
                             source="floor config") from None
        if any(b[0] == a[0] or not b[1] > a[1] for a, b in zip(alts, alts[1:], strict=False)):
            raise InputError("floor altitudes must rise with the floor number, one altitude per floor",
                             field="altitudes_m", source="floor config")
        object.__setattr__(self, "altitudes_m", alts)

    def altitude_m(self, floor: float) -> float:
        """Altitude of ``floor`` (m): the site's, else continued from the nearest listed floor by the floor height."""
        if not self.altitudes_m:
            return floor * self.floor_height_m
        f0, a0 = min(self.altitudes_m, key=lambda fa: abs(fa[0] - floor))
        return a0 + (floor - f0) * self.floor_height_m

    def levels(self, floor0: float) -> FloatArray:
        """Level (m) of floors ``floor0 + n`` above ``floor0``'s for ``n = -LEVEL_SPAN .. LEVEL_SPAN``."""
        n = np.arange(-LEVEL_SPAN, LEVEL_SPAN + 1)
        return np.array([self.altitude_m(floor0 + k) for k in n]) - self.altitude_m(floor0)


#: Floors tracked above and below the start floor.
LEVEL_SPAN = 100


class FloorTracker:
    """Online floor estimate from pressure samples on a uniform grid."""

    def __init__(self, rate_hz: float, config: FloorConfig | None = None, floor0: float = 0.0) -> None:
        self.rate_hz = float(rate_hz)
        self.config = config or FloorConfig()
        self.floor0 = float(floor0)
        self.alt = math.nan          # smoothed altitude (m)
        self.ref = math.nan          # altitude of floor0 (m)
        self.n = 0                   # floors above floor0
        self.levels = self.config.levels(self.floor0)

    def update(self, p_hpa: FloatArray, flat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Smoothed altitude above the start (m) and floor per sample; ``flat`` (bool) allows re-anchoring."""
        h = pressure_to_altitude_m(np.asarray(p_hpa, dtype=np.float64))
        c = self.config
        ks = 1.0 / (1.0 + c.smooth_s * self.rate_hz)
        kd = 1.0 / (1.0 + c.drift_tau_s * self.rate_hz)
        up = np.empty(h.size)
        fl = np.empty(h.size)
        self.alt, self.ref, self.n = _track_floors(h, np.asarray(flat, dtype=np.bool_), ks, kd,
                                                   self.levels, c.hysteresis, self.floor0, self.alt,
                                                   self.ref, self.n, up, fl)
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
def _track_floors(h: FloatArray, flat: NDArray[np.bool_], ks: float, kd: float, levels: FloatArray, hysteresis: float,
                  floor0: float, alt: float, ref: float, n: int, up: FloatArray,
                  fl: FloatArray) -> tuple[float, float, int]:  # pragma: no cover - compiled
    """The per-sample loop of :meth:`FloorTracker.update` (module doc): altitudes ``h`` (m) in, the smoothed
    altitude above the reference ``up`` (m) and the floor ``fl`` out; returns the state ``(alt, ref, n)``.
    ``levels[k]``: the level (m) of floor ``floor0 + k - (levels.size - 1) // 2`` (:meth:`FloorConfig.levels`).
    """
    mid = (levels.size - 1) // 2
    for i in range(h.size):
        if math.isnan(alt):
            alt = ref = h[i]
        alt += ks * (h[i] - alt)
        k = min(max(n + mid, 1), levels.size - 2)
        rel = alt - ref - levels[k]
        if rel > hysteresis * (levels[k + 1] - levels[k]):
            n += 1
        elif rel < -hysteresis * (levels[k] - levels[k - 1]):
            n -= 1
        elif flat[i]:
            ref += kd * rel
        up[i] = alt - ref
        fl[i] = floor0 + n
    return alt, ref, n
