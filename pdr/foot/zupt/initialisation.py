"""Coarse self-initialisation of the ZUPT-aided INS (Algorithm 1 line 3) on the first stationary run, and the
warning for a recording that starts in motion.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.foot.zupt.kernel import init_lengths
from pdr.strapdown import initial_attitude_from_gravity

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def first_stationary_run(zero_velocity: BoolArray, min_len: int) -> tuple[int, int]:
    """(start, stop) of the first run of at least ``min_len`` consecutive True flags."""
    z = np.concatenate([[False], np.asarray(zero_velocity, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(z.astype(np.int8)))
    starts, stops = edges[::2], edges[1::2]
    ok = np.flatnonzero(stops - starts >= min_len)
    if ok.size == 0:
        raise InputError(f"no stationary period of {min_len} samples: the foot never comes to rest, so the "
                         "attitude cannot be initialised (is this a foot-mounted IMU?)", field="zero_velocity")
    i = int(ok[0])
    return int(starts[i]), int(stops[i])


def coarse_start(t: Array, f_b: Array, zero_velocity: BoolArray, rate_hz: float, init_window_s: float,
                 yaw: float = 0.0) -> tuple[int, Array, str]:
    """Coarse self-initialisation of roll and pitch from gravity (Algorithm 1 line 3) on the first stationary run.

    Returns the run's first sample (where navigation starts), the attitude ``q_nb`` with heading ``yaw`` (rad)
    and the start-in-motion warning ('' when the recording starts at rest, :func:`late_start_warning`).
    """
    min_len, init_len = init_lengths(rate_hz, init_window_s)
    a, b = first_stationary_run(zero_velocity, min_len)
    b = min(b, a + init_len)
    q0 = initial_attitude_from_gravity(np.mean(f_b[a:b], axis=0), yaw=yaw)
    return a, q0, late_start_warning(a, float(t[a] - t[0]), rate_hz)


#: A first stationary period later than this into the recording (s) is reported: the motion before it is lost.
LATE_START_S = 0.1


def late_start_warning(start_index: int, start_s: float, rate_hz: float) -> str:
    """The warning for a first stationary period more than :data:`LATE_START_S` into the recording ('' otherwise)."""
    if start_index > int(round(LATE_START_S * rate_hz)):
        return (f"recording starts in motion: first stationary period at {start_s:.2f} s; "
                "navigation starts there and the motion before it is not tracked")
    return ""
