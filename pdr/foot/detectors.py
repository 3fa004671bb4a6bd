"""Zero-velocity detectors for foot-mounted IMUs, vectorised over the whole recording.

Test statistics of Skog, Händel, Nilsson, Rantakokko (2010), "Zero-velocity detection -- an algorithm
evaluation" (the detectors cited as [93, 94] in seed 001 Sec. 3.1): the foot is declared stationary at sample
``k`` when the statistic over a window ``W_k`` centred on ``k`` is below a threshold ``gamma_z`` (seed 001,
condition ``Z({f_k, w_k}_{W_k}) < gamma_z`` before eq. 3).

* ``shoe`` (SHOE / GLRT, stance hypothesis optimal detector):
  ``T_k = 1/W sum_l [ ||f_l - g fbar_k / ||fbar_k|| ||^2 / sigma_a^2 + ||w_l||^2 / sigma_w^2 ]``
* ``are`` (angular rate energy): ``T_k = 1/W sum_l ||w_l||^2 / sigma_w^2``
* ``mv`` (acceleration moving variance): ``T_k = 1/W sum_l ||f_l - fbar_k||^2 / sigma_a^2``
* ``mag`` (acceleration magnitude): ``T_k = 1/W sum_l (||f_l|| - g)^2 / sigma_a^2``

All window sums are moving averages (one pass each, no per-sample Python loop). The statistics are
dimensionless; with the default noise levels (``sigma_a = 0.01 m/s^2``, ``sigma_w = 0.1 deg/s``, as in
OpenShoe/PyShoe) and a 25 ms window, stance in walking gives 1e3-1e4 and swing 1e5 and more.

The adaptive detector (:func:`adaptive_threshold`) raises the threshold where even the stillest moment of
the surrounding gait cycle has a large statistic: in running the stance is short and the foot never comes as
completely to rest, so one fixed threshold either misses running stances or declares walking swings
stationary. The defaults (``gamma_z = 3e4``, factor 2) were chosen on the PyShoe VICON trials as one
configuration for walking, running and stairs: the factor on the odd-numbered development trials with the
RTS-smoothed ZUPT-aided INS (factors 1.5 and 2 alike, 3 before), checked on the even-numbered ones and on
``foot_stride_gcp``; 2 rather than 1.5 keeps the adaptation active in the simulated noisy stance of the tests.

With the offline gyroscope bias and interval samples the factor matters more (issue #5, ``pdr eval foot
/work/shared/data/pyshoe_vicon --method zupt --hde on --smoother on --gyro-bias on --imu-samples interval --run-gain
G`` prints the median ARMSE over the 18 trials): G = 1 makes the walking swings stationary; from 1.25 to 2.5 the
error grows with G, the lower factors at or below the reference oracles (best of five detectors, and SHOE, each with
its threshold grid-searched per trial). Without the two switches every G is worse. A factor chosen on the
odd-numbered trials holds on the even ones, but the odd trials stay above their oracle, and two foot_stride_gcp
walks (31 and 36) lose with the bias, so none of the three is a default.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import minimum_filter1d, uniform_filter1d

from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Names of the available test statistics.
DETECTORS: tuple[str, ...] = ("shoe", "are", "mv", "mag")


@dataclass(frozen=True)
class DetectorConfig:
    """Zero-velocity detector settings.

    Attributes
    ----------
    method
        One of :data:`DETECTORS`.
    window_s
        Length of the centred window ``W`` in s (rounded to an odd number of samples, at least 3).
    threshold
        Detection threshold ``gamma_z`` on the (dimensionless) statistic for walking.
    sigma_acc
        Accelerometer noise standard deviation used to normalise the statistic, m/s^2.
    sigma_gyro
        Gyroscope noise standard deviation used to normalise the statistic, rad/s.
    gravity
        Local gravity magnitude, m/s^2.
    adaptive
        Scale the threshold with the gait intensity (walking and running with one configuration).
    run_gain
        Factor of the adaptive threshold: ``gamma_k = max(gamma_z, run_gain * min T over +-0.6 s)``.
    """

    method: str = "shoe"
    window_s: float = 0.025
    threshold: float = 3.0e4
    sigma_acc: float = 0.01
    sigma_gyro: float = float(np.radians(0.1))
    gravity: float = GRAVITY_MPS2
    adaptive: bool = True
    run_gain: float = 2.0

    def __post_init__(self) -> None:
        if self.method not in DETECTORS:
            raise InputError(f"unknown zero-velocity detector '{self.method}'; expected one of {DETECTORS}",
                             field="detector")
        for name in ("window_s", "threshold", "sigma_acc", "sigma_gyro", "gravity", "run_gain"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"must be a positive number, got {value}", field=name)


def _check(acc_b: ArrayLike, gyro_b: ArrayLike) -> tuple[Array, Array]:
    f = np.asarray(acc_b, dtype=np.float64)
    w = np.asarray(gyro_b, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError(f"expected shape (N, 3), got {f.shape}", field="acc_b")
    if w.shape != f.shape:
        raise InputError(f"expected shape {f.shape} like acc_b, got {w.shape}", field="gyro_b")
    if f.shape[0] == 0:
        raise InputError("no samples", field="acc_b")
    return f, w


def window_samples(window_s: float, rate_hz: float) -> int:
    """Odd window length in samples (at least 3) for a window of ``window_s`` seconds at ``rate_hz``."""
    n = max(3, int(round(window_s * rate_hz)))
    return n if n % 2 else n + 1


def _mean(x: Array, w: int) -> Array:
    # Centred moving average along time; edges use the nearest sample.
    return uniform_filter1d(x, size=w, axis=0, mode="nearest")


def shoe_statistic(acc_b: ArrayLike, gyro_b: ArrayLike, window: int, sigma_acc: float, sigma_gyro: float,
                   gravity: float = GRAVITY_MPS2) -> Array:
    """SHOE (GLRT) statistic per sample.

    ``1/W sum ||f_l - g u_k||^2 = mean(||f||^2) - 2 g ||mean(f)|| + g^2`` with ``u_k = mean(f) / ||mean(f)||``,
    so only moving means are needed.

    Parameters
    ----------
    acc_b, gyro_b
        (N, 3) specific force (m/s^2) and angular rate (rad/s), body frame.
    window
        Window length ``W`` in samples.
    sigma_acc, sigma_gyro
        Noise standard deviations (m/s^2, rad/s).
    gravity
        Gravity magnitude, m/s^2.

    Returns
    -------
    (N,) dimensionless statistic.
    """
    f, w = _check(acc_b, gyro_b)
    mean_f = _mean(f, window)
    mean_f2 = _mean(np.sum(f * f, axis=1), window)
    acc_term = np.maximum(mean_f2 - 2.0 * gravity * np.linalg.norm(mean_f, axis=1) + gravity**2, 0.0)
    gyro_term = _mean(np.sum(w * w, axis=1), window)
    return acc_term / sigma_acc**2 + gyro_term / sigma_gyro**2


def angular_rate_energy(gyro_b: ArrayLike, window: int, sigma_gyro: float) -> Array:
    """Angular-rate energy statistic ``1/W sum ||w_l||^2 / sigma_w^2`` per sample, (N,)."""
    w = np.asarray(gyro_b, dtype=np.float64)
    return _mean(np.sum(w * w, axis=1), window) / sigma_gyro**2


def acc_moving_variance(acc_b: ArrayLike, window: int, sigma_acc: float) -> Array:
    """Acceleration moving-variance statistic ``1/W sum ||f_l - fbar_k||^2 / sigma_a^2`` per sample, (N,)."""
    f = np.asarray(acc_b, dtype=np.float64)
    mean_f = _mean(f, window)
    var = _mean(np.sum(f * f, axis=1), window) - np.sum(mean_f * mean_f, axis=1)
    return np.maximum(var, 0.0) / sigma_acc**2


def acc_magnitude(acc_b: ArrayLike, window: int, sigma_acc: float, gravity: float = GRAVITY_MPS2) -> Array:
    """Acceleration-magnitude statistic ``1/W sum (||f_l|| - g)^2 / sigma_a^2`` per sample, (N,)."""
    f = np.asarray(acc_b, dtype=np.float64)
    return _mean((np.linalg.norm(f, axis=1) - gravity) ** 2, window) / sigma_acc**2


def statistic(acc_b: ArrayLike, gyro_b: ArrayLike, rate_hz: float, config: DetectorConfig) -> Array:
    """The configured test statistic per sample, (N,)."""
    f, w = _check(acc_b, gyro_b)
    n = window_samples(config.window_s, rate_hz)
    if config.method == "shoe":
        return shoe_statistic(f, w, n, config.sigma_acc, config.sigma_gyro, config.gravity)
    if config.method == "are":
        return angular_rate_energy(w, n, config.sigma_gyro)
    if config.method == "mv":
        return acc_moving_variance(f, n, config.sigma_acc)
    return acc_magnitude(f, n, config.sigma_acc, config.gravity)


def adaptive_threshold(stat: ArrayLike, rate_hz: float, config: DetectorConfig) -> Array:
    """Per-sample threshold ``max(gamma_z, run_gain * min_{|j-k| <= 0.6 s} T_j)``, (N,).

    The smallest statistic within about one gait cycle measures how still the foot gets in its stance; in
    running it is one to two orders of magnitude above walking. Scaling the threshold with it keeps the
    stance detected in running without declaring walking swings stationary.
    """
    t = np.asarray(stat, dtype=np.float64)
    gamma = np.full(t.shape[0], config.threshold)
    if not config.adaptive:
        return gamma
    return np.maximum(gamma, config.run_gain * minimum_filter1d(t, size=_adaptive_span(rate_hz), mode="nearest"))


def _adaptive_span(rate_hz: float) -> int:
    # Samples of the adaptive threshold's window (about one gait cycle, +-0.6 s).
    return max(1, int(round(1.2 * rate_hz)))


def detector_reach(rate_hz: float, config: DetectorConfig) -> tuple[int, int]:
    """(before, after): how many samples before and after sample ``k`` decide its flag in :func:`detect`.

    The statistic's centred window and, when adaptive, the threshold's minimum filter (scipy's window of an
    even size ``s`` covers ``k - s//2 .. k + s - 1 - s//2``). An online detector can finalise the flag of
    sample ``k`` once sample ``k + after`` has arrived.
    """
    half = window_samples(config.window_s, rate_hz) // 2
    span = _adaptive_span(rate_hz) if config.adaptive else 1
    return half + span // 2, half + span - 1 - span // 2


def detect(acc_b: ArrayLike, gyro_b: ArrayLike, rate_hz: float,
           config: DetectorConfig | None = None) -> BoolArray:
    """Zero-velocity flags: ``statistic < threshold`` per sample.

    Parameters
    ----------
    acc_b, gyro_b
        (N, 3) specific force (m/s^2) and angular rate (rad/s), body frame.
    rate_hz
        Sampling rate in Hz (sets the window length in samples).
    config
        Detector settings (defaults: adaptive SHOE).

    Returns
    -------
    (N,) bool, True where the foot is detected at rest.
    """
    cfg = config or DetectorConfig()
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"sampling rate must be positive, got {rate_hz}", field="rate_hz")
    t = statistic(acc_b, gyro_b, rate_hz, cfg)
    return np.asarray(t < adaptive_threshold(t, rate_hz, cfg))


#: SHOE statistic (with the default noise levels) below which the foot counts as still for the gyroscope bias.
STILL_THRESHOLD = 300.0


def still_samples(acc_b: ArrayLike, gyro_b: ArrayLike, rate_hz: float, threshold: float = STILL_THRESHOLD,
                  config: DetectorConfig | None = None) -> BoolArray:
    """(N,) flags of the samples where the foot is still enough for its gyroscope to read only its bias.

    The SHOE statistic (:func:`statistic` with ``config``, default noise levels) below ``threshold``: a far
    stricter test than the zero-velocity threshold, so the foot's small rotations during stance stay out. Used by
    :func:`stationary_gyro_bias` and by the zero angular-rate update of :mod:`pdr.foot.zupt`.
    """
    f, w = _check(acc_b, gyro_b)
    return np.asarray(statistic(f, w, rate_hz, config or DetectorConfig()) < threshold)


def stationary_gyro_bias(acc_b: ArrayLike, gyro_b: ArrayLike, rate_hz: float, threshold: float = STILL_THRESHOLD,
                         min_s: float = 1.0, config: DetectorConfig | None = None) -> Array:
    """Gyroscope bias (rad/s, sensor frame) as the mean angular rate over the samples where the foot is still.

    The batch form of a zero angular-rate update: on the :func:`still_samples` (threshold ``threshold``,
    statistic of ``config``) the gyroscope measures only its bias. Uses the whole recording, so it is for offline
    processing. Returns zeros when fewer than ``min_s`` seconds of still samples exist.

    Why it is off by default (issue #5; pdr eval foot /work/shared/data --method zupt --hde on --smoother on
    --gyro-bias on|off). The threshold 300 still admits a root-mean-square rate of ``sqrt(300) * 0.1 deg/s =
    1.7 deg/s``, so short "still" runs inside walking stances (the foot settling) enter with mean rates of
    0.5-1 deg/s: on foot_stride_gcp walks 32 and 34 (no still run of 1 s) they are most of the set and the
    walks get worse (0.28 -> 0.55 %, 0.32 -> 0.56 %). On xio_gait_loop the set is right -- 92 % of it is the
    13.3 s rest before the walk and the 4.5 s after it, and the runs of 1 s or more alone give the same bias
    within 0.02 deg/s (loop error 65.9 mm instead of 60.1) -- but the bias moves during the walk (sensor y:
    -0.145 deg/s in the first rest, +0.093 in the last) and the loss is all in the sensor z axis (removing only
    x and y: 19.3 -> 10.5 mm; only z, -0.084 deg/s: 84.4 mm), i.e. the heading: without the correction a
    bias-driven heading drift happens to close the loop. The 400 Hz rate and the g / deg/s units are converted
    before this point and are not the cause. Per dataset with / without: PyShoe median ARMSE 0.0432 / 0.0465 m
    (odd 0.0438 / 0.0455, even 0.0407 / 0.0475; 6 trials better and 5 worse by more than 1 %), gcp median
    0.56 / 0.73 % (walk 35 better 1.06 -> 0.54 %, walks 32, 34, 36 worse), xio 60.1 / 19.3 mm. Runs of 1 s or
    more only: PyShoe 0.0465 m, gcp 0.46 % (walk 36 1.14 -> 2.68 %), xio 65.9 mm; the biases of the rests
    interpolated in time: xio 41.5 mm. None helps all three.

    Parameters
    ----------
    acc_b, gyro_b
        (N, 3) specific force (m/s^2) and angular rate (rad/s), body frame.
    rate_hz
        Sampling rate, Hz.
    threshold
        Largest statistic of a still sample (dimensionless).
    min_s
        Least total duration of still samples for an estimate, s.
    config
        Detector settings whose statistic is used (default :class:`DetectorConfig`).

    Returns
    -------
    (3,) bias in rad/s.
    """
    f, w = _check(acc_b, gyro_b)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"sampling rate must be positive, got {rate_hz}", field="rate_hz")
    still = still_samples(f, w, rate_hz, threshold, config)
    if still.sum() < max(1, int(round(min_s * rate_hz))):
        return np.zeros(3)
    return np.asarray(np.mean(w[still], axis=0))
