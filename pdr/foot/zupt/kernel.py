"""The compiled filter loop of the ZUPT-aided INS (seed 001 eqs. 3-5, Algorithm 1, drift elimination, zero
angular-rate update), its resumable state (:class:`FilterState`), its sample counts (:class:`KernelSetup`) and
its outputs (:class:`KernelOutput`); :func:`filter_rows` runs it over a block of rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import quat_exp, quat_mul, rotate_yaw, yaw_of
from pdr.foot.drift import HDE_SIZE, drift_predict, drift_update, initial_state
from pdr.foot.zupt.config import Segmentation, ZuptConfig
from pdr.foot.zupt.mechanisation import (
    zupt_predict,
)

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]


def init_lengths(rate_hz: float, init_window_s: float) -> tuple[int, int]:
    """Samples of the shortest stationary run that may initialise (0.1 s, at least 3) and of the window averaged."""
    min_len = max(3, int(round(0.1 * rate_hz)))
    return min_len, max(min_len, int(round(init_window_s * rate_hz)))


@cached_njit()
def zaru_update(bias: Array, pbias: Array, counters: IntArray, w_k: Array, still: bool, dt: float,
                par: Array) -> None:  # pragma: no cover - compiled
    """One sample of the gyroscope-bias filter (module doc) in place: random-walk prediction over ``dt``, then,
    when the foot has been still for ``par[1]`` samples (run length in ``counters[2]``), the zero angular-rate
    update ``w_k = bias + n`` per axis.
    """
    counters[2] = counters[2] + 1 if still else 0
    for i in range(3):
        pbias[i] += par[3] * dt
    if counters[2] >= par[1]:
        for i in range(3):
            gain = pbias[i] / (pbias[i] + par[2])
            bias[i] += gain * (w_k[i] - bias[i])
            pbias[i] *= 1.0 - gain


@cached_njit()
def zupt_update(p: Array, v: Array, q: Array, P: Array, r_var: float,
                dx_out: Array) -> float:  # pragma: no cover - compiled
    """Zero-velocity update (eqs. 3-4) with feedback (eq. 5) in place; returns the NIS of the innovation.

    The error estimate fed back (9,) is written to ``dx_out`` (what an RTS smoother needs).
    """
    S = P[3:6, 3:6] + np.eye(3) * r_var
    S_inv = np.linalg.inv(S)
    K = np.ascontiguousarray(P[:, 3:6]) @ S_inv
    innov = -v
    dx = K @ innov
    dx_out[:] = dx
    # Joseph form: keeps P symmetric positive semi-definite with the tiny R of a ZUPT.
    ikh = np.eye(9)
    ikh[:, 3:6] -= K
    P[:, :] = ikh @ P @ ikh.T + (K * r_var) @ K.T
    for i in range(3):
        p[i] += dx[i]
        v[i] += dx[3 + i]
    q[:] = quat_mul(quat_exp(dx[6:9]), q)
    q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    return float(innov @ S_inv @ innov)


@cached_njit()
def zupt_kernel(t: Array, f_b: Array, w_b: Array, zv: BoolArray, first: int, g_n: Array, qa: float, qg: float,
                r_var: float, interval: bool, seg_on: bool, gamma_p: float, c_min: int, c_max: int, p: Array,
                v: Array, q: Array, P: Array, dr: Array, counters: IntArray, pos: Array, vel: Array, qs: Array,
                pvar: Array, vvar: Array, avar: Array, step_idx: IntArray, step_dp: Array, step_dpsi: Array,
                step_cov: Array, hde_par: Array, hde: Array, sm_P: Array, sm_fn: Array,
                sm_dx: Array, zaru_par: Array, still: BoolArray, bias: Array,
                pbias: Array) -> int:  # pragma: no cover - compiled
    """The filter loop over samples ``first..N-1`` (sample ``first - 1`` is the last one already processed).

    The step to sample ``k`` uses the IMU samples ``k - 1`` and ``k`` (second-order mechanization), or, with
    ``interval`` (:attr:`ZuptConfig.interval_samples`), sample ``k`` alone as the mean over the step.
    Resumable: the navigation state ``p, v, q`` (local frame), the covariance ``P``, the step-wise dead
    reckoning ``dr = (x_l, chi_l)``, the Algorithm 1 counters ``counters = (c_p, c_d)`` and the drift-elimination
    state ``hde`` (parameters ``hde_par``, :meth:`ZuptConfig.hde_params`; off when ``hde_par[0] == 0``) are read at
    the start and left updated in place, so feeding a recording in consecutive chunks (each with the previous
    chunk's last sample prepended, ``first = 1``) performs exactly the operations of one run over the whole recording.
    Per-sample outputs go to ``pos, vel, qs, pvar, vvar, avar`` at the sample's index; resets to ``step_*``.
    With ``zaru_par[0]`` the gyroscope bias ``bias`` (variance ``pbias``) is updated on the ``still`` samples
    (:func:`zaru_update`; run length in ``counters[2]``) and removed from the angular rates before mechanization.
    When ``sm_P`` has rows (one per sample), what the RTS smoother (:func:`zupt_smooth_kernel`) needs is stored
    at the sample's index too: the covariance after the update ``sm_P``, the specific force of the step to the
    sample ``sm_fn`` (rebuilds ``F``) and the error fed back ``sm_dx`` (zero without an update).
    Returns the number of resets.
    """
    n = t.size
    x_l = dr[0:3]
    chi_l = dr[3]
    c_p = counters[0]
    c_d = counters[1]
    n_steps = 0
    idx = np.array([0, 1, 2, 8])
    hde_on = hde_par[0] > 0
    store = sm_P.shape[0] > 0
    dx = np.zeros(9)
    if store:
        sm_P[first - 1] = P
    zaru_on = zaru_par[0] > 0
    w0 = np.empty(3)                               # angular rates without the bias (zero without ZARU), rad/s
    w1 = np.empty(3)
    for k in range(first, n):
        for i in range(3):
            w0[i] = w_b[k - 1, i] - bias[i]
        if zaru_on:
            zaru_update(bias, pbias, counters, w_b[k], still[k], t[k] - t[k - 1], zaru_par)
        for i in range(3):
            w1[i] = w_b[k, i] - bias[i]
        if interval:                               # sample k alone: the mean over the step
            f_n = zupt_predict(p, v, q, P, f_b[k], w1, f_b[k], w1, t[k] - t[k - 1], g_n, qa, qg)
        else:
            f_n = zupt_predict(p, v, q, P, f_b[k - 1], w0, f_b[k], w1, t[k] - t[k - 1], g_n, qa, qg)
        if hde_on:
            rotate_yaw(q, drift_predict(hde, t[k] - t[k - 1], hde_par))
        if store:
            sm_fn[k] = f_n
        if zv[k]:
            zupt_update(p, v, q, P, r_var, dx)
            if store:
                sm_dx[k] = dx
        else:
            q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
        if seg_on:
            # Algorithm 1 lines 10-21: pending reset (eq. 9), reset (eq. 10).
            c_p += 1
            if P[3, 3] < gamma_p and c_p > c_min:
                c_d += 1
                if (not zv[k]) or c_d > c_max:
                    psi = yaw_of(q)
                    step_idx[n_steps] = k
                    step_dp[n_steps] = p
                    step_dpsi[n_steps] = psi
                    for i in range(4):
                        for j in range(4):
                            step_cov[n_steps, i, j] = P[idx[i], idx[j]]
                    n_steps += 1
                    c, s = math.cos(chi_l), math.sin(chi_l)
                    x_l[0] += c * p[0] - s * p[1]
                    x_l[1] += s * p[0] + c * p[1]
                    x_l[2] += p[2]
                    chi_l += psi
                    # Line 16: position and heading to zero (velocity turns with the local frame).
                    q_yaw = np.array([math.cos(-0.5 * psi), 0.0, 0.0, math.sin(-0.5 * psi)])
                    q[:] = quat_mul(q_yaw, q)
                    c, s = math.cos(psi), math.sin(psi)
                    v0, v1 = v[0], v[1]
                    v[0] = c * v0 + s * v1
                    v[1] = -s * v0 + c * v1
                    p[:] = 0.0
                    # Line 17: position and heading rows/columns of P to zero. By (6) they are decoupled from
                    # velocity, roll and pitch, whose (small) covariance is kept.
                    for i in idx:
                        P[i, :] = 0.0
                        P[:, i] = 0.0
                    c_p = 0
                    c_d = 0
        if hde_on and zv[k - 1] and not zv[k]:
            # End of a stance: heuristic drift elimination on the stride just completed.
            if seg_on:
                c, s = math.cos(chi_l), math.sin(chi_l)
                turn = drift_update(hde, x_l[0] + c * p[0] - s * p[1], x_l[1] + s * p[0] + c * p[1], hde_par)
            else:
                turn = drift_update(hde, p[0], p[1], hde_par)
            if turn != 0.0:
                rotate_yaw(q, turn)
        if seg_on:
            c, s = math.cos(chi_l), math.sin(chi_l)
            pos[k, 0] = x_l[0] + c * p[0] - s * p[1]
            pos[k, 1] = x_l[1] + s * p[0] + c * p[1]
            pos[k, 2] = x_l[2] + p[2]
            vel[k, 0] = c * v[0] - s * v[1]
            vel[k, 1] = s * v[0] + c * v[1]
            vel[k, 2] = v[2]
            qs[k] = quat_mul(np.array([math.cos(0.5 * chi_l), 0.0, 0.0, math.sin(0.5 * chi_l)]), q)
        else:
            pos[k] = p
            vel[k] = v
            qs[k] = q
        for i in range(3):
            pvar[k, i] = P[i, i]
            vvar[k, i] = P[3 + i, 3 + i]
            avar[k, i] = P[6 + i, 6 + i]
        if store:
            sm_P[k] = P
    dr[3] = chi_l
    counters[0] = c_p
    counters[1] = c_d
    return n_steps


@dataclass(frozen=True)
class KernelSetup:
    """Sample counts and noise terms of the filter loop at one sampling rate.

    Attributes
    ----------
    rate_hz
        Sampling rate the sample counts are derived from, Hz.
    min_len
        Shortest stationary run (samples) accepted for the coarse initialisation.
    init_len
        Samples of that run averaged for the initial roll and pitch.
    c_min, c_max
        Algorithm 1 counters in samples (0 without segmentation).
    seg_on
        Step segmentation enabled.
    gamma_p
        Velocity-variance threshold of eq. 9, m^2/s^2.
    """

    rate_hz: float
    min_len: int
    init_len: int
    c_min: int
    c_max: int
    seg_on: bool
    gamma_p: float


def kernel_setup(rate_hz: float, config: ZuptConfig, segmentation: Segmentation | None) -> KernelSetup:
    """Sample counts of the initialisation and of Algorithm 1 at ``rate_hz``."""
    min_len, init_len = init_lengths(rate_hz, config.init_window_s)
    c_min = c_max = 0
    if segmentation is not None:
        c_min = int(round(segmentation.c_min_s * rate_hz))
        c_max = int(round(segmentation.c_max_s * rate_hz))
    return KernelSetup(rate_hz, min_len, init_len, c_min, c_max, segmentation is not None,
                       segmentation.gamma_p if segmentation is not None else 0.0)


@dataclass
class FilterState:
    """Mutable state of the filter loop between samples (what :func:`zupt_kernel` reads and updates).

    Attributes
    ----------
    p, v
        (3,) position (m) and velocity (m/s) in the local frame of the last reset (ENU without segmentation).
    q
        (4,) attitude ``q_nb`` in that frame.
    P
        (9, 9) error covariance of ``(dp, dv, dtheta)``.
    dr
        (4,) step-wise dead reckoning ``(x_l (m, ENU), chi_l (rad))`` (eq. 7).
    counters
        (3,) int64 Algorithm 1 counters ``(c_p, c_d)`` and the length of the current still run, in samples.
    hde
        (HDE_SIZE,) state of the heuristic drift elimination (drift rate, its filter's covariance, the last
        stride end, the dominant direction, the straight-stride count; see :mod:`pdr.foot.drift`).
    bias, pbias
        (3,) gyroscope bias estimate (rad/s, sensor frame) and its variance per axis ((rad/s)^2), the zero
        angular-rate update's filter (``ZuptConfig.zaru``; the bias stays zero without it).
    """

    p: Array
    v: Array
    q: Array
    P: Array
    dr: Array
    counters: IntArray
    hde: Array = field(default_factory=lambda: np.zeros(HDE_SIZE))
    bias: Array = field(default_factory=lambda: np.zeros(3))
    pbias: Array = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def initial(cls, q0: Array, config: ZuptConfig) -> FilterState:
        """At rest at the origin with attitude ``q0`` and the initial covariance of ``config``."""
        P = np.diag(np.r_[np.zeros(3), np.full(3, config.init_sigma_vel**2), np.full(2, config.init_sigma_tilt**2),
                          config.init_sigma_yaw**2])
        return cls(np.zeros(3), np.zeros(3), np.array(q0, dtype=np.float64), P, np.zeros(4),
                   np.zeros(3, dtype=np.int64), initial_state(config.sigma_drift0), np.zeros(3),
                   np.full(3, config.sigma_bias0**2))

    def copy(self) -> FilterState:
        """An independent copy (the kernel updates a state in place)."""
        return FilterState(self.p.copy(), self.v.copy(), self.q.copy(), self.P.copy(), self.dr.copy(),
                           self.counters.copy(), self.hde.copy(), self.bias.copy(), self.pbias.copy())

    def to_dict(self) -> dict[str, list]:
        """JSON-serialisable form (floats round-trip exactly)."""
        return {"p": self.p.tolist(), "v": self.v.tolist(), "q": self.q.tolist(), "P": self.P.tolist(),
                "dr": self.dr.tolist(), "counters": self.counters.tolist(), "hde": self.hde.tolist(),
                "bias": self.bias.tolist(), "pbias": self.pbias.tolist()}

    @classmethod
    def from_dict(cls, d: dict[str, list], config: ZuptConfig | None = None) -> FilterState:
        """Inverse of :meth:`to_dict`; a state saved before the drift elimination or the zero angular-rate
        update existed starts them afresh.
        """
        f = np.float64
        cfg = config or ZuptConfig()
        hde = np.array(d["hde"], f) if "hde" in d else initial_state(cfg.sigma_drift0)
        counters = np.zeros(3, dtype=np.int64)
        saved = np.array(d["counters"], dtype=np.int64)
        counters[: saved.size] = saved
        bias = np.array(d["bias"], f) if "bias" in d else np.zeros(3)
        pbias = np.array(d["pbias"], f) if "pbias" in d else np.full(3, cfg.sigma_bias0**2)
        return cls(np.array(d["p"], f), np.array(d["v"], f), np.array(d["q"], f), np.array(d["P"], f),
                   np.array(d["dr"], f), counters, hde, bias, pbias)


@dataclass(frozen=True)
class KernelOutput:
    """Per-sample outputs of one :func:`run_kernel` call (rows before ``first`` hold the entry state) and the
    resets it found (``step_idx`` indexes the call's samples).
    """

    pos: Array
    vel: Array
    qs: Array
    pvar: Array
    vvar: Array
    avar: Array
    step_idx: IntArray
    step_dp: Array
    step_dpsi: Array
    step_cov: Array


#: Samples per segment of the checkpointed RTS smoother (:func:`run_kernel`): about 80 s at 200 Hz, 11 MB of
#: stored covariances whatever the recording's length.
SMOOTHER_SEGMENT = 1 << 14


def filter_rows(t: Array, f_b: Array, w_b: Array, zv: BoolArray, flags: BoolArray, rows: slice, first: int,
            state: FilterState, config: ZuptConfig, setup: KernelSetup, out: KernelOutput,
            store: tuple[Array, Array, Array]) -> int:
    """:func:`zupt_kernel` over the samples ``first..`` of ``rows`` (row ``first - 1`` the last sample already
    processed), outputs written to the same rows of ``out`` (reset indices count from the first row);
    ``store`` receives what the smoother needs (arrays of 0 rows: nothing).
    """
    still = flags[rows] if flags.size else flags
    return int(zupt_kernel(t[rows], f_b[rows], w_b[rows], zv[rows], first, np.array([0.0, 0.0, -config.gravity]),
                           config.sigma_acc**2, config.sigma_gyro**2, config.sigma_zupt**2,
                           config.interval_samples, setup.seg_on,
                           setup.gamma_p, setup.c_min, setup.c_max, state.p, state.v, state.q, state.P, state.dr,
                           state.counters, out.pos[rows], out.vel[rows], out.qs[rows], out.pvar[rows],
                           out.vvar[rows], out.avar[rows], out.step_idx, out.step_dp, out.step_dpsi, out.step_cov,
                           config.hde_params(), state.hde, *store, config.zaru_params(setup.rate_hz), still,
                           state.bias, state.pbias))
