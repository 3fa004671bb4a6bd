"""Step-wise dead reckoning of one foot inside the global state (seed 001 eqs. 7-8).

A foot unit sends, at every reset ``l``, the displacement ``dp_l`` (m, in the horizontal frame of the previous
reset), the heading change ``dpsi_l`` (rad) and their (4, 4) covariance (a
:class:`pdr.foot.zupt.StepIncrement`). The fusion centre propagates that foot's block of the global state

``x_l = x_{l-1} + R(chi_{l-1}) dp_l``, ``chi_l = chi_{l-1} + dpsi_l``              (eq. 7)

with the process noise ``w_l`` of covariance ``G cov(dp_l, dpsi_l) G^T``, ``G = diag(R(chi_{l-1}), 1)`` (eq. 8).
The covariance also takes the Jacobian of eq. 7 with respect to ``chi_{l-1}`` (the heading error rotates the
new displacement); this is what makes a range update correct headings through the position-heading
correlations. Only the foot's rows and columns change: ``P := J P J^T + Q`` costs O(m) per update.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.fusion.state import FOOT_DIM, FootKey, GlobalState, as_cov
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]


def rotation_z(chi: float) -> Array:
    """(3, 3) rotation ``R(chi)`` of eq. 7 from the frame of the last reset to the navigation frame."""
    c, s = math.cos(chi), math.sin(chi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def step_transition(heading: float, dp: Array, dpsi: float, cov_step: Array) -> tuple[Array, Array, Array]:
    """Increment, Jacobian and process noise of one step-wise dead-reckoning update.

    Parameters
    ----------
    heading
        ``chi_{l-1}``, rad.
    dp
        (3,) displacement since the last reset, m, frame of the last reset.
    dpsi
        Heading change, rad.
    cov_step
        (4, 4) covariance of ``(dp, dpsi)``.

    Returns
    -------
    delta
        (4,) ``[R dp, dpsi]`` added to ``[x, chi]`` (eq. 7).
    jacobian
        (4, 4) derivative of eq. 7 with respect to ``[x_{l-1}, chi_{l-1}]``.
    cov_w
        (4, 4) covariance of ``w_l`` (eq. 8).
    """
    r = rotation_z(heading)
    c, s = math.cos(heading), math.sin(heading)
    d_r = np.array([[-s, -c, 0.0], [c, -s, 0.0], [0.0, 0.0, 0.0]])
    jac = np.eye(FOOT_DIM)
    jac[:3, 3] = d_r @ dp
    g = np.zeros((FOOT_DIM, FOOT_DIM))
    g[:3, :3] = r
    g[3, 3] = 1.0
    delta = np.concatenate([r @ dp, [dpsi]])
    return delta, jac, g @ cov_step @ g.T


def check_increment(increment: StepIncrement, field: str = "step") -> tuple[Array, float, Array]:
    """Validated ``(dp, dpsi, cov)`` of a step increment (InputError naming ``field``)."""
    dp = np.asarray(increment.dp, dtype=np.float64)
    if dp.shape != (3,) or not np.all(np.isfinite(dp)):
        raise InputError("the displacement dp must be 3 finite numbers (m)", field=f"{field}.dp")
    dpsi = float(increment.dpsi)
    if not math.isfinite(dpsi):
        raise InputError("the heading change dpsi must be finite (rad)", field=f"{field}.dpsi")
    if not math.isfinite(float(increment.t_s)):
        raise InputError("the step time must be finite (s)", field=f"{field}.t_s")
    return dp, dpsi, as_cov(increment.cov, FOOT_DIM, f"{field}.cov")


def propagate_step(state: GlobalState, key: FootKey, increment: StepIncrement) -> None:
    """Apply one dead-reckoning update to foot ``key`` of ``state`` in place (eqs. 7-8).

    Raises
    ------
    InputError
        Malformed increment, unknown foot, or a step older than the foot's last update.
    """
    f = state.foot(key)
    dp, dpsi, cov_step = check_increment(increment)
    if increment.t_s < state.t_s[f]:
        raise InputError(f"step at {increment.t_s:.3f} s is older than the last update of {key} "
                         f"({state.t_s[f]:.3f} s)", field="step.t_s")
    idx = state.block(key)
    delta, jac, cov_w = step_transition(float(state.mean[idx[3]]), dp, dpsi, cov_step)
    state.mean[idx] += delta                                        # eq. 7
    p = state.cov
    p[idx, :] = jac @ p[idx, :]                                     # J P J^T touches the foot's rows ...
    p[:, idx] = p[:, idx] @ jac.T                                   # ... and columns only
    p[np.ix_(idx, idx)] += cov_w                                    # + cov(w_l), eq. 8
    state.t_s[f] = float(increment.t_s)
    state.steps[f] += 1
