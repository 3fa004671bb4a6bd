"""Tightly integrated motion-mode classification and navigation: a bank of error-state Kalman filters (seed 002).

Jump Markov model (eq. 3): the navigation state ``x_k = (r, v, q, xi)`` follows the strapdown mechanization
(eq. 12a, :func:`pdr.foot.zupt.zupt_predict`'s discretisation) whatever the motion mode ``delta_k``; the mode
decides which stochastic constraint the pseudo-observation ``y_k = 0`` imposes (eq. 3b) and how hard
(``R(delta_k)``, eq. 3d); modes follow a Markov chain with the column-stochastic transition matrix
``Pi[j, i] = p(delta_{k+1} = j | delta_k = i)`` (eq. 3e).

Two model variants of Sec. V:

* ``speed`` (eq. 12, gait-speed adaptive ZUPT): 1 unconstrained, 2 almost stationary, 3 stationary. Modes 2
  and 3 observe ``h_0 = [v, omega, C(q) s + g]`` (eq. 12c) with mode-dependent ``R_0`` (eq. 12e); mode 1 has
  ``h = 0`` with ``R = sigma_nc^2 I`` (eq. 12d), a constant likelihood.
* ``height`` (eq. 13, return to the same height): 1 unconstrained, 2 stationary at a new height, 3 stationary
  at the same height. An auxiliary state ``xi`` stores the height of the last stationary sample
  (eq. 13a); mode 3 also observes ``[p]_3 - xi`` (eq. 13b) with variance ``sigma_h^2`` (eq. 13c).

Inference (Sec. III): every leaf of the filter bank is an error-state Kalman filter conditioned on one mode
sequence (eq. 4). At each sample every leaf is predicted once and branched into the three modes; a branch's
weight is ``w_{k-1} Pi[j, i] N(0; y_hat, S)`` (eq. 6); the ``max_leaves`` most probable branches are kept
(pruning, "maximum of nine leaves"). The output is the minimum-variance merge: position and velocity means and
covariances by eq. 7, the attitude by the weighted chordal mean of eq. 8 (polar decomposition of
``sum_i w_i C(q_i)``) with the covariance of eq. 9. The log-likelihood ``sum_k log p(y_k | y_{1:k-1})``
(eq. 11b-c) is returned; :func:`learn_transition` maximises it over ``Pi`` (eq. 11a).

Deviation from eq. 12d (issue #5, :data:`NC_STATE_SPREAD_DEFAULT`): the unconstrained mode is scored on the
residuals of ``h_0`` with the spread ``H P H^T + sigma_nc^2 I`` (still no state update), and clipped gyroscope
samples add attitude process noise (:mod:`pdr.foot.saturation`); with the constant density of eq. 12d an uncertain
leaf can never re-enter a stance and the bank runs away on sprint and running recordings. A second deviation
(:mod:`pdr.foot.lost_stance`): a merged swing longer than any foot's swing reopens the leaves' velocity variance.
Measured on the PyShoe trials (``pdr eval foot /work/shared/data/pyshoe_vicon --method filterbank --hde on`` with
``max_swing_s=0`` against the default): the recovery reduces the error of the three trials that run away (one of
them to under a metre), and leaves the other 15 trials, the median, xio and foot_stride_gcp unchanged; the height
variant gains a little on its two worst trials. 1 s or 2 s instead of 1.5 s, and 0.5 or 2 m/s instead of 1 m/s, give
the same picture (1 s also changes a healthy stair trial). What remains on 2018-02-22-10-08-52 is the opposite
failure: in its slow swings the almost-stationary mode (sigma_v 0.1 m/s) wins and holds the velocity near zero while
the foot moves.

Against the ZUPT-aided INS (``pdr eval foot /work/shared/data --method all --hde on --smoother both`` prints the
figures): seed 002 compares with a ZUPT filter whose detector has one fixed threshold (row ``zupt/plain``, the best
single threshold for the PyShoe trials). The ``speed`` bank has the lower PyShoe median ARMSE and is lower on most
trials, but its runaways keep the paired test inconclusive; on foot_stride_gcp its final error is several times
smaller. The gait-adaptive detector of :mod:`pdr.foot.detectors` beats both. Scaling the constrained modes'
angular-rate and acceleration variances by that detector's threshold factor (stiller stances needed in walking than
in running) made the bank worse.

Heading drift: as in the ZUPT INS, heuristic drift elimination (:mod:`pdr.foot.drift`, settings
``zupt.hde_*``, off with ``hde_directions=0``) turns every leaf's attitude by the estimated drift at every
sample, and at the end of each stance of the merged mode posterior (unconstrained probability rising above 0.5)
the stride of the merged position measures the heading error, whose correction turns every leaf alike.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import quat_exp, quat_mul, rotate_yaw, rotmat
from pdr.filters.small_linalg import (
    congruence,
    matmul,
    matmul_bt,
    matvec,
    quadratic_form,
    symmetric_inverse,
)
from pdr.foot.drift import drift_predict, drift_update, initial_state
from pdr.foot.lost_stance import LOST_STANCE_DEFAULTS, check_lost_stance, reopen_velocity, swing_lasts
from pdr.foot.saturation import CLIP_EXCESS_FRACTION, add_clip_attitude_noise, clip_variance
from pdr.foot.zupt import ZuptConfig, check_imu, coarse_start, error_transition, mechanize
from pdr.frames import GRAVITY_MPS2

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Model variants of seed 002 Sec. V and their mode names (mode index 0, 1, 2 = the paper's 1, 2, 3).
VARIANTS: dict[str, tuple[str, str, str]] = {
    "speed": ("unconstrained", "almost_stationary", "stationary"),
    "height": ("unconstrained", "stationary_new_height", "stationary_same_height"),
}

#: Error-state layout: position, velocity, attitude (navigation-frame rotation vector), stored height xi.
N_ERR = 10
XI = 9

#: Initial transition matrices of Sec. V (columns: from-mode, rows: to-mode); their zeros are the transitions that
#: the mode diagrams of Fig. 1 leave out, kept zero by :func:`learn_transition`.
PI_INIT = {
    "speed": ((1 / 2, 1 / 3, 0.0), (1 / 2, 1 / 3, 1 / 2), (0.0, 1 / 3, 1 / 2)),
    "height": ((1 / 3, 0.0, 1 / 2), (1 / 3, 0.0, 0.0), (1 / 3, 1.0, 1 / 2)),
}

#: Default transition matrices and the rate (Hz) they belong to. ``speed``: learned by an earlier EM approximation
#: of eq. 11 (filtered expected transition counts, 6 iterations, best-likelihood iterate; since replaced by the
#: direct likelihood search of :func:`learn_transition`) from the first 90 s of the foot_stride_gcp ``own`` walks at
#: 200 Hz (a different IMU and walker than the PyShoe evaluation trials); log-likelihood -318009 -> -276888.
#: ``height``: the learned matrix of seed 002 Sec. V.B (its sampling rate is not stated; 100 Hz assumed).
PI_DEFAULT: dict[str, tuple[tuple[tuple[float, float, float], ...], float]] = {
    "speed": (((0.9908, 0.0277, 0.0), (0.0092, 0.9543, 0.0485), (0.0, 0.018, 0.9515)), 200.0),
    "height": (((0.976, 0.0, 0.031), (0.003, 0.0, 0.0), (0.021, 1.0, 0.969)), 100.0),
}

#: Default accelerometer process-noise PSD ((m/s^2)^2 s) of the leaves and spread ``sigma_nc`` of the unconstrained
#: mode (eq. 12d), issue #5. ``height``: both learned by :func:`learn_swing_noise` from ZUPT-INS runs over the same
#: training data as ``PI_DEFAULT["speed"]`` (first 90 s of the six foot_stride_gcp ``own`` walks, 357 swings):
#: pooled maximum likelihood ``q = sum |v|^2 / (3 sum T_swing)`` = 0.39 and ``sigma_nc`` = 2.73 (leave-one-walk-out:
#: q 0.41-0.52, sigma_nc 2.69-2.81, but q = 0.023 without the fast walk 35, whose swings carry most of the velocity
#: error). Eq. 13 has no almost-stationary mode: a stance is entered only if the leaf's velocity covariance at
#: foot-down covers the real velocity error there (else the stationary likelihood, eq. 6c, vanishes and the
#: unconstrained mode wins every later sample) and if the unconstrained mode's constant likelihood is as low as a
#: swing's residuals deserve (``sigma_nc`` = 1 stands for a spread of 1 m/s, 1 rad/s, 1 m/s^2, far narrower than a
#: swing). The former height defaults (median swing q = 0.009, ``sigma_nc`` = 1) lost the stances of the PyShoe
#: running trials. ``speed``: keeps ``ZuptConfig.sigma_acc``; its almost-stationary mode (sigma_v = 0.1 m/s)
#: absorbs the swing error while walking (the learned q loosens the walking stances and raises the PyShoe median
#: ARMSE, issue #5). It shares the learned ``sigma_nc`` since the unconstrained mode is scored with
#: the leaf's spread (:data:`NC_STATE_SPREAD_DEFAULT`).
ACC_PSD_DEFAULT: dict[str, float | None] = {"speed": None, "height": 0.39}
#: Default ``sigma_nc`` per variant (see :data:`ACC_PSD_DEFAULT`).
SIGMA_NC_DEFAULT: dict[str, float] = {"speed": 2.73, "height": 2.73}

#: Default of :attr:`FilterBankConfig.nc_state_spread` and :attr:`FilterBankConfig.clip_excess` (issue #5). Why:
#: a leaf whose velocity or attitude is uncertain (after clipped gyroscope samples, :mod:`pdr.foot.saturation`,
#: or a missed stance) predicts the constraint residuals with the spread ``H P H^T + R``, so its stationary
#: likelihood (eq. 6c) drops, whereas eq. 12d scores the unconstrained mode by the constant ``N(0; 0, sigma_nc^2
#: I)``: past some uncertainty no stance can win again and the bank runs away (foot_stride_gcp walk 35, several
#: PyShoe running trials). Scoring the unconstrained mode on the same residuals with ``H P H^T + sigma_nc^2 I``
#: keeps the comparison about the residuals, not the leaf's uncertainty, and the clipped-sample noise makes that
#: uncertainty honest. Both together, with ``sigma_nc`` = 2.73 for both variants, bring the PyShoe trials that ran
#: away back under or near a metre and foot_stride_gcp walk 35 from thousands of percent to a few, at a cost of
#: millimetres on the walking trials; either part alone leaves runaways (``pdr eval foot /work/shared/data --method
#: filterbank|filterbank-height --hde on`` prints the figures per dataset and trial).
NC_STATE_SPREAD_DEFAULT = True


def check_transition(pi: ArrayLike, field_name: str = "transition") -> Array:
    """A (3, 3) column-stochastic matrix of probabilities, or InputError."""
    m = np.asarray(pi, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)) or np.any(m < 0) or np.any(m > 1):
        raise InputError("the mode transition matrix must be 3x3 probabilities", field=field_name)
    if not np.allclose(m.sum(axis=0), 1.0, atol=1e-6):
        raise InputError(f"each column of the transition matrix must sum to 1, got {m.sum(axis=0)}",
                         field=field_name)
    return m


def transition_at_rate(pi: ArrayLike, from_hz: float, to_hz: float) -> Array:
    """Transition matrix of a chain sampled at ``to_hz`` with the same mode dwell times as ``pi`` at ``from_hz``.

    Off-diagonal probabilities scale with the sample interval (``p_ij ~ rate_ij dt``), the diagonal takes the
    rest; a column whose diagonal is 0 (a forced transition, e.g. mode 2 -> 3 of eq. 13) is kept as it is.
    """
    m = check_transition(pi).copy()
    r = from_hz / to_hz
    out = m.copy()
    for i in range(3):
        if m[i, i] == 0.0:
            continue
        off = [j for j in range(3) if j != i]
        out[off, i] = np.clip(m[off, i] * r, 0.0, None)
        s = float(out[off, i].sum())
        if s >= 1.0:
            out[off, i] /= s / 0.999
            s = 0.999
        out[i, i] = 1.0 - s
    return out


@dataclass(frozen=True)
class FilterBankConfig:
    """Settings of the filter bank (seed 002 eqs. 12-13).

    Attributes
    ----------
    variant
        ``speed`` (eq. 12) or ``height`` (eq. 13).
    transition
        (3, 3) column-stochastic ``Pi`` at ``transition_rate_hz``; ``None`` for :data:`PI_DEFAULT`.
    transition_rate_hz
        Sampling rate that ``transition`` belongs to, Hz.
    sigma_v, sigma_omega, sigma_s
        Per-mode standard deviations of the constraints on velocity (m/s), angular rate (rad/s) and
        acceleration ``C(q) s + g`` (m/s^2), eq. 12e; entry 0 (unconstrained) is not used.
    sigma_nc
        ``sigma_nc`` of the unconstrained mode (eq. 12d): sets its constant likelihood; default learned from
        swings (:func:`learn_swing_noise`, :data:`ACC_PSD_DEFAULT`); ``None``: :data:`SIGMA_NC_DEFAULT` of the
        variant.
    sigma_h
        Standard deviation of the same-height constraint, m (eq. 13c).
    acc_psd
        Accelerometer process-noise PSD of the leaves, (m/s^2)^2 s: velocity variance ``acc_psd * dt`` per
        sample, whatever the rate. ``None``: :data:`ACC_PSD_DEFAULT` of the variant, and where that is ``None``
        ``zupt.sigma_acc`` (velocity variance ``sigma_acc^2 dt^2`` per sample, as the ZUPT INS).
    max_leaves
        Leaves kept after pruning (seed: nine).
    clip_excess
        Clipped gyroscope samples (:mod:`pdr.foot.saturation`) add attitude process noise for an unknown excess
        rate with the standard deviation ``clip_excess * |w|`` (rad/s), constant over a run; 0: off (see
        :data:`NC_STATE_SPREAD_DEFAULT`).
    student_nu
        Degrees of freedom of a Student-t in place of the normal density of the branch likelihood (eq. 6c),
        the heavy-tailed variant that Sec. VI proposes; ``None``: normal (the seed's model).
    nc_state_spread
        Score the unconstrained mode by ``N(0; h_0(x), H P H^T + sigma_nc^2 I)`` (the constrained modes' residuals
        and leaf covariance with the spread ``sigma_nc``; no state update) instead of the constant
        ``N(0; 0, sigma_nc^2 I)`` of eq. 12d (a deviation from the seed, see :data:`NC_STATE_SPREAD_DEFAULT`).
    max_swing_s, lost_sigma_v
        A swing of the merged mode posterior (unconstrained probability at least 0.5) longer than
        ``max_swing_s`` (s) means the bank has lost its stances: every leaf's velocity variance is raised to at
        least ``lost_sigma_v^2`` ((m/s)^2) on each axis at every further sample of that swing, so the next stance
        can win again (:mod:`pdr.foot.lost_stance`). ``max_swing_s = 0`` turns this off (the seed's model).
    zupt
        Process noise, initialisation, drift elimination and sample timing (``interval_samples``) shared with the
        ZUPT-aided INS. The bank has no zero angular-rate update: ``zupt.zaru`` is refused.
    """

    variant: str = "speed"
    transition: tuple[tuple[float, float, float], ...] | None = None
    transition_rate_hz: float = 100.0
    sigma_v: tuple[float, float, float] = (0.0, 0.1, 0.01)
    sigma_omega: tuple[float, float, float] = (0.0, 0.5, 0.05)
    sigma_s: tuple[float, float, float] = (0.0, 2.0, 0.3)
    sigma_nc: float | None = None
    sigma_h: float = 0.01
    acc_psd: float | None = None
    max_leaves: int = 9
    clip_excess: float = CLIP_EXCESS_FRACTION
    student_nu: float | None = None
    nc_state_spread: bool = NC_STATE_SPREAD_DEFAULT
    max_swing_s: float = LOST_STANCE_DEFAULTS[0]
    lost_sigma_v: float = LOST_STANCE_DEFAULTS[1]
    zupt: ZuptConfig = field(default_factory=ZuptConfig)

    def __post_init__(self) -> None:
        if self.variant not in VARIANTS:
            raise InputError(f"unknown filter-bank variant '{self.variant}'; expected one of {tuple(VARIANTS)}",
                             field="variant")
        if self.transition is not None:
            check_transition(self.transition)
        for name in ("sigma_v", "sigma_omega", "sigma_s"):
            v = np.asarray(getattr(self, name), dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v[1:])) or np.any(v[1:] <= 0):
                raise InputError("must be three standard deviations, the last two positive", field=name)
        if self.sigma_nc is not None and not (math.isfinite(self.sigma_nc) and self.sigma_nc > 0):
            raise InputError(f"must be a positive number, got {self.sigma_nc}", field="sigma_nc")
        for name in ("sigma_h", "transition_rate_hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"must be a positive number, got {v}", field=name)
        if self.acc_psd is not None and not (math.isfinite(self.acc_psd) and self.acc_psd > 0):
            raise InputError(f"must be a positive number, got {self.acc_psd}", field="acc_psd")
        if not (math.isfinite(self.clip_excess) and self.clip_excess >= 0):
            raise InputError(f"must be a non-negative number, got {self.clip_excess}", field="clip_excess")
        if self.student_nu is not None and not (math.isfinite(self.student_nu) and self.student_nu > 0):
            raise InputError(f"must be a positive number, got {self.student_nu}", field="student_nu")
        check_lost_stance(self.max_swing_s, self.lost_sigma_v)
        if not 1 <= self.max_leaves <= 243:
            raise InputError("max_leaves must be between 1 and 243", field="max_leaves")
        if self.zupt.zaru:
            raise InputError("the filter bank has no zero angular-rate update (ZARU); it is a ZUPT-INS setting",
                             field="zaru")

    def acc_noise_var(self, rate_hz: float) -> float:
        """Accelerometer process noise ``qa`` of the kernel (velocity variance ``qa dt^2`` per sample), (m/s^2)^2."""
        psd = self.acc_psd if self.acc_psd is not None else ACC_PSD_DEFAULT[self.variant]
        if psd is None:
            return float(self.zupt.sigma_acc**2)
        return float(psd * rate_hz)               # psd dt = qa dt^2

    def unconstrained_sigma(self) -> float:
        """``sigma_nc`` of eq. 12d: the configured value or :data:`SIGMA_NC_DEFAULT` of the variant."""
        return float(self.sigma_nc if self.sigma_nc is not None else SIGMA_NC_DEFAULT[self.variant])

    def transition_matrix(self, rate_hz: float) -> Array:
        """``Pi`` at the recording's rate."""
        if self.transition is None:
            pi, from_hz = PI_DEFAULT[self.variant]
            return transition_at_rate(pi, from_hz, rate_hz)
        return transition_at_rate(self.transition, self.transition_rate_hz, rate_hz)


@dataclass(frozen=True)
class FilterBankTrack:
    """Merged output of the filter bank, one row per IMU sample.

    Attributes
    ----------
    t_s
        (N,) sample times, s.
    pos_n, vel_n
        (N, 3) minimum-variance position (m) and velocity (m/s), ENU (eq. 7a).
    q_nb
        (N, 4) attitude: weighted chordal mean of the leaves' attitudes (eq. 8).
    pos_var, vel_var, att_var
        (N, 3) variances of eqs. 7b and 9 (m^2, m^2/s^2, rad^2).
    mode_prob
        (N, 3) posterior probability of each mode (sum of the leaves' weights per current mode).
    mode
        (N,) most probable mode (0, 1, 2 = the paper's modes 1, 2, 3).
    log_likelihood
        ``sum_k log p(y_k | y_{1:k-1})`` (eq. 11b-c).
    start_index
        First navigated sample.
    variant
        Model variant.
    warnings
        Problems found in the input.
    """

    t_s: Array
    pos_n: Array
    vel_n: Array
    q_nb: Array
    pos_var: Array
    vel_var: Array
    att_var: Array
    mode_prob: Array
    mode: IntArray
    log_likelihood: float
    start_index: int
    variant: str
    warnings: tuple[str, ...] = ()

    @property
    def yaw(self) -> Array:
        """(N,) yaw in rad, counter-clockwise from east."""
        return quat.to_euler(self.q_nb)[2]

    @property
    def zero_velocity(self) -> NDArray[np.bool_]:
        """(N,) True where a stationary (constrained) mode is the most probable."""
        return np.asarray(self.mode != 0)


def polar_rotation(m: ArrayLike) -> Array:
    """The rotation closest to ``m`` in the Frobenius norm (eq. 8): ``U diag(1, 1, det(U V^T)) V^T``.

    ``argmin_C ||C - M||_F`` over rotations; with ``M = sum_i w_i C_i`` it is the minimiser of
    ``sum_i w_i ||C_i - C||_F^2`` (Moakher's chordal mean, ref. [13] of seed 002).
    """
    a = np.asarray(m, dtype=np.float64)
    if a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise InputError("expected a finite 3x3 matrix", field="m")
    u, _, vt = np.linalg.svd(a)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    return np.asarray(u @ np.diag([1.0, 1.0, d]) @ vt)


@cached_njit()
def _polar(m: Array) -> Array:  # pragma: no cover - compiled
    u, _, vt = np.linalg.svd(m)
    d = np.linalg.det(u @ vt)
    s = np.eye(3)
    s[2, 2] = 1.0 if d >= 0 else -1.0
    return u @ s @ vt


@cached_njit()
def _rotvec_of(c: Array) -> Array:  # pragma: no cover - compiled
    # Rotation vector of a rotation matrix (small and moderate angles).
    cos_a = min(1.0, max(-1.0, 0.5 * (c[0, 0] + c[1, 1] + c[2, 2] - 1.0)))
    a = math.acos(cos_a)
    w = np.array([c[2, 1] - c[1, 2], c[0, 2] - c[2, 0], c[1, 0] - c[0, 1]])
    k = 0.5 if a < 1e-8 else 0.5 * a / math.sin(a)
    return k * w


@cached_njit()
def _quat_of(c: Array) -> Array:  # pragma: no cover - compiled
    phi = _rotvec_of(c)
    return quat_exp(phi)


@cached_njit()
def _log_density(dim: int, logdet: float, chi2: float, nu: float) -> float:  # pragma: no cover - compiled
    # log N(e; 0, S) (nu <= 0) or log of the multivariate Student-t with nu degrees of freedom and scale S,
    # from dim, log|S| and chi2 = e' S^-1 e.
    if nu <= 0.0:
        return -0.5 * (dim * math.log(2.0 * math.pi) + logdet + chi2)
    return (math.lgamma(0.5 * (nu + dim)) - math.lgamma(0.5 * nu) - 0.5 * dim * math.log(nu * math.pi)
            - 0.5 * logdet - 0.5 * (nu + dim) * math.log1p(chi2 / nu))


@cached_njit()
def _constraint_rows(v: Array, w_k: Array, f_n: Array, g_n: Array,
                     dh: float) -> tuple[Array, Array]:  # pragma: no cover - compiled
    # Rows of h_0 (eq. 12c) and of the height constraint (eq. 13b) with their residuals y - h = -h:
    # velocity, angular rate, C(q) s + g (d(C s)/d(dtheta) = -[f_n]x, true = exp(dtheta) est), [p]_3 - xi.
    H = np.zeros((10, N_ERR))
    e = np.zeros(10)
    for a in range(3):
        H[a, 3 + a] = 1.0
        e[a] = -v[a]
        e[3 + a] = -w_k[a]
        e[6 + a] = -(f_n[a] + g_n[a])
    H[6, 7] = f_n[2]
    H[6, 8] = -f_n[1]
    H[7, 6] = -f_n[2]
    H[7, 8] = f_n[0]
    H[8, 6] = f_n[1]
    H[8, 7] = -f_n[0]
    H[9, 2] = 1.0
    H[9, XI] = -1.0
    e[9] = -dh
    return H, e


@cached_njit()
def _bank_kernel(t: Array, f_b: Array, w_b: Array, start: int, q0: Array, g_n: Array, qa: float, qg: float,
                 P0: Array, log_pi: Array, sv: Array, sw: Array, ss: Array, snc: float, sh: float, height: bool,
                 max_leaves: int, pos: Array, vel: Array, qs: Array, pvar: Array, vvar: Array, avar: Array,
                 mprob: Array, hde_par: Array, hde: Array,
                 sat_var: Array, nu: float, nc_state: bool, max_swing: float,
                 lost_var: float, interval: bool) -> float:  # pragma: no cover - compiled
    n = t.size
    swing_s = 0.0
    hde_on = hde_par[0] > 0
    was_stance = True                              # initialised at rest
    L = max_leaves
    # Leaves.
    lp = np.zeros((L, 3))
    lv = np.zeros((L, 3))
    lq = np.zeros((L, 4))
    lxi = np.zeros(L)
    lP = np.zeros((L, N_ERR, N_ERR))
    lw = np.full(L, -np.inf)
    lm = np.zeros(L, dtype=np.int64)
    lq[0] = q0
    lP[0] = P0
    lw[0] = 0.0
    lm[0] = 2                                      # initialised at rest
    n_leaves = 1
    # Candidates.
    C = 3 * L
    cp = np.zeros((C, 3))
    cv = np.zeros((C, 3))
    cq = np.zeros((C, 4))
    cxi = np.zeros(C)
    cP = np.zeros((C, N_ERR, N_ERR))
    cw = np.zeros(C)
    cm = np.zeros(C, dtype=np.int64)
    loglik = 0.0
    for k in range(start + 1, n):
        dt = t[k] - t[k - 1]
        f_k = f_b[k]
        w_k = w_b[k]
        sat_k = np.maximum(sat_var[k - 1], sat_var[k])
        sat_any = sat_k.max() > 0.0
        nc = 0
        for i in range(n_leaves):
            # Prediction (eq. 12a): one per leaf, shared by its three branches.
            q = lq[i].copy()
            p = lp[i].copy()
            v = lv[i].copy()
            if interval:                           # sample k alone: the mean over the step (ZuptConfig)
                f_n = mechanize(p, v, q, f_k, w_k, f_k, w_k, dt, g_n)
            else:
                f_n = mechanize(p, v, q, f_b[k - 1], w_b[k - 1], f_k, w_k, dt, g_n)
            q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
            F = np.eye(N_ERR)
            F[:9, :9] = error_transition(f_n, dt)
            P = congruence(F, lP[i])
            for a in range(3):
                P[3 + a, 3 + a] += qa * dt * dt
                P[6 + a, 6 + a] += qg * dt * dt
            if sat_any:
                add_clip_attitude_noise(P, 6, rotmat(q), sat_k, dt)    # clipped gyroscope axes
            # Specific force of the predicted attitude, for the acceleration constraint C(q) s + g.
            f_n = matvec(rotmat(q), f_k)
            H_all, e_all = _constraint_rows(v, w_k, f_n, g_n, p[2] - lxi[i])
            PHt = matmul_bt(P, H_all)              # shared by the modes' innovation covariances and gains
            HPHt = matmul(H_all, PHt)
            m_dim = 10 if height else 9
            if nc_state:
                # Unconstrained mode scored on the same residuals with the spread sigma_nc (FilterBankConfig.
                # nc_state_spread): its density widens with the leaf's uncertainty as the constrained modes' do.
                S1 = HPHt[:m_dim, :m_dim].copy()
                for a in range(m_dim):
                    S1[a, a] += snc * snc
                S1_inv, logdet1 = symmetric_inverse(S1)
                ll_nc = _log_density(m_dim, logdet1, quadratic_form(e_all[:m_dim], S1_inv), nu)
            else:
                ll_nc = _log_density(m_dim, 2.0 * m_dim * math.log(snc), 0.0, nu)
            for j in range(3):
                prior = log_pi[j, lm[i]]
                if prior == -np.inf:
                    continue
                cp[nc] = p
                cv[nc] = v
                cq[nc] = q
                cxi[nc] = lxi[i]
                cm[nc] = j
                if j == 0:
                    cP[nc] = P
                    ll = ll_nc
                else:
                    same_h = height and j == 2
                    dim = 10 if same_h else 9
                    H = H_all[:dim]
                    e = e_all[:dim]
                    R = np.zeros(dim)
                    for a in range(3):
                        R[a] = sv[j] ** 2
                        R[3 + a] = sw[j] ** 2
                        R[6 + a] = ss[j] ** 2
                    if same_h:
                        R[9] = sh ** 2
                    S = HPHt[:dim, :dim].copy()
                    for a in range(dim):
                        S[a, a] += R[a]
                    S_inv, logdet = symmetric_inverse(S)
                    K = matmul(PHt[:, :dim], S_inv)
                    dx = matvec(K, e)
                    ikh = np.eye(N_ERR) - matmul(K, H)
                    Pn = congruence(ikh, P)
                    for a in range(dim):
                        for b in range(N_ERR):
                            for c in range(N_ERR):
                                Pn[b, c] += K[b, a] * R[a] * K[c, a]
                    cP[nc] = Pn
                    for a in range(3):
                        cp[nc, a] += dx[a]
                        cv[nc, a] += dx[3 + a]
                    qq = quat_mul(quat_exp(dx[6:9]), q)
                    cq[nc] = qq / math.sqrt(qq[0] ** 2 + qq[1] ** 2 + qq[2] ** 2 + qq[3] ** 2)
                    cxi[nc] += dx[XI]
                    ll = _log_density(dim, logdet, quadratic_form(e, S_inv), nu)
                    if height and dim == 9:
                        # The height row unconstrained, scored as in the unconstrained mode.
                        s9 = snc * snc
                        if nc_state:
                            s9 += P[2, 2] - 2.0 * P[2, XI] + P[XI, XI]
                        ll += _log_density(1, math.log(s9), e_all[9] ** 2 / s9 if nc_state else 0.0, nu)
                cw[nc] = lw[i] + prior + ll
                nc += 1
        # Normalise (eq. 6b); log p(y_k | y_{1:k-1}) of eq. 11c.
        mx = -np.inf
        for c in range(nc):
            mx = max(mx, cw[c])
        tot = 0.0
        for c in range(nc):
            tot += math.exp(cw[c] - mx)
        lse = mx + math.log(tot)
        loglik += lse
        for c in range(nc):
            cw[c] -= lse
        # Pruning: keep the max_leaves most probable branches.
        order = np.argsort(-cw[:nc])
        n_leaves = min(L, nc)
        keep_tot = 0.0
        for r in range(n_leaves):
            c = order[r]
            keep_tot += math.exp(cw[c])
        lkeep = math.log(keep_tot)
        for r in range(n_leaves):
            c = order[r]
            lp[r] = cp[c]
            lv[r] = cv[c]
            lq[r] = cq[c]
            lxi[r] = cxi[c]
            lP[r] = cP[c]
            lw[r] = cw[c] - lkeep
            lm[r] = cm[c]
        # Eq. 13a: xi follows the height while stationary.
        if height:
            for r in range(n_leaves):
                if lm[r] != 0:
                    lxi[r] = lp[r, 2]
                    for b in range(N_ERR):
                        lP[r, XI, b] = lP[r, 2, b]
                    for b in range(N_ERR):
                        lP[r, b, XI] = lP[r, b, 2]
                    lP[r, XI, XI] = lP[r, 2, 2]
        if hde_on:
            # Heuristic drift elimination (pdr.foot.drift): the estimated drift is removed from every leaf.
            turn = drift_predict(hde, dt, hde_par)
            for r in range(n_leaves):
                rotate_yaw(lq[r], turn)
        # Merge (eqs. 7-9).
        mean_p = np.zeros(3)
        mean_v = np.zeros(3)
        M = np.zeros((3, 3))
        for r in range(n_leaves):
            w = math.exp(lw[r])
            mprob[k, lm[r]] += w
            mean_p += w * lp[r]
            mean_v += w * lv[r]
            M += w * rotmat(lq[r])
        c_mv = _polar(M)
        qs[k] = _quat_of(c_mv)
        for r in range(n_leaves):
            w = math.exp(lw[r])
            dphi = _rotvec_of(c_mv @ rotmat(lq[r]).T)
            for a in range(3):
                dp_ = lp[r, a] - mean_p[a]
                dv_ = lv[r, a] - mean_v[a]
                pvar[k, a] += w * (lP[r, a, a] + dp_ * dp_)
                vvar[k, a] += w * (lP[r, 3 + a, 3 + a] + dv_ * dv_)
                avar[k, a] += w * (lP[r, 6 + a, 6 + a] + dphi[a] * dphi[a])
        pos[k] = mean_p
        vel[k] = mean_v
        in_stance = mprob[k, 0] < 0.5
        if hde_on and was_stance and not in_stance:
            # End of a stance of the merged mode posterior: the stride of the merged position measures the
            # heading error; the correction turns every leaf and the merged attitude alike.
            turn = drift_update(hde, mean_p[0], mean_p[1], hde_par)
            if turn != 0.0:
                for r in range(n_leaves):
                    rotate_yaw(lq[r], turn)
                rotate_yaw(qs[k], turn)
        was_stance = in_stance
        swing_s = swing_lasts(swing_s, in_stance, dt)
        for r in range(n_leaves):
            reopen_velocity(lP[r], 3, swing_s, max_swing, lost_var)    # a swing too long: stances lost
    return loglik


def run_filterbank(t_s: ArrayLike, acc_b: ArrayLike, gyro_b: ArrayLike, zero_velocity: ArrayLike,
                   config: FilterBankConfig | None = None) -> FilterBankTrack:
    """Run the filter bank over a recording (seed 002 Sec. III with the models of Sec. V).

    Parameters
    ----------
    t_s
        (N,) strictly increasing sample times, s.
    acc_b, gyro_b
        (N, 3) specific force (m/s^2) and angular rate (rad/s), sensor frame.
    zero_velocity
        (N,) detector flags, used only to find the first stationary period for the coarse initialisation of
        roll and pitch; the filter bank classifies the motion mode itself.
    config
        Model and noise settings.
    """
    cfg = config or FilterBankConfig()
    t, f_b, w_b = check_imu(t_s, acc_b, gyro_b)
    zv = np.asarray(zero_velocity, dtype=bool)
    if zv.shape != t.shape:
        raise InputError(f"expected shape {t.shape}, got {zv.shape}", field="zero_velocity")
    n = t.size
    rate = 1.0 / float(np.median(np.diff(t)))
    z = cfg.zupt
    a, q0, warning = coarse_start(t, f_b, zv, rate, z.init_window_s, z.yaw0)
    P0 = np.zeros((N_ERR, N_ERR))
    P0[3:6, 3:6] = np.eye(3) * z.init_sigma_vel**2
    P0[6, 6] = P0[7, 7] = z.init_sigma_tilt**2
    P0[8, 8] = z.init_sigma_yaw**2
    pi = cfg.transition_matrix(rate)
    with np.errstate(divide="ignore"):
        log_pi = np.log(pi)
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    qs = np.tile(q0, (n, 1))
    pvar = np.zeros((n, 3))
    vvar = np.zeros((n, 3))
    avar = np.zeros((n, 3))
    mprob = np.zeros((n, 3))
    mprob[: a + 1, 2] = 1.0
    loglik = _bank_kernel(t, np.ascontiguousarray(f_b), np.ascontiguousarray(w_b), a, q0,
                          np.array([0.0, 0.0, -z.gravity]), cfg.acc_noise_var(rate), z.sigma_gyro**2, P0, log_pi,
                          np.asarray(cfg.sigma_v, dtype=np.float64), np.asarray(cfg.sigma_omega, dtype=np.float64),
                          np.asarray(cfg.sigma_s, dtype=np.float64), cfg.unconstrained_sigma(), cfg.sigma_h,
                          cfg.variant == "height", cfg.max_leaves, pos, vel, qs, pvar, vvar, avar, mprob,
                          z.hde_params(), initial_state(z.sigma_drift0),
                          clip_variance(w_b, cfg.clip_excess),
                          cfg.student_nu if cfg.student_nu is not None else 0.0, cfg.nc_state_spread,
                          cfg.max_swing_s, cfg.lost_sigma_v**2, z.interval_samples)
    return FilterBankTrack(t, pos, vel, quat.normalize(qs), pvar, vvar, avar, mprob,
                           np.argmax(mprob, axis=1).astype(np.int64), float(loglik), a, cfg.variant,
                           (warning,) if warning else ())


#: Bound of the column log-odds that parametrise ``Pi`` in :func:`learn_transition` (``|log(Pi[j, i] / Pi[r, i])|``
#: <= 12: no free entry below ~6e-6, so no transition of Fig. 1 is ruled out by the search).
LOGIT_BOUND = 12.0
#: Side of the initial Nelder-Mead simplex in those log-odds (a factor e^2 ~ 7 in a probability ratio).
SIMPLEX_STEP = 2.0


class _Budget(Exception):
    """The likelihood-evaluation budget of :func:`learn_transition` is spent."""


def _transition_coords(mask: NDArray[np.bool_]) -> list[tuple[int, int, int]]:
    """Free entries ``(j, i, r)`` of a structure mask: ``Pi[j, i]`` is parametrised by its log-odds against the
    reference ``Pi[r, i]`` of its column (the diagonal if free, else the first free entry).
    """
    out = []
    for i in range(mask.shape[1]):
        free = np.flatnonzero(mask[:, i])
        r = i if mask[i, i] else int(free[0])
        out += [(int(j), i, r) for j in free if j != r]
    return out


def _transition_of(theta: Array, mask: NDArray[np.bool_], coords: list[tuple[int, int, int]]) -> Array:
    """Column-stochastic ``Pi`` of log-odds ``theta``: a softmax over each column's free entries."""
    logit = np.where(mask, 0.0, -np.inf)
    for (j, i, _), v in zip(coords, theta, strict=True):
        logit[j, i] = v
    e = np.exp(logit - logit.max(axis=0))
    return np.asarray(e / e.sum(axis=0))


@dataclass(frozen=True)
class TransitionLearning:
    """Result of :func:`learn_transition`.

    Attributes
    ----------
    transition
        (3, 3) learned ``Pi`` at ``rate_hz``: the evaluated matrix of largest likelihood.
    rate_hz
        Sampling rate the matrix belongs to, Hz.
    log_likelihood
        (E,) log-likelihood of the training data (eq. 11b, the sum over the sequences) at each evaluated
        ``Pi`` in the order of evaluation; entry 0 is the initial matrix.
    seconds
        Wall-clock cost of the search, s.
    """

    transition: Array
    rate_hz: float
    log_likelihood: Array
    seconds: float

    @property
    def best_so_far(self) -> Array:
        """(E,) largest log-likelihood found up to each evaluation (non-decreasing)."""
        return np.asarray(np.maximum.accumulate(self.log_likelihood))


def transition_log_likelihood(sequences: Sequence[tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike]],
                              config: FilterBankConfig, transition: ArrayLike, rate_hz: float) -> float:
    """``log p(y_{1:k}; Pi)`` of eq. 11b summed over training sequences, each evaluated by the filter bank (eq. 11c).

    Everything but ``Pi`` (noise, pruning to ``max_leaves``, first navigated sample) is fixed by ``config`` and
    the data, so values for different ``Pi`` are comparable (``log p(y_1)`` is left out: it does not depend on
    ``Pi``). ``transition`` is at ``rate_hz``; a sequence at another rate gets it via :func:`transition_at_rate`.
    """
    pi = check_transition(transition)
    cfg = FilterBankConfig(**{**config.__dict__, "transition": tuple(map(tuple, pi.tolist())),
                              "transition_rate_hz": rate_hz})
    return float(sum(run_filterbank(t, f, w, zv, cfg).log_likelihood for t, f, w, zv in sequences))


def learn_transition(sequences: Sequence[tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike]],
                     config: FilterBankConfig | None = None, rate_hz: float = 100.0, max_evaluations: int = 60,
                     initial: ArrayLike | None = None) -> TransitionLearning:
    """Maximum-likelihood ``Pi`` of training data, ``argmax_Pi p(y_{1:k}; Pi)`` (seed 002 eq. 11a).

    The objective is the log of eq. 11b, ``sum_n log p(y_n | y_{1:n-1})`` with the one-step predictive
    likelihood of eq. 11c given by the pruned filter bank (:func:`transition_log_likelihood`). It is maximised
    directly over the free entries of ``Pi``: the transitions of the variant's diagram (seed Fig. 1, the
    non-zero pattern of :data:`PI_INIT`; the others stay zero), each column parametrised by the log-odds of its
    free entries against one of them (a softmax, so every column stays stochastic), bounded by
    :data:`LOGIT_BOUND`. The likelihood of a pruned bank is not smooth in ``Pi`` (pruning decisions jump), so
    the search is derivative-free: bounded Nelder-Mead from ``initial`` with a simplex of side
    :data:`SIMPLEX_STEP`, stopped after ``max_evaluations`` likelihood evaluations (each one filter-bank run
    over all sequences). ``Pi`` is per sample at ``rate_hz``.

    Parameters
    ----------
    sequences
        ``(t_s, acc_b, gyro_b, zero_velocity)`` per training recording, each starting at rest.
    config
        Model settings (its transition matrix is replaced).
    rate_hz
        Sampling rate the learned ``Pi`` belongs to, Hz (that of the training data).
    max_evaluations
        Likelihood evaluations allowed, the initial one included.
    initial
        (3, 3) starting matrix, zero on the structural zeros and positive elsewhere; default :data:`PI_INIT`.
    """
    from scipy.optimize import minimize

    base = config or FilterBankConfig()
    if not sequences:
        raise InputError("no training sequences", field="sequences")
    if max_evaluations < 1:
        raise InputError(f"must be at least 1, got {max_evaluations}", field="max_evaluations")
    mask = np.asarray(PI_INIT[base.variant]) > 0
    pi0 = check_transition(PI_INIT[base.variant] if initial is None else initial, "initial")
    if np.any(pi0[~mask] > 0) or np.any(pi0[mask] <= 0):
        raise InputError(f"the initial matrix must have the transitions of the '{base.variant}' diagram (seed "
                         f"Fig. 1), non-zero exactly where {PI_INIT[base.variant]} is", field="initial")
    coords = _transition_coords(mask)
    x0 = np.clip([math.log(pi0[j, i] / pi0[r, i]) for j, i, r in coords], -LOGIT_BOUND, LOGIT_BOUND)
    history: list[float] = []
    best: list[Array] = [pi0]
    t0 = time.perf_counter()

    def neg_ll(theta: Array) -> float:
        if len(history) >= max_evaluations:
            raise _Budget
        pi = _transition_of(theta, mask, coords)
        ll = transition_log_likelihood(sequences, base, pi, rate_hz)
        if not math.isfinite(ll):
            ll = -math.inf
        if not history or ll > max(history):
            best[0] = pi
        history.append(ll)
        return -ll if math.isfinite(ll) else math.inf

    if x0.size == 0:
        neg_ll(x0)
    else:
        simplex = np.vstack([x0] + [x0 + np.where(np.arange(x0.size) == d,
                                                  -SIMPLEX_STEP if x0[d] > SIMPLEX_STEP - LOGIT_BOUND
                                                  else SIMPLEX_STEP, 0.0) for d in range(x0.size)])
        try:
            minimize(neg_ll, x0, method="Nelder-Mead", bounds=[(-LOGIT_BOUND, LOGIT_BOUND)] * x0.size,
                     options={"initial_simplex": simplex, "maxfev": max_evaluations, "xatol": 0.05,
                              "fatol": 0.5})
        except _Budget:
            pass
    return TransitionLearning(best[0], rate_hz, np.asarray(history), time.perf_counter() - t0)


