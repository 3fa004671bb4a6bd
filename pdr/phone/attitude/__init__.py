"""Device attitude: the first UKF of seed 003 (Sec. 4) and the EKF of the original RMPCA as a baseline.

State: the attitude quaternion ``q_nb`` (Hamilton, scalar first, body -> ENU; seed 003 eqs. 4-5 call
``R(q) = R_GCS^DCS`` what :func:`pdr.quaternion.to_rotmat` calls ``C_nb``; ``h_DCS = R(q)^T h_GCS``).

Time update (eqs. 6-9, 34): ``q_{k+1} = F_k q_k`` with ``F_k = exp(0.5 Ts Omega(omega_k))`` (eq. 7; the
closed form ``cos(|w| Ts/2) I + sin(|w| Ts/2)/|w| Omega`` is used), ``omega`` the bias-corrected gyro rate;
``P = F P F^T + W`` with ``W = Xi W_gyro Xi^T`` (eqs. 8-9). Seed 003 prints ``Xi`` for a vector-first
quaternion; the scalar-first form ``Xi = Ts/2 [-e^T; q0 I + [e x]]`` is used here (same covariance).

Measurement update (eqs. 10-13, 35-40): ``z = [a; m] = [R(q)^T g; R(q)^T h] + v`` with the unscented transform of
the paper (``alpha = 1e-3``, ``beta = 2``, ``kappa = 0``, ``L = 4``). Rows are used only when eq. 12 (accelerometer:
``| |a| - |g| | < eps_a1`` and ``var(|a|) < eps_a2``, quasi-static) or eq. 13 (magnetometer: ``| |m| - |h| | <
eps_m1`` and ``var(|m|) < eps_m2``; a dip-angle check is added) accept them; otherwise their variance is infinite,
i.e. the rows are dropped. With ``AttitudeConfig.mag_yaw_only`` the field's rows act on the yaw alone
(:func:`.kernel.mag_yaw_update`): the azimuth of the measured field is one scalar row along the rotation about up,
so a disturbed field cannot tilt the attitude; eq. 11's three rows are the default. The variances of eqs. 12-13 are
computed over a trailing exponential window (time constant ``var_window_s``) instead of the centred window of the
paper, so the filter is causal and can run online. The quaternion is renormalised after each update. The landmark
row ``Delta UH = f(q)`` (eqs. 14-32) is applied once per step by :func:`landmark_update` (see
:mod:`pdr.phone.heading`).

Gyro bias: while the user stands (quasi-static accelerometer, small spread of ``|a|`` and of the gyro for
``static_min_s``; a hand-held phone still trembles) gravity is fixed in the navigation frame, also in a moving
elevator cabin (its acceleration is vertical), so its body-frame direction ``u`` obeys
``du/dt = u x (omega_raw - b)``. Low-passed versions of both sides give the rows
``[us]x b = LP(u x omega_raw) - d(us)/dt`` (rank 2: blind to the bias about the vertical). That component
comes from the gyro alone, ``us^T b = us^T omega_raw``, while the device does not rotate (trailing gyro
spread within the white noise ``sigma_gyro`` of eq. 9 on each axis, e.g. a phone in the pocket of a standing
user): at rest the gyro mean is the bias, and the field adds only its own changes. A user carried through
the building's field (elevator cabin) sees the field change although the device does not rotate; explaining
that change as rotation corrupted the bias (``pdr eval pocket-heading``: up to 2.6 deg/s in the stairs +
elevator walks, against 0.3-0.6 deg/s true). While the device rotates (a hand-held phone trembles and turns
slowly, so the gyro mean is not the bias) the component comes from the local magnetic field's rows of the
gravity rows' form, provided the field passes the magnetic-disturbance test of eq. 13 over the stationary
period: its magnitude and its dip relative to gravity (both invariant under any rotation of the device
while the field is fixed in the navigation frame) stay within ``bias_field_uT`` and ``bias_dip_deg`` of their
values at the start of the period. The normal equations are accumulated over stationary samples in
blocks of ``bias_hold_s`` that enter one block late (the trailing detectors see the end of standing late,
and a field that starts to move is noticed late: a block's magnetic rows enter only if neither it nor the
next block saw the field move or the device at rest; when standing ends, the older block enters if the newer,
partial one lasted at least ``var_window_s``, the time constant within which the detectors notice the first
step), with forgetting ``bias_tau_s`` and a small ridge
towards zero, and solved for ``b``. Unlike the mean of the raw gyro, the
gravity and (fixed) field rows are not biased by the slow rotation of a hand-held phone. A field that
moves only in azimuth, at constant magnitude and dip, while a hand-held phone rotates passes that test: a cabin
carried along its shaft through a building's field does this. So a stand while the barometric altitude moves
(:meth:`AttitudeFilter.run`'s ``carried``, :attr:`pdr.phone.floors.FloorSamples.moving`) gives no rows at all: on
IPIN trial 53 such stands had turned the bias about the vertical from -0.1 to -0.5 deg/s, where the walk's legs
against the truth give -0.27 (``pdr eval ipin``: smoothed p75 5.55 -> 4.44 m). Without a barometer they still
enter.

Magnetometer rows (eq. 13, adapted to disturbed buildings): the reference magnitude and dip follow the
measured field with time constant ``mag_ref_tau_s`` (so the gates reject abrupt disturbances, not a
building whose field differs from the first sample's), rows are not used while the user stands (one spot
gives one, possibly disturbed, measurement of north however many samples it has), and at the end of the
first stationary period that gives gyro-bias rows (at least one complete ``bias_hold_s`` block; a shorter
stand would make the reopening depend on where the recording starts) the yaw variance is reopened to
``init_yaw_sigma_deg``: the yaw propagated through the calibration motion with a still unknown gyro bias is
not trusted, and the walk's magnetometer rows, averaged by a large ``sigma_m``, set it. While the user stands
the yaw's variance grows with the gyro's residual bias, ``(b T)^2`` over ``T`` s (``stand_bias_dps``), so that
the rows after a long stand correct what the bias turned.

The :class:`AttitudeFilter` ``method="ekf"`` runs the same models with a linearised update
(finite-difference Jacobian of ``phi(q)``), the attitude filter of the original RMPCA (seed 003 ref. [14]),
as the baseline the UKF is compared with.

Modules: :mod:`.config` (:class:`AttitudeConfig`, :func:`gyro_compensated`), :mod:`.state` (the kernel's
auxiliary layout, :class:`AttitudeState`), :mod:`.kernel` (the numba-compiled recursion, the one UKF update)
and :mod:`.filter` (:class:`AttitudeFilter`, the driver). The driver holds the configuration, the state
(serialisable with :meth:`AttitudeState.state`) and feeds uniform-rate batches.
"""

from __future__ import annotations

from pdr.phone.attitude.config import OS_BIAS_MIN, AttitudeConfig, gyro_compensated
from pdr.phone.attitude.filter import AttitudeFilter, yaw_of_axis
from pdr.phone.attitude.state import STATIONARY, USED_ACC, USED_MAG, AttitudeState

__all__ = ["OS_BIAS_MIN", "STATIONARY", "USED_ACC", "USED_MAG", "AttitudeConfig", "AttitudeFilter",
           "AttitudeState", "gyro_compensated", "yaw_of_axis"]
