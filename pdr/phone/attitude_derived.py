"""Per-sample quantities of an attitude the step stages read: the specific force in ENU, the yaw of the device's
y and z axes and the up-component of its y axis.

The pipeline computes them for every attitude segment (one per confirmed step); the rotation is a compiled loop
(:func:`_rotate`, the same IEEE operations in the same order as the numpy expressions it replaced, so the values
are bit-identical) and the two yaws one ``numpy.arctan2`` each (numpy's SIMD arctan2 differs from libm's in the
last bit, so it stays numpy's).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel

FloatArray = NDArray[np.float64]


@kernel
def _rotate(q: FloatArray, acc: FloatArray) -> tuple[FloatArray, FloatArray]:  # pragma: no cover - compiled
    """``f_n = C_nb(q) acc`` (N, 3) and the elements ``c01, c11, c02, c12, c21`` of ``C_nb`` (5, N) per sample."""
    n = q.shape[0]
    f_n = np.empty((n, 3))
    c = np.empty((5, n))
    for k in range(n):
        w, x, y, z = q[k, 0], q[k, 1], q[k, 2], q[k, 3]
        c00 = 1 - 2 * (y * y + z * z)
        c01 = 2 * (x * y - w * z)
        c02 = 2 * (x * z + w * y)
        c10 = 2 * (x * y + w * z)
        c11 = 1 - 2 * (x * x + z * z)
        c12 = 2 * (y * z - w * x)
        c20 = 2 * (x * z - w * y)
        c21 = 2 * (y * z + w * x)
        c22 = 1 - 2 * (x * x + y * y)
        ax, ay, az = acc[k, 0], acc[k, 1], acc[k, 2]
        f_n[k, 0] = c00 * ax + c01 * ay + c02 * az
        f_n[k, 1] = c10 * ax + c11 * ay + c12 * az
        f_n[k, 2] = c20 * ax + c21 * ay + c22 * az
        c[0, k], c[1, k], c[2, k], c[3, k], c[4, k] = c01, c11, c02, c12, c21
    return f_n, c


def attitude_derived(q: FloatArray, acc: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per sample from ``C_nb(q)`` (``q`` (N, 4) unit ``q_nb``, ``acc`` (N, 3) specific force in m/s^2, body frame):
    the specific force in ENU (N, 3) m/s^2, the yaw (rad, CCW from east) of the device y and z axes (N,) and the
    up-component of the device y axis (N,).
    """
    f_n, c = _rotate(np.ascontiguousarray(q, dtype=np.float64), np.ascontiguousarray(acc, dtype=np.float64))
    return f_n, np.arctan2(c[1], c[0]), np.arctan2(c[3], c[2]), c[4]
