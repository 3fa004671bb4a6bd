"""Configuration of the attitude filters (:class:`AttitudeConfig`) and the gyro stream's kind
(:func:`gyro_compensated`: the operating system's bias-compensated stream takes a bias prior).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.os_calibration import os_calibrated

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class AttitudeConfig:
    """Noise and gating parameters of the attitude filters (SI units).

    Attributes
    ----------
    sigma_gyro
        Gyro white noise (rad/s), ``W_gyro = sigma_gyro^2 I`` (eq. 9).
    sigma_a, sigma_m
        Accelerometer (m/s^2) and magnetometer (uT) measurement noise when accepted (eq. 11).
    eps_a1, eps_a2
        Eq. 12: maximum ``| |a| - |g| |`` (m/s^2) and variance of ``|a|`` (m^2/s^4).
    eps_m1, eps_m2
        Eq. 13: maximum ``| |m| - |h| |`` (uT) and variance of ``|m|`` (uT^2).
    eps_dip_deg
        Maximum deviation of the angle between ``a`` and ``m`` from the reference dip angle (deg).
        ``eps_m1`` and ``eps_dip_deg`` were 10; in a steel building (IPIN 2023 museum: |m| 30-40 uT against
        48 uT outdoors, dip -25 to -72 deg) rejecting more rows leaves the heading to the gyro for longer and
        the deflections do not average out: 20 lowered the landmark p75 of ``pdr eval ipin`` on the
        repetition-01 files it was chosen on and on the held-out repetition-02 files.
    earth_dip_deg
        Dip (deg, positive down) of the earth's field where the recording was made, from a field model at its
        location (:func:`pdr.geomagnetic.earth_field`; the pipeline sets it from a log's location fix), or None
        (unknown). Field rows whose dip departs from it by more than ``eps_dip_deg`` are not used, whatever the
        reference (which follows the measured field and so takes a building's bent field for the earth's when the
        recording starts in one). A field bent that far is steel's, and its horizontal part is not north either: at
        the start of IPIN trial 04 the field dips 33-46 deg where the model says 65.5, and the filter, following it,
        walked 15-27 deg off for the first 35 s (the phone's own fusion did not). The gate's width is the reference
        gate's (``eps_dip_deg``), chosen on the repetition-01 walks of ``pdr eval ipin`` (mean of the walks' p75,
        causal, with the model's dip given to every walk: 10, 15, 20, 25, 30 deg gave 3.84, 3.46, 3.31, 3.41,
        3.37 m, 3.57 without; smoothed 3.33 at 20, 3.35 without) and confirmed on the held-out repetition-02
        walks (3.35 -> 3.26 m causal, 3.03 -> 2.89 smoothed). It costs the elevator walk (trial 53, whose field dips
        40-47 deg along stretches of walking: 4.17 -> 4.33 m causal, 4.26 -> 5.55 smoothed).
    var_window_s
        Time constant of the trailing exponential windows for the variances of eqs. 12-13 (s).
    alpha, beta, kappa
        Unscented transform parameters (eqs. 35-37; the paper's 1e-3, 2, 0), also used by the unscented
        transforms of the landmark row and of the second UKF (:mod:`pdr.phone.heading`). With the attitude
        covariances met in practice (yaw sigma of a few degrees) the measurement functions are close to
        linear over the sigma-point spread, so alpha = 0.5 or 1 gives the same headings as 1e-3, and the
        UKF the same as the EKF (``pdr eval pocket-heading``, ``pdr eval ipin``).
    static_gyro_std, static_acc_std, static_mag_std, static_min_s
        Stationary detection (the user stands; the phone may tremble in the hand): trailing standard
        deviations of the gyro (rad/s, norm over the axes), of ``|a|`` (m/s^2) and of ``|m|`` (uT) below
        these, with the accelerometer quasi-static (eq. 12), for at least ``static_min_s`` (s).
    bias_field_uT, bias_dip_deg
        Largest change of the field's magnitude (uT) and dip relative to gravity (deg) within a stationary
        period for the field's rows to enter the gyro bias (the magnetic-disturbance test of eq. 13 applied
        to the bias rows).
    bias_tau_s, bias_smooth_s, bias_prior_s, bias_hold_s
        Gyro bias least squares over stationary samples: forgetting time constant (s of stationary data),
        low-pass time constant of the vectors (s), ridge weight towards zero bias (s of data), and the
        length of the blocks of rows held back (s): a block enters only once another block of
        stationary samples has followed it.
    compensated_bias_prior_s
        The ridge ``bias_prior_s`` used instead when the gyro stream is the operating system's bias-compensated
        one (:func:`gyro_compensated`): a Bayesian prior on the residual bias. The ridge equals ``N^2 / sigma0^2``,
        with ``N`` the noise density of the bias rows at a stand and ``sigma0`` the prior's spread. ``N``, measured
        at the stands of ``../shared/data`` (residual of the rows around the final bias, times the square root of its
        correlation time), is 1.1-1.6 deg/s sqrt(s) at the IPIN stands and 2.3-3.0 at the motion-capture walkers'
        (a hand that turns slowly while the walker pauses); with ``N = 2`` and ``sigma0 = 1`` deg/s (an
        OS-compensated gyro's residual; 0.1-0.5 deg/s on the Nexus 5 walks) it is 4 s: a stand of 4 s moves the
        estimate half way. Without the prior, one 1.7 s stand of a turning hand set the bias to (-1.6, 0.8, -3.5)
        deg/s, 10x the true residual, and the yaw drifted by 120 deg over the walk. A gyro the OS does not
        compensate can be biased by several deg/s (IPIN trial 27: 2.9 deg/s), where such a prior would hold the
        estimate back for the first minute (``pdr eval ipin``'s p75 rose with it), so it keeps ``bias_prior_s``.
    gravity_tau_s
        Time constant of the local gravity magnitude estimate during stationary periods (s).
    mag_ref_tau_s
        Time constant (s) with which the reference field's magnitude and dip follow the measured field
        (0: fixed at the first quasi-static sample).
    mag_yaw_only
        The magnetometer corrects the yaw alone (:func:`pdr.phone.attitude.kernel.mag_yaw_update`) instead of the
        three field rows of eq. 11. The tilt is observed by gravity; the field's rows also pull it wherever the field
        is not the reference (a magnet, steel), and while the user walks the accelerometer's rows are mostly gated
        out (eq. 12), so in a disturbed field nothing brings the tilt back. Off by default: with it, the yaw takes the
        whole of a steel building's deflection, which eq. 11's rows share with the tilt, and the hand-held heading
        between the IPIN landmarks got worse (``pdr eval ipin``), while the trouser-pocket and swinging-hand walks of
        ``pdr eval heading`` gained from the kept tilt.
    earth_field_max_uT
        The strongest field (uT) taken for the earth's: the geomagnetic field at the surface lies between about 22
        and 67 uT (World Magnetic Model), so a stronger one is a magnet or steel nearby, whatever the reference
        (which follows the measured field, ``mag_ref_tau_s``, and would follow a field that ramps up slowly as the
        phone nears a magnet); its rows are not used and the reference never follows above it.
    magnet_undo_tau_s, magnet_rise_uT
        Memory (s) of the yaw the field's rows turned the attitude by while the field was stronger than the
        reference by more than ``magnet_rise_uT`` (uT), undone when a field stronger than the earth's
        (``earth_field_max_uT``) appears; 0 s: never undone. A field above the earth's is a magnet or steel close to
        the phone, and it does not appear from nowhere: the phone moved into it, and for the seconds before (a
        dipole's field falls with the cube of the distance, so it rises from the building's level to the earth's
        maximum over the last metre or so) the rows saw a strengthening field deflected by it, which the gates,
        whose reference follows the field (``mag_ref_tau_s``), let through. Those rows' turn is summed with this
        exponential memory (the reference's own time constant) and taken back at the first stronger sample; the
        gyro carries the yaw from there. Rows in a field no stronger than the reference (the usual ups and downs
        of a building's field, and the rows that bring a wrong start back to north) are not undone. On the
        motion-capture benchmark (``pdr eval heading``) the rise was chosen between 0 and 5 uT on the tuning walker
        (causal walking direction 12.7 / 12.6 deg; it was 12.6 without the undo) and confirmed on the other (13.9
        without, 13.3 with 5 uT): the other walker's disturbed texting walk, whose phone neared a magnet through 5 s
        of a strengthening field, went from 21.7 to 6.2 deg attitude yaw error.
    sigma_a_moving
        Accelerometer noise (m/s^2) of gravity rows taken while the device is not quasi-static (eq. 12 rejects the
        sample); 0: none, seed 003's gate alone. A phone that moves with a limb (a trouser pocket's thigh, a
        swinging arm) never passes eq. 12 while its user walks (0 % of the samples of the motion-capture benchmark's
        swinging-hand and walking front-pocket recordings after the first stand), so with the gate alone its tilt
        is observed by nothing for the whole walk and drifts with the gyro (tilt error 3.2 deg mean over the
        benchmark, 9.3 on one swinging hand), and the magnetometer's three rows then share the field's
        deflections between that tilt and the yaw. The limb's accelerations are periodic with the gait and average
        out about gravity over a stride, so rows with a noise of the order of the limb's acceleration act as a
        low-pass over several strides (the filter's gain on them is about ``sigma_gyro sqrt(ts) g / sigma``
        per sample). Set per placement by :attr:`pdr.phone.pipeline.PipelineConfig.limb_sigma_a_moving`: a
        hand-held phone keeps the gate alone (with these rows the hand-held IPIN and MS walks lost a little: in a
        steel building the field's deflection is then taken by the yaw alone, as with ``mag_yaw_only``).
        Also tried for a hand-held phone only while it swings (no quasi-static sample and a trailing gyro spread
        above 2 rad/s for 2 or 4 s; or no quasi-static sample for 2-20 s): IPIN trial 26 repetition 02, whose walker
        swings the phone at 300-500 deg/s for its first 30 s (eq. 12 rejects every sample, the field's three rows
        leave the rotation about the field's axis to the gyro, and the yaw drifts 5 deg/s from the rotation vector's),
        went from 4.26 to 2.55-3.85 m causal p75, but the hand-held walks' p75 rose from 3.66 to 3.71-3.97 m causal and
        3.22 to 3.33-3.41 m smoothed (``pdr eval ipin``): their walkers swing or turn the phone that fast for several
        seconds too (7-23 % of half-second windows above 2 rad/s), and there the rows cost.
    mag_bias_gain, nu_window_s, nu_steady_deg
        The integral term of a complementary filter: the gyro's residual bias about the vertical learnt from the
        magnetometer's yaw innovation ``nu`` (rad) while the user moves, ``d bias / dt = -mag_bias_gain * nu``
        along the vertical (1/s^2; 0: off, the bias comes from the stands alone). The stands' least squares sets
        the bias only while the user stands, and an OS-compensated gyro keeps a residual of 0.1-0.4 deg/s (the
        motion-capture walks: median gyro less the mocap rate), which the field's rows, with the filter's time
        constant ``tau`` of about 10 s, leave as a steady yaw lag of ``bias * tau`` (4-10 deg measured on walks
        whose field rows were all accepted). ``1 / (4 tau^2)``, 0.0025, makes the loop critically damped. A bias
        turns the field seen through the estimate steadily; a disturbance turns it back and forth as the user
        walks through it, so the term acts only while the trailing standard deviation of ``nu`` (time constant
        ``nu_window_s``, s) is below ``nu_steady_deg``. Set per placement by
        :attr:`pdr.phone.pipeline.PipelineConfig.limb_mag_bias_gain`. On the motion-capture benchmark the
        attitude's yaw error in clean-field frames went from 5.5 to 4.8 deg (the rotation vector: 5.4) and the
        walking direction from 13.1 to 12.6 (tuning walker) and 14.3 to 13.9 deg (the other); the steadiness
        limit was chosen on the tuning walker among 1.5, 3, 5 and 8 deg (gains 0.0025 and 0.005 were within
        0.1 deg of each other).

        A robust alternative, measured offline and not built: the yaw corrected by the running median (causal,
        the last 30 s) of the field's azimuth seen through the estimate, over the rows whose magnitude (25-65 uT)
        and dip (within 20 deg of the earth's) look like the earth's field. On the motion-capture benchmark's
        clean walks it removes the residual lag (the tuning walker's clean texting walk 8.3 -> 3.6 deg attitude
        yaw, its back pocket 4.4 -> 2.5), but where the walk starts in a deflected field the median is the
        deflection's (the other walker's disturbed front pocket 14.6 -> 26.9 deg); applied only while the window's
        azimuths agree (1.48 MAD below 5 or 10 deg) it leaves the disturbed walks alone and the mean over all 18
        walks goes 5.9 -> 5.6 deg. The texting walks' walking direction is not bound by the attitude (the rotation
        vector's 3.9 deg attitude still gives 18.2 deg there), so the gain in walking direction would be about the
        pocket walks' 1 deg.
    mag_when_static
        Use magnetometer rows while stationary (False: a standing user sees one, possibly disturbed,
        field; its repeated samples are not independent measurements of north). True, measured: ``pdr eval ipin``
        causal p75 3.54 -> 3.81 m, smoothed 2.96 -> 3.06 (trial 51 4.57 -> 9.77 m causal; the elevator walk, trial
        53, whose legs are shorter than the field rows' time constant, only 4.37 -> 4.18).
    stand_bias_dps
        The gyro's residual bias about the vertical (deg/s, one sigma) while the user stands: with no field rows,
        the yaw's variance grows by ``(b T)^2`` over the ``T`` s stood since the field's rows were last used (a
        bias turns the yaw steadily, so the growth is quadratic, not the gyro noise's random walk). Without it the
        filter leaves a stand as sure of its yaw as it entered, however long the stand, and the field's rows after
        it correct the yaw over the filter's time constant (about 10 s), longer than the few steps between stops of
        a hand-held walk. 0.2: the motion-capture benchmark's residual biases about up (``pdr eval heading``) have
        an RMS of 0.22 deg/s (0.25 on the tuning walker, 0.20 on the other); not tuned on the figures below.
        ``pdr eval ipin`` (p75, m, causal / smoothed, without -> with): repetition-01 walks 3.58 / 2.86 -> 3.44 /
        2.87, repetition-02 walks 3.22 / 2.63 -> 3.31 / 2.43, all 27 walks 3.59 / 3.07 -> 3.54 / 2.96; the elevator
        walk (trial 53: stops of 12-36 s between its walking legs, four of them rides) 4.88 / 4.44 -> 4.37 / 4.40.
        ``pdr eval heading`` (no stands) and ``pdr eval steps`` do not change; ``pdr eval ms`` only with ``--map``
        (F3 online 3.01 -> 2.93 m).

        What is left on trial 53 is not the stands: its legs out of the elevator onto floor -2 stay 15-23 deg off
        (``pdr eval ipin FILE --legs``; the phone's rotation vector 2-6 deg), because the yaw carried through the
        cabin by the gyro starts from the approach leg next to the shaft, already 30-38 deg off for both (a steel
        shaft's field that passes the gates), and the rotation vector, which follows the field everywhere, cabin
        included, forgets it at the exit. Reopening the yaw variance to ``init_yaw_sigma_deg`` at the first field row
        after a ride (the barometer's ``carried``) was tried: trial 53 went 4.37 / 4.40 -> 4.98 / 3.82 m (causal /
        smoothed), the 27 walks' causal p75 3.54 -> 3.75; not adopted.
        Reopening it (30, 60 or 120 deg) at the first, third or sixth step after each ride instead: trial 53 causal
        4.24-4.51 m, smoothed 4.35-4.40, the other 26 walks unchanged. The rides are not what is left: the two legs
        between the start and the first ride (42-50 s and 62-73 s) are already 23 and 15 deg off against the rotation
        vector's 6 and 3, after a start 38 deg off (the rotation vector 31) beside the shaft; with legs of 7-14 s the
        field's rows cannot pull the yaw back within the filter's time constant.
    init_yaw_sigma_deg
        Standard deviation of the initial yaw (deg) set at the magnetic alignment.
    mag_declination_deg
        Magnetic declination (deg, east positive): magnetic north is rotated clockwise from true north.
    """

    sigma_gyro: float = 0.01
    sigma_a: float = 1.0
    sigma_m: float = 15.0
    eps_a1: float = 1.5
    eps_a2: float = 1.0
    eps_m1: float = 20.0
    eps_m2: float = 20.0
    eps_dip_deg: float = 20.0
    var_window_s: float = 0.5
    alpha: float = 1e-3
    beta: float = 2.0
    kappa: float = 0.0
    static_gyro_std: float = 0.3
    static_acc_std: float = 0.5
    static_mag_std: float = 1.0
    static_min_s: float = 1.0
    bias_tau_s: float = 300.0
    bias_smooth_s: float = 0.25
    bias_prior_s: float = 0.02
    compensated_bias_prior_s: float = 4.0
    bias_hold_s: float = 1.0
    gravity_tau_s: float = 5.0
    mag_ref_tau_s: float = 5.0
    mag_when_static: bool = False
    init_yaw_sigma_deg: float = 60.0
    mag_declination_deg: float = 0.0
    bias_field_uT: float = 10.0
    bias_dip_deg: float = 10.0
    mag_yaw_only: bool = False
    earth_field_max_uT: float = 70.0
    sigma_a_moving: float = 0.0
    mag_bias_gain: float = 0.0
    nu_window_s: float = 2.0
    nu_steady_deg: float = 5.0
    magnet_undo_tau_s: float = 5.0
    magnet_rise_uT: float = 5.0
    earth_dip_deg: float | None = None
    stand_bias_dps: float = 0.2

    def params(self) -> FloatArray:
        return np.array([self.sigma_gyro, self.sigma_a, self.sigma_m, self.eps_a1, self.eps_a2, self.eps_m1,
                         self.eps_m2, math.radians(self.eps_dip_deg), self.var_window_s, self.alpha, self.beta,
                         self.kappa, self.static_gyro_std, self.static_acc_std, self.static_min_s,
                         self.bias_tau_s, self.bias_smooth_s, self.bias_prior_s, self.gravity_tau_s,
                         self.mag_ref_tau_s, float(self.mag_when_static), math.radians(self.init_yaw_sigma_deg),
                         self.static_mag_std, self.bias_hold_s, self.bias_field_uT,
                         math.radians(self.bias_dip_deg), float(self.mag_yaw_only), self.earth_field_max_uT,
                         self.sigma_a_moving, self.mag_bias_gain, self.nu_window_s,
                         math.radians(self.nu_steady_deg), self.magnet_undo_tau_s,
                         self.magnet_rise_uT,
                         math.nan if self.earth_dip_deg is None else math.radians(self.earth_dip_deg),
                         math.radians(self.stand_bias_dps)])



#: Smallest median difference (rad/s, norm) between the uncalibrated and the calibrated gyro streams that shows the
#: OS applying a bias estimate (one LSB of a phone gyro is about 1e-3 rad/s; equal streams differ by 0).
OS_BIAS_MIN = 1e-5


def gyro_compensated(t_gyro_s: FloatArray, gyro: FloatArray, t_uncal_s: FloatArray, gyro_uncal: FloatArray) -> bool:
    """Whether a log's ``gyro`` stream (N, 3, rad/s, at times ``t_gyro_s``) is the OS's bias-compensated one: its
    ``gyro_uncal`` stream (M, 3) differs from it by a bias estimate (:func:`pdr.os_calibration.os_calibrated`, median
    norm of the difference above :data:`OS_BIAS_MIN`). Android's TYPE_GYROSCOPE subtracts the estimate that
    TYPE_GYROSCOPE_UNCALIBRATED reports beside its raw rates.
    """
    return os_calibrated(t_gyro_s, gyro, t_uncal_s, gyro_uncal, OS_BIAS_MIN)
