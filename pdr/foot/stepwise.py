"""Step-wise dead reckoning (seed 001 Sec. 3.2, eqs. 7-8, Algorithm 1 line 19).

The step-wise inertial navigation (:func:`pdr.foot.zupt.run_zupt` with a :class:`~pdr.foot.zupt.Segmentation`)
hands over, at every reset ``l``, the displacement ``dp_l`` (in the frame of the previous reset), the heading
change ``dpsi_l`` and their covariance. This is the low-rate interface a shoe unit sends (14 numbers a step).
The dead reckoning composes them:

``x_l = x_{l-1} + R(chi_{l-1}) dp_l``, ``chi_l = chi_{l-1} + dpsi_l`` (eq. 7), with the noise ``w_l`` of
covariance ``cov([R dp_l, dpsi_l])`` (eq. 8). The covariance of ``(x_l, chi_l)`` is propagated with the
Jacobian of eq. 7 with respect to ``chi_{l-1}`` (the heading uncertainty rotates the new displacement), which
the additive form of eq. 7 leaves implicit.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]


def _rot(chi: float) -> Array:
    c, s = math.cos(chi), math.sin(chi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class DeadReckoningTrack:
    """Global position and heading at every reset.

    Attributes
    ----------
    t_s
        (L+1,) times, s (the first row is the initial state).
    pos_n
        (L+1, 3) positions ``x_l``, m, navigation frame.
    heading
        (L+1,) headings ``chi_l``, rad (counter-clockwise yaw).
    cov
        (L+1, 4, 4) covariance of ``(x_l, chi_l)``.
    """

    t_s: Array
    pos_n: Array
    heading: Array
    cov: Array


class StepwiseDeadReckoning:
    """Online step-wise dead reckoning: feed step increments one by one (eq. 7).

    Parameters
    ----------
    pos0_n
        (3,) initial position ``x_0``, m.
    heading0
        Initial heading ``chi_0``, rad.
    cov0
        (4, 4) initial covariance of ``(x_0, chi_0)``.
    """

    def __init__(self, pos0_n: Array | None = None, heading0: float = 0.0, cov0: Array | None = None) -> None:
        self.pos_n = np.zeros(3) if pos0_n is None else np.asarray(pos0_n, dtype=np.float64).copy()
        self.heading = float(heading0)
        self.cov = np.zeros((4, 4)) if cov0 is None else np.asarray(cov0, dtype=np.float64).copy()
        if self.pos_n.shape != (3,) or self.cov.shape != (4, 4):
            raise InputError("initial position must be (3,) and covariance (4, 4)", field="pos0_n")

    def update(self, step: StepIncrement) -> None:
        """Apply one step increment (eqs. 7-8)."""
        dp = np.asarray(step.dp, dtype=np.float64)
        if dp.shape != (3,) or np.shape(step.cov) != (4, 4) or not np.all(np.isfinite(dp)):
            raise InputError("a step increment needs a finite (3,) displacement and a (4, 4) covariance",
                             field="step")
        r = _rot(self.heading)
        d_r = np.array([[-math.sin(self.heading), -math.cos(self.heading), 0.0],
                        [math.cos(self.heading), -math.sin(self.heading), 0.0], [0.0, 0.0, 0.0]])
        jac = np.eye(4)
        jac[:3, 3] = d_r @ dp
        g = np.zeros((4, 4))
        g[:3, :3] = r
        g[3, 3] = 1.0
        cov_w = g @ np.asarray(step.cov, dtype=np.float64) @ g.T       # eq. 8
        self.cov = jac @ self.cov @ jac.T + cov_w
        self.pos_n = self.pos_n + r @ dp                                   # eq. 7
        self.heading = self.heading + float(step.dpsi)


def dead_reckon(steps: Iterable[StepIncrement], t0_s: float = 0.0, pos0_n: Array | None = None,
                heading0: float = 0.0, cov0: Array | None = None) -> DeadReckoningTrack:
    """Run the step-wise dead reckoning over a sequence of step increments (Algorithm 1 line 19)."""
    dr = StepwiseDeadReckoning(pos0_n, heading0, cov0)
    ts, ps, hs, cs = [t0_s], [dr.pos_n.copy()], [dr.heading], [dr.cov.copy()]
    for s in steps:
        dr.update(s)
        ts.append(s.t_s)
        ps.append(dr.pos_n.copy())
        hs.append(dr.heading)
        cs.append(dr.cov.copy())
    return DeadReckoningTrack(np.array(ts), np.array(ps), np.array(hs), np.array(cs))
