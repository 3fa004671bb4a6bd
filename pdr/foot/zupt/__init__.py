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

Why the update is off by default (issue #5): it helps on PyShoe (causal), xio_gait_loop and the median of
foot_stride_gcp, but it loses badly on the foot_stride_gcp walks whose only rest is short and where the standing
foot still turns slowly: a real rotation, not a bias, read as bias and removed for the rest of the walk turns the
heading. A larger ``sigma_zaru`` or a longer ``zaru_min_still_s`` does not remove that loss and loses xio. The
update pays where the sensor's bias is large against the foot's residual motion (a consumer IMU) and the walk has
long rests. ``pdr eval foot /work/shared/data --method zupt --hde on --smoother both --zaru on|off`` prints the
figures.

Sample timing (``ZuptConfig.interval_samples``): by default each IMU sample is taken as the value at its instant
and the step from ``k - 1`` to ``k`` integrates the two samples (trapezoid, coning term). An IMU that averages or
integrates between outputs delivers instead the mean over the interval ending at ``k``; ``interval_samples`` then
integrates sample ``k`` alone over that step, as PyShoe's reference INS does. Not the default: no clear gain on PyShoe,
and xio loses (``pdr eval foot /work/shared/data --method zupt --hde on --smoother both --imu-samples
instant|interval``). With the PyShoe files' reference labels (``--zv-labels shoe``: thresholds grid-searched per trial
with that first-order INS) it gains more, because those labels were tuned to that mechanization.

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

The package: :mod:`.config` (noise model, segmentation), :mod:`.mechanisation` (strapdown step and error model),
:mod:`.kernel` (the compiled filter loop and its state), :mod:`.smoother` (the checkpointed RTS smoother),
:mod:`.initialisation` (coarse start, start-in-motion warning) and :mod:`.driver` (:func:`run_zupt`).
"""

from __future__ import annotations

from pdr.foot.zupt.config import Segmentation, ZuptConfig
from pdr.foot.zupt.driver import ZuptTrack, check_imu, closing_step, run_kernel, run_zupt
from pdr.foot.zupt.initialisation import LATE_START_S, coarse_start, first_stationary_run, late_start_warning
from pdr.foot.zupt.kernel import FilterState, KernelOutput, KernelSetup, init_lengths, kernel_setup
from pdr.foot.zupt.mechanisation import ATT, POS, VEL, YAW, error_transition, mechanize, zupt_predict
from pdr.foot.zupt.smoother import SMOOTHER_SEGMENT
from pdr.step_increment import StepIncrement

__all__ = ["ATT", "LATE_START_S", "POS", "SMOOTHER_SEGMENT", "VEL", "YAW", "FilterState", "KernelOutput",
           "KernelSetup", "Segmentation", "StepIncrement", "ZuptConfig", "ZuptTrack", "check_imu", "closing_step",
           "coarse_start", "error_transition", "first_stationary_run", "init_lengths", "kernel_setup",
           "late_start_warning", "mechanize", "run_kernel", "run_zupt", "zupt_predict"]
