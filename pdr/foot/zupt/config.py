"""Configuration of the ZUPT-aided INS: the noise model (:class:`ZuptConfig`) and the step segmentation of
Algorithm 1 (:class:`Segmentation`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.foot.detectors import STILL_THRESHOLD
from pdr.frames import GRAVITY_MPS2

Array = NDArray[np.float64]


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
