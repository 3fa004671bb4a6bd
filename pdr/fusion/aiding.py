"""Anchors, position fixes and pressure as range-type updates (seed 001 Sec. 4.3, last paragraph).

"Ranging to anchor nodes whose positions are not kept in x or position updates (from a GNSS receiver or
similar) may trivially be implemented as range updates (zero range in the case of the position update) with
``z_1 = x_a - x_b`` replaced with ``z_1 = x_a - x_c``. Fusion of pressure measurements may be implemented as
range updates in the vertical direction, either relative to other agents or relative to a reference pressure."

All three use the sampled update of :mod:`pdr.fusion.ranging` (Algorithm 3) with the uniform-Cauchy
likelihood of eq. 20:

* anchor range: ``z_1 = x_a - x_c`` (3-D), predicted range ``||z_1||``;
* position fix: ``z_1 = x_a - x_c`` on the fixed axes (horizontal for GNSS), measured range 0: ``gamma`` is the
  fix's error bound and ``sigma`` its heavy-tailed scale;
* height difference: ``z_1 = z_a - z_b`` or ``z_a - h_ref`` (1-D, signed: a pressure difference tells which
  is higher), predicted value ``z_1`` itself.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.frames import pressure_to_altitude_m
from pdr.fusion.ranging import (
    Lattice,
    RangeModel,
    condition_on_likelihood,
    range_likelihood,
    square_lattice,
    uniform_cauchy,
)
from pdr.fusion.state import FootKey, GlobalState
from pdr.fusion.transforms import anchor_transform, pair_transform

Array = NDArray[np.float64]


def anchor_range_update(state: GlobalState, foot: FootKey, anchor_n: ArrayLike, range_m: float,
                        model: RangeModel, lattice: Lattice | None = None) -> bool:
    """Range (m) from a foot's agent to an anchor at ``anchor_n`` (3, m, ENU), in place; True if applied."""
    if not (math.isfinite(range_m) and range_m >= 0):
        raise InputError(f"a range must be a non-negative distance in m, got {range_m}", field="range_m")
    transform = anchor_transform(state.position_indices(foot), anchor_n, state.dim)
    return condition_on_likelihood(state, transform, range_likelihood(range_m, model),
                                   lattice if lattice is not None else square_lattice(3))


def position_fix_update(state: GlobalState, foot: FootKey, pos_n: ArrayLike, model: RangeModel,
                        horizontal: bool = True, lattice: Lattice | None = None) -> bool:
    """Position fix as a zero range to the fixed point (m, ENU; 2 values if ``horizontal``, else 3)."""
    axes = 2 if horizontal else 3
    point = np.asarray(pos_n, dtype=np.float64).reshape(-1)
    if point.size != axes:
        raise InputError(f"a {'horizontal' if horizontal else '3-D'} fix needs {axes} coordinates (m)",
                         field="pos_n")
    transform = anchor_transform(state.position_indices(foot)[:axes], point, state.dim)
    return condition_on_likelihood(state, transform, range_likelihood(0.0, model),
                                   lattice if lattice is not None else square_lattice(axes))


def height_difference_update(state: GlobalState, foot_a: FootKey, foot_b: FootKey | None, dh_m: float,
                             model: RangeModel, reference_height_m: float = 0.0,
                             lattice: Lattice | None = None) -> bool:
    """Signed vertical difference ``z_a - z_b`` (or ``z_a - reference_height_m`` when ``foot_b`` is None), m."""
    if not math.isfinite(dh_m):
        raise InputError(f"a height difference must be finite (m), got {dh_m}", field="dh_m")
    za = state.position_indices(foot_a)[2:]
    if foot_b is None:
        transform = anchor_transform(za, [reference_height_m], state.dim)
    else:
        transform = pair_transform(za, state.position_indices(foot_b)[2:], state.dim)
    return condition_on_likelihood(state, transform, lambda s: uniform_cauchy(dh_m, s[:, 0], model),
                                   lattice if lattice is not None else square_lattice(1))


def pressure_height_difference(p_a_hpa: float, p_b_hpa: float) -> float:
    """Height of the point at pressure ``p_a_hpa`` above the one at ``p_b_hpa``, m (standard atmosphere)."""
    if not (math.isfinite(p_a_hpa) and math.isfinite(p_b_hpa) and p_a_hpa > 0 and p_b_hpa > 0):
        raise InputError("pressures must be positive numbers in hPa", field="pressure_hpa")
    return float(pressure_to_altitude_m(p_a_hpa, p0_hpa=p_b_hpa))
