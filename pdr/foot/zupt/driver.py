"""The ZUPT-aided INS over a recording: input checks, :func:`run_kernel` (filter, optionally the checkpointed
smoother) and :func:`run_zupt` with its output :class:`ZuptTrack`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.filters.rotation_kernels import yaw_of
from pdr.foot.detectors import still_samples
from pdr.foot.strides import reset_strides
from pdr.foot.zupt.config import Segmentation, ZuptConfig
from pdr.foot.zupt.initialisation import coarse_start
from pdr.foot.zupt.kernel import FilterState, KernelOutput, KernelSetup, filter_rows, kernel_setup
from pdr.foot.zupt.mechanisation import ATT
from pdr.foot.zupt.smoother import SMOOTHER_SEGMENT, smooth_segments
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


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
        Step increments (only with segmentation): one per reset, and one at the last sample when the recording
        ends a stride that no reset closed (:func:`closing_step`). Each says whether it closes a stride
        (:func:`pdr.foot.strides.reset_strides`; :attr:`step_strides` lists them): False for a reset while the foot
        stands.
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
    def step_strides(self) -> tuple[bool, ...]:
        """Per step, whether it closes a stride (:attr:`pdr.step_increment.StepIncrement.stride`)."""
        return tuple(s.stride for s in self.steps)

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
        n_steps = filter_rows(t, f_b, w_b, zv, flags, slice(0, n), first, state, config, setup, out, nothing)
        return replace(out, step_idx=out.step_idx[:n_steps], step_dp=out.step_dp[:n_steps],
                       step_dpsi=out.step_dpsi[:n_steps], step_cov=out.step_cov[:n_steps])
    starts = list(range(first, n, segment))
    checkpoints = []
    for a in starts:
        checkpoints.append(state.copy())
        filter_rows(t, f_b, w_b, zv, flags, slice(a - 1, min(a + segment, n)), 1, state, config, setup, out, nothing)
    smooth_segments(t, f_b, w_b, zv, flags, starts, checkpoints, segment, config, setup, out)
    return replace(out, step_idx=out.step_idx[:0], step_dp=out.step_dp[:0], step_dpsi=out.step_dpsi[:0],
                   step_cov=out.step_cov[:0])


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
    strides, open_stride = reset_strides(zv, t, a, out.step_idx) if setup.seg_on else ([], False)
    steps = [StepIncrement(float(t[k]), int(k), dp.copy(), float(dpsi), cov.copy(), stride)
             for k, dp, dpsi, cov, stride in zip(out.step_idx, out.step_dp, out.step_dpsi, out.step_cov, strides,
                                                 strict=True)]
    if open_stride:
        steps.append(closing_step(state, float(t[-1]), t.size - 1))
    return ZuptTrack(t, out.pos, out.vel, quat.normalize(out.qs), zv, out.pvar, out.vvar, out.avar, tuple(steps), a,
                     tuple(warnings), state.bias.copy())


#: Rows and columns of the filter covariance a step increment carries: position and yaw (eq. 8), as the reset of
#: :func:`pdr.foot.zupt.kernel.zupt_kernel` records them.
STEP_COV_ROWS = np.array([0, 1, 2, 8])


def closing_step(state: FilterState, t_s: float, index: int) -> StepIncrement:
    """The step increment (eqs. 7-8) a reset at sample ``index`` (time ``t_s``, s) would record, ``state`` left as
    it is: the end of a recording closes a stride that ended after the last reset (the foot came to rest within
    ``c_max_s`` of the end, so Algorithm 1 made no reset after it; :func:`pdr.foot.strides.reset_strides`).
    """
    return StepIncrement(float(t_s), int(index), state.p.copy(), float(yaw_of(state.q)),
                         state.P[np.ix_(STEP_COV_ROWS, STEP_COV_ROWS)].copy())
