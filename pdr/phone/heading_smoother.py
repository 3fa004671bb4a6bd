"""Offline smoothing of a finished phone track's step headings: gyro yaw plus a bias learnt from the magnetometer.

Why
    The causal hand-held/torso heading follows the magnetometer-referenced device yaw within seconds (the
    attitude UKF's yaw noise is large there, :attr:`pdr.phone.pipeline.PipelineConfig.device_heading_sigma_gyro`), so a
    building's steel deflects it by 10-25 degrees over whole corridors. The gyro alone keeps the shape of a route
    to a few degrees once its bias about the vertical is known, but that bias (tenths of a deg/s on the IPIN 2023
    phones, more on some walks; the stationary estimate of :mod:`pdr.phone.attitude` is missing when the user
    never stands still; each step event carries it as ``gyro_bias_dps``) turns it by tens of degrees within
    minutes, and a causal filter cannot tell
    the bias from a deflection until minutes of magnetometer data have passed (a causal version of this model,
    tried on the IPIN walks, was worse than the magnetometer heading). Once the whole walk is known, a
    fixed-interval smoother can: the magnetometer's deflections vary from place to place, the bias does not.

Model (per step ``k`` at time ``t_k``, yaw in rad counter-clockwise from east)
    ``psi_k = g_k + d_k`` where ``g_k`` is the gyro yaw of the step (:class:`pdr.phone.pipeline.PdrPipeline`
    integrates the gyro's rate about the vertical; its origin is arbitrary) and the state ``x = (d, beta)`` is the
    offset of the gyro yaw and its drift rate (the gyro bias about the vertical, rad/s):

    - transition ``d_k = d_{k-1} + beta_{k-1} dt + w_d``, ``beta_k = beta_{k-1} + w_beta``: a random walk of the offset
      (``heading_rw_deg`` per sqrt(s): gyro noise, the device turning in the hand) and an integrated random walk of
      the bias (``bias_rw_deg`` deg/s per sqrt(s)), with the exact discrete covariance of the integrated walk;
    - measurement ``z_k = wrap(m_k - g_k) = d_k + v_k`` (plus the turn lag, "Turns" below): ``m_k`` is the causal
      step heading before the drift elimination (magnetometer-referenced device heading), ``v_k`` with standard
      deviation ``sigma_mag_deg`` (a deflection, not sensor noise); a step whose heading a site landmark set keeps
      that landmark's sigma.

    A Kalman filter forward and the Rauch-Tung-Striebel recursion backward give ``d_k`` from all steps; the
    smoothed heading is ``g_k + d_k`` (plus the gyro's share of the turn lag, "Turns").

    Stationary bias: when the user stood still at some time in the walk, the attitude filter measured the gyro bias
    ``b`` (device frame, :mod:`pdr.phone.attitude`), and the step events carry it (``gyro_bias_dps``) with the
    device-frame up direction integrated over the walk (``up_time_s``). The bias added ``up_time_s . b`` to the gyro
    yaw; the walk's last estimate is removed from ``g_k`` first and ``beta`` is then only what is left of it, with a
    prior of ``stationary_bias_sigma_deg`` instead of ``bias_sigma_deg``. Without it the magnetometer has to teach the
    bias, and a deflection that changes steadily along a route, or a walk too short for its deflections to average
    out, passes for one. The drift elimination of the causal track (its dominant directions are learnt
    from the deflected headings) is not applied: measured on the IPIN 2023 hand-held walks it only adds back the
    deflection the smoother removed.

Model checks (:func:`smooth_track`)
    The model assumes a gyro whose residual bias is small once the stationary estimate is removed, and measured
    offsets ``z_k`` that scatter about a slowly moving ``d`` by deflections of ``sigma_mag_deg``. Both are tested on
    the plain forward filter's innovations ``nu_k`` and their variances ``S_k`` (:func:`check_model`), with the
    steps within ``deflection_corr_s`` counted as one measurement (a deflection stays while the walker crosses it):

    - **Stationary bias**: a likelihood-ratio test of the stationary prior (``stationary_bias_sigma_deg``) against
      the wide one (``bias_sigma_deg``). Above the chi-square (1 degree of freedom) quantile at
      ``consistency_p``, the magnetometer contradicts the stationary estimate (an attitude filter that learnt a
      wrong bias while the user stood, or a bias that changed since), and the bias is learnt from the
      magnetometer as on a walk without a stationary estimate. On a turning-rich walk this matters most: a
      turn makes the vertical axis sweep the device frame, so a wrong bias vector turns the gyro yaw by a
      different amount on every leg, and no short straight stretch shows it.
    - **Innovation consistency**: the sum of ``nu_k^2 / S_k`` against its chi-square bound is reported in the
      summary. It is not acted upon: on the Tyrex motion-capture walks it flags a few walks (pocket walks among
      them), and on each the smoothed heading beats the causal one (``pdr eval heading`` prints both per
      recording), so falling back to the causal heading there was worse. The pocket measurement (RMPCA, lagging
      through turns) is not the model's
      white deflection, and the robust reweighting already handles it.

Turns (the model without long straight legs)
    The offset ``d`` is the phone's yaw relative to the walking direction, constant along a straight leg. Through a
    turn it is not: the body segment the phone rides on turns ahead of the path (measured with the motion-capture
    truth on the tuning walker of ``pdr eval heading``: a back-pocket phone's yaw leads the walking direction by
    0.23-0.26 s), and the causal measurement ``m_k`` lags it by the filter behind it (a front pocket's walking line
    0.34-0.42 s). Both are time shifts, so to first order they add ``delta w_k`` to ``z_k``, where ``w_k`` is the
    gyro yaw's turn rate at the step (:func:`turn_rate`, rad/s) and ``delta`` (s) the sum of the two lags. The model
    carries ``delta`` as a third state, constant over the walk, with the measurement
    ``z_k = d_k + w_k delta + v_k``. On long straight legs ``w_k`` is near zero and ``delta`` stays at its prior
    (the straight-leg model); on a walk that loops in a small room it is learnt from every turn.

    Only the sum is observable from ``m - g``: a gyro that leads and a measurement that lags look alike (on the
    motion-capture pocket walks the estimated sum is 0.2-0.45 s in both pockets, though the gyro is the one that
    leads in a back pocket and the measurement the one that lags in a front pocket). With prior spreads
    ``gyro_lag_sigma_s`` and ``measured_lag_sigma_s`` for the two parts (their root mean squares over the tuning
    walker's pocket and swinging-hand recordings, 0.16 and 0.25 s, each lag the slope of a least-squares fit of
    the mocap walking direction minus ``g``, or ``m`` minus it, against ``w``; the texting walks left out, where
    ``m`` is the device's own yaw and the two lags are one), the posterior mean of the gyro's part is the share
    ``gyro_lag_sigma_s^2 / (gyro_lag_sigma_s^2 + measured_lag_sigma_s^2)`` of ``delta``, and the smoothed heading
    is ``g_k + d_k + share w_k delta``; its variance adds the part of the split the data cannot decide.

    A trouser pocket tells the split itself: which side of the thigh the phone is on
    (:class:`pdr.phone.walking_direction.PocketSide`, carried by each walking pocket step as ``pocket_side``). A back
    pocket sits on the buttock, which turns with the pelvis ahead of the path, while its measured walking line has
    no lag (the causal heading's error against the true turn rate: slopes -0.07 to +0.06 s on the benchmark's four
    back-pocket walks); a front pocket sits on the thigh, whose measured line lags (-0.16 to -0.23 s) and whose yaw
    does not lead (with the prior share its smoothed slope was still -0.09 and -0.10 s on the tuning walker). So
    the gyro takes the whole lag behind the thigh and none of it in front (:meth:`HeadingSmootherConfig.
    step_lag_shares`), moving from the prior share as the side evidence grows. Smoothed mean error
    (``pdr eval heading``), tuning walker: back pockets 8.5 and 8.3 -> 5.1 and 7.1 deg, front 6.2 and 7.3 -> 5.9 and
    7.1; the other walker: back 12.8 and 5.3 -> 12.1 and 4.0, front 16.3 and 8.5 -> 17.1 and 8.5 (its disturbed
    pair's side evidence is near zero); the simulated pocket walks 11.8 -> 12.0 deg (``pdr eval pocket-heading``;
    the simulator's pocket has no pelvis lead). The summary
    line reports ``delta`` and its standard deviation: a lag many standard deviations from zero says that the
    straight-leg model would not have held.

Limbs (the gyro yaw over a stride)
    A phone in a trouser pocket or a swinging hand turns about the vertical with the limb, forth and back once per
    stride, and ``g_k`` is its mean over one step: half a stride, the forward swing on one step and the backward
    swing on the next. So ``g_k`` alternates from step to step about the direction of the stride, by up to tens of
    degrees in a swinging hand, while the measured direction ``m_k`` is read from the limb's motion over a whole
    stride and does not. For these placements the smoother takes, per step, the gyro yaw over the stride centred
    on it (:func:`stride_mean_yaw`): the step itself and the neighbouring halves of the steps before and after, in
    which the limb's swing cancels. A hand-held or torso phone's yaw and its measured device heading swing
    together, so there ``g_k`` is kept: averaging only ``g`` would put the swing into ``m - g``. Smoothed mean error
    on the motion-capture benchmark (``pdr eval heading``, all recordings, automatic placement): 11.54 -> 11.18
    deg (tuning walker 10.72 -> 10.53, the other 12.33 -> 11.79); swinging hand 19.2, 23.6, 27.9, 20.3 -> 18.7,
    23.4, 28.2, 16.1 deg. Averaging the hand-held IPIN walks' ``g`` too raised their smoothed landmark p75 from 3.07
    to 3.36 m (``pdr eval ipin``).

Track
    Positions are re-integrated with the causal step lengths,
    ``p_k = p_k^causal + sum_j L_j (u(psi_j) - u(psi_j^causal))`` over the steps since the last position fix (a site
    landmark), so fixes and floors stay as they were (:func:`pdr.phone.track.redo_steps`).

Figures: ``pdr eval ipin /work/shared/data/ipin2023_t3/logfiles --placement hand`` scores the causal and the
smoothed tracks side by side (landmark median and p75, absolute and with the first segment aligned). The parameters
were chosen on the repetition-01 files, where the landmark p75 is flat over a wide range of ``sigma_mag_deg``, either
random walk and the bias prior (not tuned to a point), and checked on the held-out repetition-02 files; the
stationary bias prior is the one setting the repetition-01 figure is sensitive to (the tighter, the better, down to
0.01 deg/s). What is left is mostly the deflection averaged over a whole walk (about 18 deg on both walks of one
IPIN trial), which no magnetometer-referenced heading can see.

Tried and not adopted: the local field as the measurement, ``m_k`` replaced by the step heading turned by the field's
yaw innovation over the step (the field's azimuth in the attitude's frame against north, at the samples whose field
rows the filter used), so that the causal filter's memory (a slowly converging start) stays out of ``z_k``. On the
motion-capture benchmark the smoothed mean went 11.2 -> 11.6 deg (a disturbed swinging walk 18.7 -> 12.0, a run
6.3 -> 11.1), on the IPIN walks 2.96 -> 3.91 m p75 (trial 03 8.97 -> 15.0 m). A hand-held trial-03 smoothed track
is worse than its causal one for another reason: :class:`pdr.phone.heading_stages.DeviceHeading`, "What limits it".

Trouser pocket: ``m_k`` is the pocket step's causal heading, the RMPCA walking direction (:mod:`pdr.phone.heading`),
and the gyro yaw is that of a device axis (:mod:`pdr.phone.gyro_yaw`; the vertical rate integrated directly would gain
the swinging thigh's geometric phase, 1-2 deg per stride). The offset is the phone's yaw in the pocket relative to the
walking direction, fixed while the phone stays put, so the smoother mostly removes the RMPCA's lag through turns; a
walk-long bias of the RMPCA direction stays: ``pdr eval pocket-heading --data /work/shared/data`` prints the simulated
pocket walks' causal and smoothed errors (the smoothed mean falls; the median, that walk-long bias, hardly moves).

The service streams the causal track; this smoother runs where the whole walk is at hand (``pdr track``, the
evaluations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.chi_square import chi2_quantile
from pdr.errors import InputError
from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import wrap_pi
from pdr.filters.rts import rts_smooth
from pdr.frames import heading_deg_to_yaw, wrap_angle
from pdr.phone.heading_stages import DEVICE_HEADING_PLACEMENTS, STRIDE_HEADING_PLACEMENTS
from pdr.phone.track import redo_steps

FloatArray = NDArray[np.float64]

#: Placements the smoother handles: hand-held and torso (the step heading is the device heading plus an offset),
#: trouser pocket and swinging hand (the step heading is the walking direction from the thigh's or arm's motion;
#: the phone's yaw keeps a fixed offset to it while it stays in the pocket or the hand's grip).
SMOOTHED_PLACEMENTS = DEVICE_HEADING_PLACEMENTS + STRIDE_HEADING_PLACEMENTS


@dataclass(frozen=True)
class HeadingSmootherConfig:
    """Noise of the smoother's model (module doc).

    Attributes
    ----------
    sigma_mag_deg
        Standard deviation of a step's magnetometer-referenced heading about the true one (deg).
    heading_rw_deg
        Random walk of the gyro yaw's offset (deg per sqrt(s)).
    bias_rw_deg
        Random walk of the gyro's residual bias about the vertical (deg/s per sqrt(s)).
    bias_sigma_deg
        Prior standard deviation of that bias at the first step (deg/s) when the walk has no stationary bias
        estimate (the user never stood still): the bias is then learnt from the magnetometer alone.
    stationary_bias_sigma_deg
        The same when the attitude filter estimated the gyro bias while the user stood (the step events'
        ``gyro_bias_dps``): the gyro yaw is corrected with the walk's last estimate and the smoother learns only
        what is left of it (deg/s).
    robust_k, iterations
        Robust reweighting (:func:`smooth_offsets`): a step's measurement variance is multiplied by
        ``1 + (residual / (robust_k sigma))^2`` (Cauchy weights) from the previous pass, over ``iterations``
        passes (1: plain smoother).
    jump_deg
        A change of ``m - g`` by more than this between consecutive steps (deg) restarts the offset: the phone
        was turned about a horizontal axis, which moves the device heading but not the rotation about the vertical
        (the IPIN walks' opening calibration motion). A deflection that changes by as much within one step is
        taken for the same: the bias is then learnt from the stretches between such places only. On the IPIN
        repetition-01 files the landmark p75 is flat from 20 to 30 deg, a little worse at 45 deg and several times
        worse without the restart (``pdr eval ipin`` with ``jump_deg`` changed).
    gyro_lag_sigma_s, measured_lag_sigma_s
        Prior spreads (s) of the two turn lags of the module doc's "Turns" model: how far the device's yaw leads
        the walking direction through a turn (the body segment the phone rides on), and how far the measured
        direction lags it (the causal filter behind it). Only their sum is observable, so the gyro's share of the
        estimated lag is ``gyro_lag_sigma_s^2 / (gyro_lag_sigma_s^2 + measured_lag_sigma_s^2)``.
    pocket_side_corr
        A trouser-pocket step's side evidence (the step event's ``pocket_side``, the stride correlation of forward
        and vertical specific force: :class:`pdr.phone.walking_direction.PocketSide`) at which the turn lag's split
        is taken as known (module doc, "Turns"): behind the thigh (at ``-pocket_side_corr`` or below) the gyro's
        share is 1, in front of it (``+pocket_side_corr`` or above) 0, and in between it moves linearly from the
        prior share at 0. 0.2 is the full lead weight of :class:`pdr.phone.walking_direction.PocketSide`.
    pocket_jump_deg
        ``jump_deg`` for trouser-pocket steps. Their measurement is the RMPCA walking direction, which lags through
        a turn by 30-60 deg for a step or two, so 20 deg would restart the offset at every turn; a phone turned
        round in the pocket still restarts it. On the simulated pocket walks (``pdr eval pocket-heading``, with this
        changed) the smoothed error falls as the threshold rises from 20 to 90 deg and stays from 90 to 180 deg.
    jump_window_steps, limb_jump_window_steps
        Steps on each side of a step over which a jump must hold (:func:`_offset_measurements`): the offset
        restarts where the circular mean of the next ``n`` steps' offsets differs from that of the previous ``n`` by
        more than the jump threshold. 1 (a held phone) compares consecutive steps. ``limb_jump_window_steps`` is
        used with ``pocket_jump_deg`` for trouser-pocket and swinging-hand walks: their measurement is read from the
        limb's motion stride by stride and is misread for a few strides at a time (on the motion-capture benchmark
        the swinging hand has runs of up to four steps 60-170 deg off, on every walk), which a one-step rule takes
        for the phone turned in the hand or pocket and restarts the offset at, twice per run; a regrip or the phone
        turned round in the pocket lasts. Swinging-hand smoothed error (``pdr eval heading``) with 1, 5, 8 and 12:
        tuning walker 21.5, 22.2, 20.9, 20.9 deg; the other walker 27.1, 26.5, 24.0, 24.0 (pocket walks unchanged).
    """

    sigma_mag_deg: float = 30.0
    heading_rw_deg: float = 0.1
    bias_rw_deg: float = 0.0057
    bias_sigma_deg: float = 2.0
    stationary_bias_sigma_deg: float = 0.02
    robust_k: float = 2.0
    jump_deg: float = 20.0
    pocket_jump_deg: float = 90.0
    jump_window_steps: int = 1
    limb_jump_window_steps: int = 8
    consistency_p: float = 0.01
    deflection_corr_s: float = 10.0
    gyro_lag_sigma_s: float = 0.16
    measured_lag_sigma_s: float = 0.25
    iterations: int = 4
    pocket_side_corr: float = 0.2

    @property
    def gyro_lag_share(self) -> float:
        """The gyro's share of an estimated turn lag (module doc "Turns")."""
        return self.gyro_lag_sigma_s ** 2 / (self.gyro_lag_sigma_s ** 2 + self.measured_lag_sigma_s ** 2)

    def step_lag_shares(self, pocket_side: list[float | None]) -> FloatArray:
        """(N,) the gyro's share of the turn lag per step, from each step's pocket side evidence (None: not a walking
        trouser-pocket stride, the prior share; ``pocket_side_corr``).
        """
        prior = self.gyro_lag_share
        side = np.array([math.nan if v is None else v for v in pocket_side], dtype=np.float64)
        decided = np.nan_to_num(np.minimum(np.abs(side) / self.pocket_side_corr, 1.0))     # 0 where unknown
        return prior + decided * (np.where(side < 0.0, 1.0, 0.0) - prior)

    def __post_init__(self) -> None:
        if not 0.0 < self.consistency_p < 1.0:
            raise InputError(f"consistency_p must lie in (0, 1), got {self.consistency_p}", field="consistency_p",
                             source="heading smoother")
        if self.jump_window_steps < 1 or self.limb_jump_window_steps < 1:
            raise InputError("jump_window_steps and limb_jump_window_steps must be >= 1", field="jump_window_steps",
                             source="heading smoother")
        if self.iterations < 1:
            raise InputError(f"iterations must be >= 1, got {self.iterations}", field="iterations",
                             source="heading smoother")
        for name in ("sigma_mag_deg", "heading_rw_deg", "bias_rw_deg", "bias_sigma_deg", "stationary_bias_sigma_deg",
                     "robust_k", "jump_deg", "pocket_jump_deg", "deflection_corr_s", "gyro_lag_sigma_s",
                     "measured_lag_sigma_s", "pocket_side_corr"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be a positive number, got {v}", field=name, source="heading smoother")


def _offset_measurements(t_s: FloatArray, gyro_yaw: FloatArray, meas_yaw: FloatArray, jump_deg: float,
                         window: int = 1) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Step times (s), the measured offsets ``z = wrap(m - g)`` (rad) and where the offset jumps by more than
    ``jump_deg`` (deg): the phone was turned about a horizontal axis (handled, turned over, put away), which moves
    its device heading but not the gyro's rotation about the vertical. A jump at step ``k`` compares the circular
    means of the offsets of steps ``k..k+window-1`` and ``k-window..k-1`` (fewer at the ends); ``window`` 1 compares
    consecutive steps.
    """
    t = np.asarray(t_s, dtype=np.float64)
    if np.any(np.diff(t) < 0):
        raise InputError("step times must be non-decreasing", field="t_s", source="heading smoother")
    z = np.asarray(wrap_angle(np.asarray(meas_yaw) - np.asarray(gyro_yaw)), dtype=np.float64)
    jump = np.zeros(t.size, dtype=bool)
    if window == 1:
        jump[1:] = np.abs(np.asarray(wrap_angle(np.diff(z)))) > math.radians(jump_deg)
        return t, z, jump
    csum = np.concatenate([[0.0], np.cumsum(np.exp(1j * z))])
    k = np.arange(1, t.size)
    before = csum[k] - csum[np.maximum(k - window, 0)]
    after = csum[np.minimum(k + window, t.size)] - csum[k]
    jump[1:] = np.abs(np.angle(after * np.conj(before))) > math.radians(jump_deg)
    return t, z, jump


def stride_mean_yaw(t_start_s: ArrayLike, t_end_s: ArrayLike, yaw: ArrayLike, limb: ArrayLike) -> FloatArray:
    """(N,) each step's yaw over the stride centred on it (rad, unwrapped; module doc "Limbs").

    ``t_start_s``, ``t_end_s`` (s) bound each step, ``yaw`` (rad) is a step's mean yaw, ``limb`` marks the steps to
    average. A marked step whose neighbours are both marked and adjacent (each begins within its own duration of the
    other's end: no stop between them) gets the mean of the three over the stride from the middle of the step before
    to the middle of the step after, each weighted by its share of that stride (1/4, 1/2, 1/4 for equal steps); any
    other step keeps its own yaw.
    """
    y = np.unwrap(np.asarray(yaw, dtype=np.float64))
    t0 = np.asarray(t_start_s, dtype=np.float64)
    t1 = np.asarray(t_end_s, dtype=np.float64)
    out = y.copy()
    if y.size < 3:
        return out
    limb = np.asarray(limb, dtype=bool)
    dur = t1 - t0
    gap = t0[1:] - t1[:-1]                          # gap[k]: from the end of step k to the start of step k + 1
    adjacent = (gap < dur[1:]) & (gap < dur[:-1])
    mid = np.flatnonzero(limb[1:-1] & limb[:-2] & limb[2:] & adjacent[:-1] & adjacent[1:]) + 1
    w = np.column_stack([0.5 * dur[mid - 1], dur[mid], 0.5 * dur[mid + 1]])
    out[mid] = np.sum(w * np.column_stack([y[mid - 1], y[mid], y[mid + 1]]), axis=1) / np.sum(w, axis=1)
    return out


def turn_rate(t_s: FloatArray, gyro_yaw: FloatArray) -> FloatArray:
    """(N,) turn rate of the gyro yaw at each step (rad/s): its central difference over the neighbouring steps
    (one-sided at the ends; zero for fewer than two steps or steps at the same time).
    """
    t = np.asarray(t_s, dtype=np.float64)
    g = np.unwrap(np.asarray(gyro_yaw, dtype=np.float64))
    w = np.zeros(t.size)
    if t.size < 2:
        return w
    lo = np.r_[0, np.arange(t.size - 2), t.size - 2]
    hi = np.r_[1, np.arange(2, t.size), t.size - 1]
    span = t[hi] - t[lo]
    ok = span > 0
    w[ok] = (g[hi] - g[lo])[ok] / span[ok]
    return w


@dataclass(frozen=True)
class SmoothedOffsets:
    """What :func:`smooth_offsets` learnt of a walk (module doc, "Model" and "Turns").

    Attributes
    ----------
    offset
        (N,) what is added to the gyro yaw to give the smoothed heading (rad): ``d_k`` plus the gyro's share of the
        turn lag times the turn rate.
    offset_sigma
        (N,) its standard deviation (rad), the unobservable split of the turn lag included.
    bias
        (N,) the residual gyro bias ``beta`` about the vertical (rad/s).
    turn_lag_s, turn_lag_sigma_s
        The turn lag ``delta`` of the measured direction behind the gyro yaw (s, positive: the measurement leads)
        and its standard deviation.
    """

    offset: FloatArray
    offset_sigma: FloatArray
    bias: FloatArray
    turn_lag_s: float
    turn_lag_sigma_s: float


def smooth_offsets(t_s: FloatArray, gyro_yaw: FloatArray, meas_yaw: FloatArray, meas_sigma: FloatArray,
                   config: HeadingSmootherConfig | None = None, bias_sigma_deg: float | None = None,
                   lag_share: FloatArray | None = None) -> SmoothedOffsets:
    """The smoothed offset of the gyro yaw, the residual bias and the turn lag of a walk (:class:`SmoothedOffsets`).

    ``t_s`` (s, non-decreasing), ``gyro_yaw`` and ``meas_yaw`` (rad) and ``meas_sigma`` (rad) have one value per
    step; ``bias_sigma_deg`` is the prior standard deviation of ``beta`` about zero (deg/s; default
    ``config.bias_sigma_deg``); ``lag_share`` (N,) the gyro's share of the turn lag per step (default
    ``config.gyro_lag_share`` for every step).
    Robust: the offset restarts where it jumps between steps (``config.jump_deg``, held over
    ``config.jump_window_steps``), and the smoother is rerun
    ``config.iterations`` times with each step's measurement variance inflated by its last residual, so steps whose
    device heading is not the walking direction lose their pull.
    """
    c = config or HeadingSmootherConfig()
    t, z, jump = _offset_measurements(t_s, gyro_yaw, meas_yaw, c.jump_deg, c.jump_window_steps)
    n = t.size
    if n == 0:
        return SmoothedOffsets(np.zeros(0), np.zeros(0), np.zeros(0), 0.0, _lag_sigma(c))
    w = turn_rate(t, np.asarray(gyro_yaw, dtype=np.float64))
    sigma = np.asarray(meas_sigma, dtype=np.float64)
    resid = np.zeros(n)
    bias_sigma = math.radians(c.bias_sigma_deg if bias_sigma_deg is None else bias_sigma_deg)
    for _ in range(c.iterations):
        r = sigma ** 2 * (1.0 + (resid / (c.robust_k * sigma)) ** 2)      # Cauchy weights
        xs, ps = _rts(t, z, r, w, jump, bias_sigma, c)
        resid = np.abs(np.asarray(wrap_angle(z - xs[:, 0] - w * xs[:, 2])))
    share = np.full(n, c.gyro_lag_share) if lag_share is None else np.asarray(lag_share, dtype=np.float64)
    # The gyro's lag is share * delta, plus what the data cannot split: its variance given the sum, share (1 - share)
    # times the sum's prior variance (with the prior share, gyro_lag_sigma_s^2 measured_lag_sigma_s^2 / their sum;
    # none once a pocket's side has decided the split).
    split_var = share * (1.0 - share) * _lag_sigma(c) ** 2
    var = ps[:, 0, 0] + 2.0 * share * w * ps[:, 0, 2] + w ** 2 * (share ** 2 * ps[:, 2, 2] + split_var)
    return SmoothedOffsets(offset=xs[:, 0] + share * w * xs[:, 2], offset_sigma=np.sqrt(np.maximum(var, 0.0)),
                           bias=xs[:, 1], turn_lag_s=float(xs[0, 2]),
                           turn_lag_sigma_s=float(math.sqrt(max(ps[0, 2, 2], 0.0))))


def _lag_sigma(c: HeadingSmootherConfig) -> float:
    """Prior standard deviation (s) of the observable turn lag, the sum of the gyro's and the measurement's."""
    return math.hypot(c.gyro_lag_sigma_s, c.measured_lag_sigma_s)


@dataclass(frozen=True)
class ModelCheck:
    """How well the smoother's model explains a walk's measured offsets (module doc "Model checks").

    Attributes
    ----------
    log_likelihood
        Log-likelihood of the offsets under the model: the plain forward filter's (no robust reweighting)
        Gaussian innovations ``nu_k`` with variances ``S_k = H P_k|k-1 H^T + R_k`` (rad^2), summed over ``dof``
        steps.
    nis
        Sum of the normalised innovation squares ``nu_k^2 / S_k`` over those steps: chi-square with ``dof``
        degrees of freedom when the model holds.
    dof
        Steps counted: all but the first and those where the offset restarts (a jump).
    """

    log_likelihood: float
    nis: float
    dof: int


def check_model(t_s: FloatArray, gyro_yaw: FloatArray, meas_yaw: FloatArray, meas_sigma: FloatArray,
                config: HeadingSmootherConfig | None = None, bias_sigma_deg: float | None = None) -> ModelCheck:
    """The innovations of the smoother's forward filter against their stated variances (:class:`ModelCheck`).

    Same arguments as :func:`smooth_offsets`; one plain forward pass with the stated measurement variances
    ``meas_sigma ** 2``.
    """
    c = config or HeadingSmootherConfig()
    t, z, jump = _offset_measurements(t_s, gyro_yaw, meas_yaw, c.jump_deg, c.jump_window_steps)
    n = t.size
    xf, pf = np.zeros((n, 3)), np.zeros((n, 3, 3))
    xp, pp = np.zeros((n, 3)), np.zeros((n, 3, 3))
    r = np.asarray(meas_sigma, dtype=np.float64) ** 2
    w = turn_rate(t, np.asarray(gyro_yaw, dtype=np.float64))
    bias_sigma = math.radians(c.bias_sigma_deg if bias_sigma_deg is None else bias_sigma_deg)
    if n:
        _forward(t, z, r, w, jump, bias_sigma ** 2, _lag_sigma(c) ** 2,
                 math.radians(c.heading_rw_deg) ** 2, math.radians(c.bias_rw_deg) ** 2, xf, pf, xp, pp)
    used = ~jump
    used[:1] = False
    nu = np.asarray(wrap_angle(z - xp[:, 0] - w * xp[:, 2]))[used]
    s = (pp[:, 0, 0] + 2.0 * w * pp[:, 0, 2] + w ** 2 * pp[:, 2, 2] + r)[used]
    nis = float(np.sum(nu ** 2 / s))
    return ModelCheck(log_likelihood=float(-0.5 * (np.sum(np.log(2.0 * math.pi * s)) + nis)), nis=nis,
                      dof=int(used.sum()))


def _rts(t: FloatArray, z: FloatArray, r: FloatArray, w: FloatArray, jump: NDArray[np.bool_], bias_sigma: float,
         c: HeadingSmootherConfig) -> tuple[FloatArray, FloatArray]:
    """One forward Kalman filter (:func:`_forward`) and the backward pass (:func:`pdr.filters.rts.rts_smooth`)
    of the module's model (``bias_sigma``: prior standard deviation of the bias, rad/s): the smoothed states
    ``(d, beta, delta)`` (N, 3) and their covariances (N, 3, 3).
    """
    n = t.size
    xf, pf = np.zeros((n, 3)), np.zeros((n, 3, 3))      # filtered
    xp, pp = np.zeros((n, 3)), np.zeros((n, 3, 3))      # predicted
    fs = np.tile(np.eye(3), (n, 1, 1))                  # fs[k]: transition from step k - 1 to k
    fs[1:, 0, 1] = np.diff(t)
    _forward(t, z, r, w, jump, bias_sigma ** 2, _lag_sigma(c) ** 2, math.radians(c.heading_rw_deg) ** 2,
             math.radians(c.bias_rw_deg) ** 2, xf, pf, xp, pp)
    return rts_smooth(xf, pf, xp, pp, fs)


@cached_njit()
def _forward(t: FloatArray, z: FloatArray, r: FloatArray, w: FloatArray, jump: NDArray[np.bool_], bias_var: float,
             lag_var: float, q_d: float, q_b: float, xf: FloatArray, pf: FloatArray, xp: FloatArray,
             pp: FloatArray) -> None:  # pragma: no cover - compiled
    """The forward filter of the offset ``d`` (rad), bias ``beta`` (rad/s) and turn lag ``delta`` (s), in place.

    Transition ``d_k = d_k-1 + dt beta_k-1`` with the integrated random walks ``q_b`` (bias, rad^2/s^3) and
    ``q_d`` (offset, rad^2/s), the offset's variance raised by pi^2 at a ``jump``; ``delta`` constant, prior
    variance ``lag_var`` (s^2). Measurement ``z_k = d_k + w_k delta`` (``w_k`` the gyro's turn rate, rad/s;
    wrapped innovation) with variance ``r_k`` (rad^2). Writes the predicted ``xp, pp`` and filtered ``xf, pf``
    means (K, 3) and covariances (K, 3, 3) that :func:`pdr.filters.rts.rts_smooth` takes. A compiled loop: the
    smoothed track of a 2-hour session (13 000 steps, four passes) is served on request.
    """
    x = np.zeros(3)
    x[0] = z[0]
    p = np.zeros((3, 3))
    p[0, 0], p[1, 1], p[2, 2] = r[0], bias_var, lag_var
    a = np.zeros((3, 3))
    ph = np.zeros(3)
    for k in range(t.size):
        if k:
            dt = t[k] - t[k - 1]
            x[0] += dt * x[1]
            # F P F^T + Q with F = I + dt e_0 e_1^T: row 0 gains dt * row 1, then column 0 gains dt * column 1.
            for j in range(3):
                a[0, j] = p[0, j] + dt * p[1, j]
                a[1, j] = p[1, j]
                a[2, j] = p[2, j]
            for i in range(3):
                p[i, 0] = a[i, 0] + dt * a[i, 1]
                p[i, 1] = a[i, 1]
                p[i, 2] = a[i, 2]
            p[0, 0] += q_b * dt ** 3 / 3.0 + q_d * dt + (math.pi ** 2 if jump[k] else 0.0)
            p[0, 1] += q_b * dt ** 2 / 2.0
            p[1, 0] += q_b * dt ** 2 / 2.0
            p[1, 1] += q_b * dt
        xp[k] = x
        pp[k] = p
        # H = [1, 0, w_k]
        for i in range(3):
            ph[i] = p[i, 0] + w[k] * p[i, 2]
        s = ph[0] + w[k] * ph[2] + r[k]
        innov = wrap_pi(z[k] - x[0] - w[k] * x[2])
        for i in range(3):
            x[i] += ph[i] / s * innov
        for i in range(3):
            for j in range(3):
                a[i, j] = p[i, j] - ph[i] * ph[j] / s
        for i in range(3):
            for j in range(3):
                p[i, j] = 0.5 * (a[i, j] + a[j, i])
        xf[k] = x
        pf[k] = p


def smooth_track(steps: list[dict[str, Any]], config: HeadingSmootherConfig | None = None
                 ) -> tuple[list[dict[str, Any]], str | None]:
    """Smoothed copies of a finished walk's step events (:mod:`pdr.phone.pipeline`) and a one-line summary.

    Steps of other placements, or without a gyro, are returned unchanged with the reason as the summary.
    The copies carry ``"smoothed": True``, the smoothed ``heading_deg`` and ``heading_sigma_deg`` and the
    re-integrated ``east_m``/``north_m``.
    """
    out = [dict(s) for s in steps]
    if not out:
        return out, None
    usable = [s.get("placement") in SMOOTHED_PLACEMENTS and s.get("gyro_heading_deg") is not None for s in out]
    if not all(usable):
        return out, ("heading not smoothed: the smoother needs a hand-held, torso or trouser-pocket phone with a "
                     f"gyroscope ({sum(usable)} of {len(out)} steps qualify)")
    c = config or HeadingSmootherConfig()
    if any(s.get("placement") in STRIDE_HEADING_PLACEMENTS for s in out):
        # A swinging phone's step heading (thigh or arm) jumps more than a held one's; a walk whose placement
        # changed has the offset jump at the change.
        c = replace(c, jump_deg=c.pocket_jump_deg, jump_window_steps=c.limb_jump_window_steps)
    t = np.array([s["t_s"] for s in out], dtype=np.float64)
    gyro = np.asarray(heading_deg_to_yaw(np.array([s["gyro_heading_deg"] for s in out])), dtype=np.float64)
    raw = np.asarray(heading_deg_to_yaw(np.array([s["heading_raw_deg"] for s in out])), dtype=np.float64)
    sigma = np.array([math.radians(s["heading_sigma_deg"]) if s.get("landmark_heading") else
                      math.radians(c.sigma_mag_deg) for s in out])
    bias_sigma = None
    notes: list[str] = []
    # Steps per deflection: the checks' statistics count independent deflections, not steps (deflection_corr_s).
    per_deflection = max(1.0, c.deflection_corr_s * (len(out) - 1) / max(float(t[-1] - t[0]), 1e-9))
    known = [s for s in out if s.get("gyro_bias_dps") is not None and s.get("up_time_s") is not None]
    if known:
        # The walk's last stationary bias estimate (device frame), removed from the gyro yaw: it added
        # up_time . b to it (pdr.phone.pipeline); the smoother then learns only the residual.
        b = np.radians(np.asarray(known[-1]["gyro_bias_dps"], dtype=np.float64))
        up_time = np.array([s.get("up_time_s") or [math.nan] * 3 for s in out], dtype=np.float64)
        if np.isfinite(up_time).all():
            gyro = gyro - up_time @ b
            bias_sigma = c.stationary_bias_sigma_deg
            # Likelihood-ratio test of the stationary estimate (module doc "Model checks"): does the magnetometer
            # agree with a residual bias near zero, or does it need the wide prior of a walk without one?
            tight = check_model(t, gyro, raw, sigma, c, c.stationary_bias_sigma_deg)
            wide = check_model(t, gyro, raw, sigma, c, c.bias_sigma_deg)
            lr = 2.0 * (wide.log_likelihood - tight.log_likelihood) / per_deflection
            if lr > chi2_quantile(1.0 - c.consistency_p, 1.0):
                bias_sigma = c.bias_sigma_deg
                notes.append(f"the stationary gyro bias estimate disagrees with the magnetometer (likelihood ratio "
                             f"{lr:.1f}): the bias is learnt from the magnetometer")
    # A limb's phone (pocket, swinging hand) swings with it once per stride (module doc "Limbs").
    limb = np.array([s.get("placement") in STRIDE_HEADING_PLACEMENTS for s in out])
    if limb.any():
        gyro = stride_mean_yaw(np.array([s.get("t_start_s", s["t_s"]) for s in out], dtype=np.float64), t, gyro, limb)
    check = check_model(t, gyro, raw, sigma, c, bias_sigma)
    dof = check.dof / per_deflection
    bound = chi2_quantile(1.0 - c.consistency_p, max(dof, 1.0))
    if check.dof and check.nis / per_deflection > bound:
        # Reported, not acted on (module doc "Model checks": falling back to the causal heading there was worse).
        notes.append(f"the magnetometer-gyro offsets are inconsistent with the model (innovation chi-square "
                     f"{check.nis / per_deflection:.0f} over {dof:.0f} deflections, {100 * (1 - c.consistency_p):.0f}% "
                     f"bound {bound:.0f})")
    shares = c.step_lag_shares([s.get("pocket_side") for s in out])
    sm = smooth_offsets(t, gyro, raw, sigma, c, bias_sigma, shares)
    if sm.turn_lag_s ** 2 > chi2_quantile(1.0 - c.consistency_p, 1.0) * sm.turn_lag_sigma_s ** 2:
        # Module doc "Turns": the offset follows the turn rate, which the straight-leg model would not allow.
        notes.append(f"the measured direction and the gyro yaw disagree on the timing of turns ("
                     f"{abs(sm.turn_lag_s) / sm.turn_lag_sigma_s:.1f} standard deviations): not a straight-leg walk")
    yaw = np.asarray(wrap_angle(gyro + sm.offset), dtype=np.float64)
    out = redo_steps(out, yaw)
    for k, s in enumerate(out):
        s["heading_sigma_deg"] = math.degrees(float(sm.offset_sigma[k]))
        s["smoothed"] = True
    return out, (f"heading smoothed over {len(out)} steps: residual gyro bias about the vertical "
                 f"{math.degrees(float(np.median(sm.bias))):+.3f} deg/s; the measured direction lags the gyro "
                 f"yaw through turns by {-sm.turn_lag_s:+.2f} +/- {sm.turn_lag_sigma_s:.2f} s (the gyro's share "
                 f"{float(np.mean(shares)):.2f} applied, mean over the steps)" + "".join(f"; {n}" for n in notes))


def smoothed_rows(rows: list[dict[str, Any]], notices: list[str]) -> list[dict[str, Any]]:
    """The offline-smoothed track (:func:`smooth_track`); its summary joins ``notices``."""
    out, summary = smooth_track(rows)
    if summary:
        notices.append(summary)
    return out
