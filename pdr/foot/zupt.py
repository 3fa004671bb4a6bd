"""Zero-velocity-aided inertial navigation (ZUPT-aided INS) with an error-state Kalman filter.

Seed 001 Sec. 3.1: the strapdown mechanization (eq. 1, :mod:`pdr.strapdown`) runs at the IMU rate; a
first-order error model (eq. 2) propagates the covariance of the 9 error states ``(dp, dv, dtheta)``; samples
flagged stationary by a zero-velocity detector give the pseudo-measurement ``y = v = 0`` (eqs. 3-4); the
estimated errors are fed back into the navigation state and reset to zero (eq. 5). As in the seed, the error
filter has no sensor bias states.

Optional zero angular-rate update (ZARU, ``ZuptConfig.zaru``): while the foot is completely still -- the SHOE
statistic with the default noise levels below ``zaru_threshold`` for at least ``zaru_min_still_s`` in a row, a far
stricter test than the zero-velocity detector's, so the small rotations of a walking stance stay out -- the true
angular rate is zero and the gyroscope measures its own bias: ``y_k = w_k = b_k + n_k``. A Kalman filter of the
bias per sensor axis (random walk ``sigma_bias_rw``, measurement noise ``sigma_zaru``) runs causally inside the
same loop and the mechanization integrates ``w - b``. The bias filter is decoupled from the 9 error states (the
attitude error it leaves behind is what the ZUPTs and the drift elimination see anyway), so the filter, its
smoother and the chunked online run stay as they are.

Why the update is off by default (issue #5; ``pdr eval foot /work/shared/data --method zupt --hde on --smoother
both --zaru on|off``, off / on): PyShoe median ARMSE 0.0465 / 0.0465 m smoothed, 0.0579 / 0.0539 m causal;
xio_gait_loop 19.3 / 10.6 mm; foot_stride_gcp median 0.73 / 0.59 %, but walk 36 1.14 / 2.97 % and walk 34
0.32 / 0.65 %. Walk 36's only rest (1.9 s at the start) reads 0.37 deg/s about the sensor z axis, 30 times
the 3DM-GX5-25's specified bias instability: a slow real rotation of the standing foot, not a bias, and
removing it for 70 s turns the heading. A larger ``sigma_zaru`` (2 or 4 deg/s, the still samples taken as
correlated) or ``zaru_min_still_s`` of 1 s do not remove that loss (walk 36 2.5-3.0 %) and lose xio
(47-64 mm). The update pays where the sensor's bias is large against the foot's residual motion (a consumer
IMU) and the walk has long rests.

Sample timing (``ZuptConfig.interval_samples``): by default each IMU sample is taken as the value at its instant
and the step from ``k - 1`` to ``k`` integrates the two samples (trapezoid, coning term). An IMU that averages or
integrates between outputs delivers instead the mean over the interval ending at ``k``; ``interval_samples`` then
integrates sample ``k`` alone over that step, as PyShoe's reference INS does. Measured (issue #5, ``pdr eval foot
/work/shared/data --method zupt --hde on --smoother both --imu-samples instant|interval``): PyShoe median ARMSE
0.0465 / 0.0453 m smoothed, 0.0579 / 0.0582 m causal; xio_gait_loop 19 / 34 mm; foot_stride_gcp median 0.73 /
0.73 %. Not the default: no clear gain, and xio loses. With the PyShoe files' reference labels (``--zv-labels
shoe``: thresholds grid-searched per trial with that first-order INS) it gains more, 0.0427 -> 0.0409 m smoothed
and 0.0496 -> 0.0478 m causal, because those labels were tuned to that mechanization.

Error convention: ``error = true - estimate`` for position and velocity, and ``q_true = exp(dtheta) * q_est``
(a navigation-frame rotation vector, :func:`pdr.quaternion.boxplus`). With it the attitude-to-velocity block
of eq. 2 is ``-[f_n]x dt`` (the seed's ``+[f_n]x dt`` belongs to the opposite sign of ``dtheta``).

The same loop implements the step-wise inertial navigation of Sec. 3.2 / Algorithm 1 (``segmentation``):
at every reset the position and heading (and their covariance rows) are zeroed and handed over as
``(dp_l, dpsi_l, P_w)`` to :mod:`pdr.foot.stepwise`.

Heading drift (``ZuptConfig.hde_directions``): the heading is not observable from ZUPTs (seed 001 eq. 6), so
the INS heading drifts; it is removed by heuristic drift elimination (:mod:`pdr.foot.drift`, shared with the
filter bank and belief condensation): straight strides along one of a few dominant directions measure the
heading error, a two-state Kalman filter of heading error and drift rate feeds it back into the attitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.filters.rotation_kernels import quat_exp, quat_mul, rotmat, yaw_of
from pdr.filters.rts import rts_step
from pdr.foot.detectors import STILL_THRESHOLD, still_samples
from pdr.foot.drift import HDE_SIZE, drift_predict, drift_update, initial_state, rotate_yaw
from pdr.frames import GRAVITY_MPS2
from pdr.step_increment import StepIncrement
from pdr.strapdown import initial_attitude_from_gravity

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

# Indices of the error state (seed 001 eq. 2).
POS = slice(0, 3)
VEL = slice(3, 6)
ATT = slice(6, 9)
YAW = 8


@dataclass(frozen=True)
class ZuptConfig:
    """Noise model of the ZUPT-aided INS (seed 001 eqs. 2-4).

    Attributes
    ----------
    sigma_acc
        Accelerometer process noise, m/s^2 (white, per sample: velocity noise ``sigma_acc * dt``).
    sigma_gyro
        Gyroscope process noise, rad/s (attitude noise ``sigma_gyro * dt``).
    sigma_zupt
        Standard deviation of the zero-velocity pseudo-measurement noise ``n_k`` of eq. 4, m/s.
    init_sigma_vel
        Initial velocity standard deviation, m/s.
    init_sigma_tilt
        Initial roll and pitch standard deviation, rad (after the coarse self-initialisation).
    init_sigma_yaw
        Initial heading standard deviation, rad (heading is not observable: it only sets the covariance).
    gravity
        Local gravity magnitude, m/s^2.
    init_window_s
        Length of the stationary period at the start used for the coarse self-initialisation, s.
    yaw0
        Initial yaw in rad (counter-clockwise from east in the navigation frame).
    hde_directions
        Number of evenly spaced dominant walking directions for the heuristic drift elimination (4: a
        rectangular building; 8 adds the diagonals); 0 disables it.
    hde_sigma_dir
        Standard deviation of a straight stride's direction about the dominant direction it follows, rad.
    hde_max_dev
        Largest deviation from a dominant direction that is taken as drift, rad.
    hde_straight_tol
        Largest change of direction between consecutive strides of a straight stretch, rad.
    hde_min_strides
        Strides of a straight stretch before its strides count as measurements.
    hde_min_stride_m
        Shortest horizontal stride (m) that has a direction (shorter ones are ignored).
    sigma_drift0
        Initial standard deviation of the heading drift rate, rad/s.
    sigma_drift_rw
        Random walk of the heading drift rate, rad/s per sqrt(s).
    sigma_heading_rw
        Random walk of the heading error in the drift filter, rad per sqrt(s).
    zaru
        Estimate the gyroscope bias by zero angular-rate updates while the foot is still (module doc).
    zaru_threshold
        Largest SHOE statistic (default detector noise levels, dimensionless) of a still sample
        (:func:`pdr.foot.detectors.still_samples`).
    zaru_min_still_s
        Time the foot must have been still before its samples measure the bias, s.
    sigma_zaru
        Standard deviation of the angular rate of a still sample about the bias (noise and residual motion), rad/s.
    sigma_bias0
        Initial standard deviation of the gyroscope bias per axis, rad/s.
    sigma_bias_rw
        Random walk of the gyroscope bias, rad/s per sqrt(s).
    interval_samples
        Each IMU sample is the mean specific force and angular rate over the interval that ends at it (an IMU
        that averages or integrates between outputs), so the step to sample ``k`` uses sample ``k`` alone;
        default off: samples are the values at their instants and the mechanization is second-order between
        ``k - 1`` and ``k`` (module doc, "Sample timing").
    """

    sigma_acc: float = 0.5
    sigma_gyro: float = float(np.radians(0.5))
    sigma_zupt: float = 0.01
    init_sigma_vel: float = 0.01
    init_sigma_tilt: float = float(np.radians(1.0))
    init_sigma_yaw: float = float(np.radians(0.1))
    gravity: float = GRAVITY_MPS2
    init_window_s: float = 0.5
    yaw0: float = 0.0
    hde_directions: int = 4
    hde_sigma_dir: float = float(np.radians(2.0))
    hde_max_dev: float = float(np.radians(10.0))
    hde_straight_tol: float = float(np.radians(5.0))
    hde_min_strides: int = 3
    hde_min_stride_m: float = 0.3
    sigma_drift0: float = float(np.radians(0.2))
    sigma_drift_rw: float = float(np.radians(0.005))
    sigma_heading_rw: float = float(np.radians(0.05))
    zaru: bool = False
    zaru_threshold: float = STILL_THRESHOLD
    zaru_min_still_s: float = 0.5
    sigma_zaru: float = float(np.radians(0.5))
    sigma_bias0: float = float(np.radians(0.5))
    sigma_bias_rw: float = float(np.radians(0.03))
    interval_samples: bool = False

    def __post_init__(self) -> None:
        for name in ("sigma_acc", "sigma_gyro", "sigma_zupt", "init_sigma_vel", "init_sigma_tilt",
                     "init_sigma_yaw", "gravity", "init_window_s", "hde_sigma_dir", "hde_max_dev",
                     "hde_straight_tol", "hde_min_stride_m", "sigma_drift0", "sigma_drift_rw", "sigma_heading_rw",
                     "zaru_threshold", "zaru_min_still_s", "sigma_zaru", "sigma_bias0", "sigma_bias_rw"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"must be a positive number, got {value}", field=name)
        for name in ("hde_directions", "hde_min_strides"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
                raise InputError(f"must be a non-negative integer, got {value!r}", field=name)
        if self.hde_min_strides < 1:
            raise InputError(f"must be at least 1, got {self.hde_min_strides}", field="hde_min_strides")

    def zaru_params(self, rate_hz: float) -> Array:
        """``(on, min_still_samples, sigma_zaru^2, sigma_bias_rw^2)`` as :func:`zaru_update` reads them."""
        return np.array([float(self.zaru), float(max(1, int(round(self.zaru_min_still_s * rate_hz)))),
                         self.sigma_zaru**2, self.sigma_bias_rw**2])

    def hde_params(self) -> Array:
        """Parameters of the drift elimination as the kernel reads them (see :func:`pdr.foot.drift.drift_update`)."""
        return np.array([float(self.hde_directions), self.hde_sigma_dir**2, self.hde_max_dev, self.hde_straight_tol,
                         float(self.hde_min_strides), self.hde_min_stride_m, self.sigma_heading_rw**2,
                         self.sigma_drift_rw**2])


@dataclass(frozen=True)
class Segmentation:
    """Recursive step segmentation of Algorithm 1 (seed 001 eqs. 9-10).

    Attributes
    ----------
    gamma_p
        Threshold on the velocity variance ``P_vx`` (m^2/s^2) for a pending reset (eq. 9).
    c_min_s
        Minimum time between resets, s (``c_min`` of eq. 9).
    c_max_s
        Maximum time a reset may stay pending, s (``c_max`` of eq. 10): a reset happens at the end of a
        stance or after this long in a long stationary period.
    """

    gamma_p: float = 1e-4
    c_min_s: float = 0.3
    c_max_s: float = 2.0


@dataclass(frozen=True)
class ZuptTrack:
    """Output of the ZUPT-aided INS, one row per IMU sample.

    Attributes
    ----------
    t_s
        (N,) sample times, s.
    pos_n
        (N, 3) position, m, ENU (start at the origin). With segmentation: the step-wise dead-reckoned
        position ``x_l + R(chi_l) p_k``.
    vel_n
        (N, 3) velocity, m/s, ENU.
    q_nb
        (N, 4) attitude.
    zero_velocity
        (N,) the detector flags used as ZUPTs.
    pos_var
        (N, 3) variances of the position (m^2) of the local filter (since the last reset with
        segmentation).
    vel_var
        (N, 3) variances of the velocity, m^2/s^2.
    att_var
        (N, 3) variances of the attitude error (roll, pitch, yaw about the ENU axes), rad^2.
    steps
        Step increments (only with segmentation).
    start_index
        First sample that was navigated (the coarse initialisation needs a stationary start).
    warnings
        Problems found in the input (start in motion, saturation, gaps).
    gyro_bias
        (3,) gyroscope bias estimated by the zero angular-rate updates at the end, rad/s, sensor frame (zeros
        without ``ZuptConfig.zaru``).
    """

    t_s: Array
    pos_n: Array
    vel_n: Array
    q_nb: Array
    zero_velocity: BoolArray
    pos_var: Array
    vel_var: Array
    att_var: Array
    steps: tuple[StepIncrement, ...] = ()
    start_index: int = 0
    warnings: tuple[str, ...] = field(default_factory=tuple)
    gyro_bias: Array = field(default_factory=lambda: np.zeros(3))

    @property
    def yaw(self) -> Array:
        """(N,) yaw in rad, counter-clockwise from east."""
        return quat.to_euler(self.q_nb)[2]


def check_imu(t_s: ArrayLike, acc_b: ArrayLike, gyro_b: ArrayLike) -> tuple[Array, Array, Array]:
    """Validate IMU arrays: (N,) strictly increasing finite times and (N, 3) finite samples."""
    t = np.asarray(t_s, dtype=np.float64)
    f = np.asarray(acc_b, dtype=np.float64)
    w = np.asarray(gyro_b, dtype=np.float64)
    if t.ndim != 1 or t.size < 2:
        raise InputError("need at least two samples", field="t_s")
    for name, arr in (("acc_b", f), ("gyro_b", w)):
        if arr.shape != (t.size, 3):
            raise InputError(f"expected shape ({t.size}, 3), got {arr.shape}", field=name)
        if not np.all(np.isfinite(arr)):
            raise InputError(f"sample {int(np.argmax(~np.all(np.isfinite(arr), axis=1)))} is not finite",
                             field=name)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputError("time must be finite and strictly increasing", field="t_s")
    return t, f, w


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


def init_lengths(rate_hz: float, init_window_s: float) -> tuple[int, int]:
    """Samples of the shortest stationary run that may initialise (0.1 s, at least 3) and of the window averaged."""
    min_len = max(3, int(round(0.1 * rate_hz)))
    return min_len, max(min_len, int(round(init_window_s * rate_hz)))


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


@njit(cache=True)
def mechanize(p: Array, v: Array, q: Array, f0_b: Array, w0_b: Array, f_b: Array, w_b: Array, dt: float,
              g_n: Array) -> Array:  # pragma: no cover - compiled
    """Second-order strapdown step (eq. 1 as :mod:`pdr.strapdown`) in place; returns the mean specific force f_n.

    ``f0_b, w0_b`` are the samples at the start of the interval, ``f_b, w_b`` at its end: two-sample rotation
    vector (trapezoid + coning term), acceleration integrated as varying linearly between the two ends.
    """
    theta = np.empty(3)
    theta[0] = 0.5 * (w0_b[0] + w_b[0]) * dt + (w0_b[1] * w_b[2] - w0_b[2] * w_b[1]) * dt * dt / 12.0
    theta[1] = 0.5 * (w0_b[1] + w_b[1]) * dt + (w0_b[2] * w_b[0] - w0_b[0] * w_b[2]) * dt * dt / 12.0
    theta[2] = 0.5 * (w0_b[2] + w_b[2]) * dt + (w0_b[0] * w_b[1] - w0_b[1] * w_b[0]) * dt * dt / 12.0
    c0 = rotmat(q)
    q1 = quat_mul(q, quat_exp(theta))
    c1 = rotmat(q1)
    f_n = np.empty(3)
    for i in range(3):
        f0 = c0[i, 0] * f0_b[0] + c0[i, 1] * f0_b[1] + c0[i, 2] * f0_b[2]
        f1 = c1[i, 0] * f_b[0] + c1[i, 1] * f_b[1] + c1[i, 2] * f_b[2]
        a0 = f0 + g_n[i]
        a1 = f1 + g_n[i]
        p[i] += v[i] * dt + (a0 / 3.0 + a1 / 6.0) * dt * dt
        v[i] += 0.5 * (a0 + a1) * dt
        f_n[i] = 0.5 * (f0 + f1)
    q[:] = q1
    return f_n


@njit(cache=True)
def error_transition(f_n: Array, dt: float) -> Array:  # pragma: no cover - compiled
    """Transition matrix of the 9 error states (eq. 2) over ``dt`` with specific force ``f_n``."""
    F = np.eye(9)
    for i in range(3):
        F[i, 3 + i] = dt
    # -[f_n]x dt: attitude error (true = exp(dtheta) est) to velocity error.
    F[3, 7] = f_n[2] * dt
    F[3, 8] = -f_n[1] * dt
    F[4, 6] = -f_n[2] * dt
    F[4, 8] = f_n[0] * dt
    F[5, 6] = f_n[1] * dt
    F[5, 7] = -f_n[0] * dt
    return F


@njit(cache=True)
def zupt_predict(p: Array, v: Array, q: Array, P: Array, f0_b: Array, w0_b: Array, f_b: Array, w_b: Array,
                 dt: float, g_n: Array, qa: float, qg: float) -> Array:  # pragma: no cover - compiled
    """Mechanization (eq. 1) and covariance propagation (eq. 2) in place; returns the specific force f_n."""
    f_n = mechanize(p, v, q, f0_b, w0_b, f_b, w_b, dt, g_n)
    propagate_covariance(P, error_transition(f_n, dt), dt, qa, qg)
    return f_n


@njit(cache=True)
def propagate_covariance(P: Array, F: Array, dt: float, qa: float, qg: float) -> None:  # pragma: no cover
    """``P := F P F^T + Q`` in place (eq. 2), white velocity noise ``qa dt^2`` and attitude noise ``qg dt^2``.

    Plain loops that skip the zeros of ``F`` (18 of its 81 entries are non-zero): cheaper than two BLAS calls.
    """
    FP = np.zeros((9, 9))
    for i in range(9):
        for k in range(9):
            f = F[i, k]
            if f != 0.0:
                for j in range(9):
                    FP[i, j] += f * P[k, j]
    for i in range(9):
        for j in range(9):
            acc = 0.0
            for k in range(9):
                f = F[j, k]
                if f != 0.0:
                    acc += FP[i, k] * f
            P[i, j] = acc
    for i in range(3):
        P[3 + i, 3 + i] += qa * dt * dt
        P[6 + i, 6 + i] += qg * dt * dt


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def zupt_smooth_kernel(t: Array, first: int, qa: float, qg: float, sm_P: Array, sm_fn: Array, sm_dx: Array,
                       pos: Array, vel: Array, qs: Array, pvar: Array, vvar: Array, avar: Array,
                       e_next: Array) -> None:  # pragma: no cover - compiled
    """RTS backward pass of the error-state filter (:mod:`pdr.filters.rts`) over samples ``first - 1..N-1``.

    ``F`` and the predicted covariance ``P_k+1|k = F P_k|k F^T + Q`` are rebuilt from the stored specific
    force instead of being stored. The smoothed errors correct ``pos, vel, qs`` in place as eq. 5 does
    (``q := exp(dtheta) q``); ``sm_P`` is overwritten by the smoothed covariances and ``pvar, vvar, avar`` by
    their diagonals. Without segmentation only (a reset of Algorithm 1 makes ``P_k+1|k`` singular).
    The last sample is taken as smoothed already: its smoothed error is ``e_next`` (zeros at the end of a
    recording) and its smoothed covariance ``sm_P[N-1]``; on return ``e_next`` holds the smoothed error of
    sample ``first - 1``, so that a recording can be smoothed segment by segment, last segment first.
    """
    n = t.size
    e = np.zeros(9)
    zero = np.zeros(9)
    for k in range(n - 2, first - 2, -1):
        dt = t[k + 1] - t[k]
        F = error_transition(sm_fn[k + 1], dt)
        Pp = sm_P[k].copy()
        propagate_covariance(Pp, F, dt, qa, qg)
        rts_step(zero, sm_P[k], F, -sm_dx[k + 1], Pp, e_next, sm_P[k + 1], e, sm_P[k])
        for i in range(3):
            pos[k, i] += e[i]
            vel[k, i] += e[3 + i]
        qk = quat_mul(quat_exp(e[6:9]), qs[k])
        qs[k] = qk / math.sqrt(qk[0] ** 2 + qk[1] ** 2 + qk[2] ** 2 + qk[3] ** 2)
        for i in range(3):
            pvar[k, i] = sm_P[k, i, i]
            vvar[k, i] = sm_P[k, 3 + i, 3 + i]
            avar[k, i] = sm_P[k, 6 + i, 6 + i]
        e_next[:] = e


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


def _filter(t: Array, f_b: Array, w_b: Array, zv: BoolArray, flags: BoolArray, rows: slice, first: int,
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


def run_kernel(t: Array, f_b: Array, w_b: Array, zv: BoolArray, first: int, state: FilterState,
               config: ZuptConfig, setup: KernelSetup, smooth: bool = False,
               still: BoolArray | None = None, segment: int = SMOOTHER_SEGMENT) -> KernelOutput:
    """Run the filter loop over samples ``first..N-1`` of contiguous arrays, updating ``state`` in place.

    ``still`` (N,) flags the samples whose SHOE statistic is below ``config.zaru_threshold`` (needed with
    ``config.zaru``; :func:`pdr.foot.detectors.still_samples`).

    With ``smooth`` (offline, without segmentation) the RTS backward pass then replaces the per-sample outputs
    from ``first - 1`` on by the smoothed ones; ``state`` stays the causal filter's. The smoother is
    checkpointed: the filter runs once, keeping its state at the start of every ``segment`` samples; then,
    last segment first, each segment is filtered again from its checkpoint, storing what the backward pass needs,
    and smoothed. The result is the same to the bit as one pass over stored covariances, at the cost of a second
    filter pass and with memory for one segment instead of the recording.
    """
    if smooth and setup.seg_on:
        raise InputError("the RTS smoother works without step segmentation only", field="smoother")
    if segment < 2:
        raise InputError(f"must be at least 2, got {segment}", field="segment")
    n = t.size
    max_steps = n // max(1, setup.c_min) + 2 if setup.seg_on else 1
    out = KernelOutput(np.zeros((n, 3)), np.zeros((n, 3)), np.tile(state.q, (n, 1)), np.zeros((n, 3)),
                       np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(max_steps, dtype=np.int64),
                       np.zeros((max_steps, 3)), np.zeros(max_steps), np.zeros((max_steps, 4, 4)))
    if config.zaru and (still is None or still.shape != t.shape):
        raise InputError("the zero angular-rate update needs the still flags of every sample", field="still")
    flags = np.ascontiguousarray(still if config.zaru and still is not None else np.zeros(0, dtype=bool))
    nothing = (np.zeros((0, 9, 9)), np.zeros((0, 3)), np.zeros((0, 9)))
    if not smooth:
        n_steps = _filter(t, f_b, w_b, zv, flags, slice(0, n), first, state, config, setup, out, nothing)
        return replace(out, step_idx=out.step_idx[:n_steps], step_dp=out.step_dp[:n_steps],
                       step_dpsi=out.step_dpsi[:n_steps], step_cov=out.step_cov[:n_steps])
    starts = list(range(first, n, segment))
    checkpoints = []
    for a in starts:
        checkpoints.append(state.copy())
        _filter(t, f_b, w_b, zv, flags, slice(a - 1, min(a + segment, n)), 1, state, config, setup, out, nothing)
    _smooth_segments(t, f_b, w_b, zv, flags, starts, checkpoints, segment, config, setup, out)
    return replace(out, step_idx=out.step_idx[:0], step_dp=out.step_dp[:0], step_dpsi=out.step_dpsi[:0],
                   step_cov=out.step_cov[:0])


def _smooth_segments(t: Array, f_b: Array, w_b: Array, zv: BoolArray, flags: BoolArray, starts: list[int],
                     checkpoints: list[FilterState], segment: int, config: ZuptConfig, setup: KernelSetup,
                     out: KernelOutput) -> None:
    """Backward pass of :func:`run_kernel`, segment by segment from the last; ``out`` holds the filtered track."""
    n = t.size
    e_next = np.zeros(9)
    p_end: Array | None = None
    per_sample = (out.pos, out.vel, out.qs, out.pvar, out.vvar, out.avar)
    for a, checkpoint in zip(reversed(starts), reversed(checkpoints), strict=True):
        b = min(a + segment, n)
        rows = slice(a - 1, b)
        m = b - a + 1
        store = (np.zeros((m, 9, 9)), np.zeros((m, 3)), np.zeros((m, 9)))
        # The segment's last sample was smoothed with the next segment: filtering again must not overwrite it.
        kept = [arr[b - 1].copy() for arr in per_sample]
        _filter(t, f_b, w_b, zv, flags, rows, 1, checkpoint.copy(), config, setup, out, store)
        for arr, row in zip(per_sample, kept, strict=True):
            arr[b - 1] = row
        if p_end is not None:
            store[0][m - 1] = p_end
        zupt_smooth_kernel(t[rows], 1, config.sigma_acc**2, config.sigma_gyro**2, *store, out.pos[rows],
                           out.vel[rows], out.qs[rows], out.pvar[rows], out.vvar[rows], out.avar[rows], e_next)
        p_end = store[0][0].copy()


def run_zupt(t_s: ArrayLike, acc_b: ArrayLike, gyro_b: ArrayLike, zero_velocity: ArrayLike,
             config: ZuptConfig | None = None, segmentation: Segmentation | None = None,
             rate_hz: float | None = None, smooth: bool = False, segment: int = SMOOTHER_SEGMENT) -> ZuptTrack:
    """Run the ZUPT-aided INS over a recording (seed 001 eqs. 1-5; Algorithm 1 with ``segmentation``).

    Parameters
    ----------
    t_s
        (N,) strictly increasing sample times, s.
    acc_b
        (N, 3) specific force including gravity, m/s^2, sensor frame.
    gyro_b
        (N, 3) angular rate, rad/s, sensor frame.
    zero_velocity
        (N,) bool zero-velocity flags (from :func:`pdr.foot.detectors.detect`).
    config
        Noise model.
    segmentation
        When given, perform the step-wise inertial navigation resets and step-wise dead reckoning.
    rate_hz
        Sampling rate that sets the sample counts of the initialisation and of Algorithm 1, Hz (default: from
        the median sample interval).
    smooth
        Offline only: replace the filtered track by the RTS-smoothed one (:func:`zupt_smooth_kernel`, the
        error-state form of :mod:`pdr.filters.rts`); not with ``segmentation``. Checkpointed in segments of
        ``segment`` samples (:func:`run_kernel`): the stored covariances take the memory of one segment.

    Returns
    -------
    The track; samples before the first stationary period keep the initial state.
    """
    cfg = config or ZuptConfig()
    t, f_b, w_b = check_imu(t_s, acc_b, gyro_b)
    f_b = np.ascontiguousarray(f_b)
    w_b = np.ascontiguousarray(w_b)
    zv = np.asarray(zero_velocity, dtype=bool)
    if zv.shape != t.shape:
        raise InputError(f"expected shape {t.shape}, got {zv.shape}", field="zero_velocity")
    rate = 1.0 / float(np.median(np.diff(t))) if rate_hz is None else float(rate_hz)
    setup = kernel_setup(rate, cfg, segmentation)
    warnings: list[str] = []

    a, q0, warning = coarse_start(t, f_b, zv, rate, cfg.init_window_s, cfg.yaw0)
    if warning:
        warnings.append(warning)

    state = FilterState.initial(q0, cfg)
    still = still_samples(f_b, w_b, rate, cfg.zaru_threshold) if cfg.zaru else None
    out = run_kernel(t, f_b, w_b, zv, a + 1, state, cfg, setup, smooth=smooth, still=still, segment=segment)
    if smooth:
        # Samples before navigation starts take the smoothed state of its first sample.
        for arr in (out.pos, out.vel, out.qs, out.pvar, out.vvar, out.avar):
            arr[:a] = arr[a]
    else:
        out.vvar[: a + 1] = cfg.init_sigma_vel**2
        out.avar[: a + 1] = np.diag(FilterState.initial(q0, cfg).P)[ATT]
    steps = tuple(StepIncrement(float(t[k]), int(k), dp.copy(), float(dpsi), cov.copy())
                  for k, dp, dpsi, cov in zip(out.step_idx, out.step_dp, out.step_dpsi, out.step_cov, strict=True))
    return ZuptTrack(t, out.pos, out.vel, quat.normalize(out.qs), zv, out.pvar, out.vvar, out.avar, steps, a,
                     tuple(warnings), state.bias.copy())


#: A first stationary period later than this into the recording (s) is reported: the motion before it is lost.
LATE_START_S = 0.1


def late_start_warning(start_index: int, start_s: float, rate_hz: float) -> str:
    """The warning for a first stationary period more than :data:`LATE_START_S` into the recording ('' otherwise)."""
    if start_index > int(round(LATE_START_S * rate_hz)):
        return (f"recording starts in motion: first stationary period at {start_s:.2f} s; "
                "navigation starts there and the motion before it is not tracked")
    return ""
