"""Whether the phone's operating system already calibrated a stream.

Android's calibrated gyroscope (TYPE_GYROSCOPE) and magnetometer (TYPE_MAGNETIC_FIELD) are the raw sensor's
samples less an estimate (gyro bias, hard-iron offset) that the OS reports beside the raw ones in the
uncalibrated streams (TYPE_*_UNCALIBRATED); iOS's calibrated magnetic field likewise. A log that holds both
streams shows the estimate as their difference at the sample times they share (the same sensor events). A phone
without an estimate gives equal streams, and streams with no common sample time give no evidence.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def os_calibrated(t_s: ArrayLike, values: ArrayLike, t_uncal_s: ArrayLike, uncal: ArrayLike,
                  min_norm: float) -> bool:
    """Whether ``values`` (N, 3, at times ``t_s``, s) is the OS's calibrated stream of the raw ``uncal`` (M, 3, at
    ``t_uncal_s``): at their common sample times the median norm of their difference exceeds ``min_norm`` (the
    streams' unit; below one least significant bit of the sensor, since equal streams differ by exactly 0).
    False when they share no sample time.
    """
    _, ia, ib = np.intersect1d(np.asarray(t_s), np.asarray(t_uncal_s), return_indices=True)
    if ia.size == 0:
        return False
    d = np.asarray(uncal, dtype=np.float64)[ib] - np.asarray(values, dtype=np.float64)[ia]
    return bool(np.median(np.linalg.norm(d, axis=1)) > min_norm)
