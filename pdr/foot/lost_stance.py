"""Recovery of lost stances in the filter bank (seed 002), issue #5.

The filter bank decides by itself, sample by sample, whether the foot stands: a stance mode wins when its
constraint explains the residuals better than the unconstrained mode does. Its Markov chain (seed 002 eq. 3e) has
no memory of how long the foot has been moving, so nothing in the model says that a foot's swing lasts well under
a second (0.35-0.6 s walking, less running). Once the velocity has drifted beyond what the covariance covers, every
later foot-down looks improbable as a stance, free motion keeps winning and the navigator integrates freely for
many seconds: it runs away (13 m on PyShoe running trials).

A swing of the navigator's own stance decision longer than ``max_swing_s`` (1.5 s, about three walking swings)
is taken as that state; the velocity variance is then raised to at least ``lost_sigma_v^2`` per axis (1 m/s, the
size of a swing's velocity) at every further sample of that swing, so the next stance's residuals are explained
again. Raising diagonal entries keeps the covariance positive semi-definite; the mean is not touched. A
healthy walk or run never has such a swing, so its track does not change.

Belief condensation (seed 000) has the same memoryless context but not this failure: its condensed velocity variance
in a long swing is already above (0.5 m/s)^2 (0.3 or 0.5 m/s change none of the PyShoe running trials), and 1 m/s
moves the running trials both ways, one much better and three worse (``pdr eval foot /work/shared/data/pyshoe_vicon
--method bc``), so it keeps the seed's model.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters.compiled import cached_njit

Array = NDArray[np.float64]

#: Defaults of ``max_swing_s`` (s) and ``lost_sigma_v`` (m/s).
LOST_STANCE_DEFAULTS = (1.5, 1.0)


def check_lost_stance(max_swing_s: float, lost_sigma_v: float) -> None:
    """Refuse settings that are not a non-negative swing duration (0: off) and a positive velocity spread."""
    if not (math.isfinite(max_swing_s) and max_swing_s >= 0):
        raise InputError(f"must be a non-negative number of seconds, got {max_swing_s}", field="max_swing_s")
    if not (math.isfinite(lost_sigma_v) and lost_sigma_v > 0):
        raise InputError(f"must be a positive number, got {lost_sigma_v}", field="lost_sigma_v")


@cached_njit()
def swing_lasts(swing_s: float, in_stance: bool, dt: float) -> float:  # pragma: no cover - compiled
    """Duration (s) of the current swing after a sample of ``dt`` s: 0 in a stance."""
    return 0.0 if in_stance else swing_s + dt


@cached_njit()
def reopen_velocity(P: Array, v0: int, swing_s: float, max_swing: float,
                    lost_var: float) -> None:  # pragma: no cover - compiled
    """In a swing longer than ``max_swing`` (s; 0: never), raise the velocity variances ``P[v0+a, v0+a]`` of the
    error covariance ``P`` to at least ``lost_var`` ((m/s)^2), in place.
    """
    if max_swing <= 0.0 or swing_s <= max_swing:
        return
    for a in range(3):
        if P[v0 + a, v0 + a] < lost_var:
            P[v0 + a, v0 + a] = lost_var