@dataclass(frozen=True)
class SwingNoise:
    """Result of :func:`learn_swing_noise`.

    Attributes
    ----------
    acc_psd
        Pooled maximum-likelihood accelerometer process-noise PSD, (m/s^2)^2 s.
    sigma_nc
        Spread of the unconstrained mode (eq. 12d): geometric mean of the swing residuals' RMS per variable.
    rms
        (9,) RMS of ``[v (m/s), omega (rad/s), C(q) s + g (m/s^2)]`` over the swing samples.
    swings
        Swings used for ``acc_psd``.
    """

    acc_psd: float
    sigma_nc: float
    rms: Array
    swings: int


def learn_swing_noise(runs: Sequence[tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike, ArrayLike, ArrayLike]],
                      gravity: float = GRAVITY_MPS2) -> SwingNoise:
    """Learn the leaves' process noise and the unconstrained mode's spread from ZUPT-INS runs (issue #5).

    The stances come from the ZUPT detector, the states from the ZUPT-aided INS (as seed 000 learns its context
    from the states of a ZUPT-EKF run); the rest of the bank's model is learned by eq. 11 (:func:`learn_transition`).

    * ``acc_psd``: a swing's velocity error is ``N(0, q T I)`` after ``T`` seconds without a ZUPT; the INS's
      predicted velocity ``v`` at the last swing sample before each stance is that error, and the maximum
      likelihood ``q`` over all swings is ``sum |v|^2 / (3 sum T)``.
    * ``sigma_nc``: the unconstrained mode's likelihood is ``N(y; 0, sigma_nc^2 I)`` evaluated at ``y = 0``
      (eq. 12d); the isotropic Gaussian with the same volume (determinant) as the swing samples' residuals
      ``[v, omega, C(q) s + g]`` has ``sigma_nc`` = geometric mean of their per-variable RMS.

    Parameters
    ----------
    runs
        ``(t_s, vel_n, q_nb, acc_b, gyro_b, zero_velocity)`` per training recording: times (s), the ZUPT INS's
        velocity (m/s, ENU) and attitude, the IMU's specific force (m/s^2) and angular rate (rad/s), the
        detector's flags.
    gravity
        m/s^2.
    """
    v2, dur, res = 0.0, 0.0, []
    swings = 0
    for t_s, vel_n, q_nb, acc_b, gyro_b, zero_velocity in runs:
        t = np.asarray(t_s, dtype=np.float64)
        zv = np.asarray(zero_velocity, dtype=bool)
        vel = np.asarray(vel_n, dtype=np.float64)
        if zv.shape != t.shape or vel.shape != (t.size, 3):
            raise InputError("each run needs (N,) times and flags and (N, 3) velocities", field="runs")
        edges = np.flatnonzero(np.diff(zv.astype(np.int8)))
        if edges.size == 0:
            continue
        lift = edges[zv[edges]] + 1                    # first swing sample
        down = edges[~zv[edges]] + 1                   # first stance sample
        for s in down:
            before = lift[lift < s]
            if before.size == 0:
                continue
            v2 += float(np.sum(vel[s - 1] ** 2))
            dur += float(t[s - 1] - t[before[-1] - 1])
            swings += 1
        swing = ~zv
        swing[: int(np.argmax(zv))] = False            # before the first stance the INS is not aligned
        a_n = quat.rotate(np.asarray(q_nb, dtype=np.float64)[swing], np.asarray(acc_b, dtype=np.float64)[swing])
        a_n[:, 2] -= gravity
        res.append(np.concatenate([vel[swing], np.asarray(gyro_b, dtype=np.float64)[swing], a_n], axis=1))
    if swings == 0 or dur <= 0:
        raise InputError("no swing between two detected stances in the training runs", field="runs")
    rms = np.sqrt(np.mean(np.concatenate(res) ** 2, axis=0))
    return SwingNoise(v2 / (3.0 * dur), float(np.exp(np.mean(np.log(rms)))), rms, swings)
