"""Android sensor conventions shared by the readers of Android app logs."""

from __future__ import annotations

import sys

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat


def rotation_vector_to_q_nb(xyz: NDArray[np.float64], w: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Android rotation vector (N, 3) to attitude ``q_nb`` (N, 4), Hamilton scalar first, ENU.

    ``TYPE_ROTATION_VECTOR`` holds the x, y, z parts of the unit quaternion that rotates device axes
    into the East-North-Up world frame (north: magnetic north, Android applies no declination); the scalar
    is the logged 4th value ``w`` when given (N,), else ``w = sqrt(max(0, 1 - |v|^2))`` (as
    ``SensorManager.getQuaternionFromVector`` does when the 4th value is absent). The result is normalised,
    so it is exactly ``q_nb`` of :mod:`pdr.frames`.
    """
    v = np.asarray(xyz, dtype=np.float64)
    if w is None and v.ndim == 2 and v.shape[1] == 3 and "numba" in sys.modules:
        # One compiled pass, the same bits (pdr.io.android_kernel); not where it would load numba (pdr inspect).
        from pdr.io.android_kernel import q_nb_of_rotation_vectors
        return np.asarray(q_nb_of_rotation_vectors(v))
    with np.errstate(over="ignore"):    # a corrupt 1e308 gives no attitude, refused by pdr.units.check_ranges
        if w is None:
            w = np.sqrt(np.clip(1.0 - np.sum(v * v, axis=1), 0.0, 1.0))
        return quat.normalize(np.column_stack([np.asarray(w, dtype=np.float64), v]))
