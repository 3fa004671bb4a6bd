"""The step-wise inertial navigation's per-step output, shared by foot navigation and cooperative fusion.

:mod:`pdr.foot` (the ZUPT-aided INS with step segmentation, :mod:`pdr.foot.zupt`) produces it; :mod:`pdr.fusion`
(the fusion centre's dead reckoning, seed 001 eqs. 7-8) consumes it. It lives here so that neither package imports
the other for it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class StepIncrement:
    """Low-rate output of the step-wise inertial navigation at reset ``l`` (seed 001 eqs. 7-8).

    Attributes
    ----------
    t_s
        Time of the reset, s.
    index
        Sample index of the reset.
    dp
        (3,) displacement since the previous reset, m, in the local frame of the previous reset.
    dpsi
        Heading change since the previous reset, rad (counter-clockwise).
    cov
        (4, 4) covariance of ``(dp, dpsi)``: ``[[P_p, P_p,psi], [P_p,psi^T, P_psi]]``.
    stride
        Whether the reset closes a stride of the foot (:mod:`pdr.foot.strides`). False for a reset of the step-wise
        navigation while the foot stands (Algorithm 1 makes one every ``c_max_s``): its increment is composed like any
        other (a turn on the spot), but it is no step.
    """

    t_s: float
    index: int
    dp: Array
    dpsi: float
    cov: Array
    stride: bool = True
