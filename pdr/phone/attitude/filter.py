"""The attitude filter's driver: :class:`AttitudeFilter` holds the configuration and the state and feeds
uniform-rate batches to the compiled kernel; :func:`yaw_of_axis`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.phone.attitude.config import AttitudeConfig
from pdr.phone.attitude.kernel import run_kernel
from pdr.phone.attitude.state import AUX_BIAS_READY, AttitudeState

FloatArray = NDArray[np.float64]


class AttitudeFilter:
    """Quaternion attitude filter over uniform-rate samples: the seed-003 UKF or the RMPCA EKF baseline.

    Parameters
    ----------
    rate_hz
        Sample rate of the batches fed to :meth:`run` (Hz).
    config
        Noise and gating parameters.
    method
        ``"ukf"`` (seed 003 Sec. 4) or ``"ekf"`` (linearised baseline).
    """

    def __init__(self, rate_hz: float, config: AttitudeConfig | None = None, method: str = "ukf") -> None:
        if not rate_hz > 0:
            raise InputError(f"rate must be positive, got {rate_hz}", field="rate_hz")
        if method not in ("ukf", "ekf"):
            raise InputError(f"method must be 'ukf' or 'ekf', got {method!r}", field="method")
        self.rate_hz = float(rate_hz)
        self.config = config or AttitudeConfig()
        self.method = method
        self.state = AttitudeState()
        self._params = self.config.params()

    @property
    def bias_known(self) -> bool:
        """Whether a stationary period has given the gyro bias estimate (``state.bias``) its first rows."""
        return bool(self.state.aux[AUX_BIAS_READY] > 0)

    def set_config(self, config: AttitudeConfig) -> None:
        """Use new noise and gating parameters from the next sample on (the state is kept)."""
        self.config = config
        self._params = config.params()

    def run(self, acc_b: FloatArray, gyro_b: FloatArray | None = None, mag_b: FloatArray | None = None,
            carried: NDArray[np.bool_] | None = None) -> tuple[FloatArray, NDArray[np.int64]]:
        """Filter a batch of uniform samples.

        Parameters
        ----------
        acc_b, gyro_b, mag_b
            (N, 3) specific force (m/s^2), angular rate (rad/s) and magnetic field (uT), body frame;
            gyro and magnetometer may be None (the filter degrades: no gyro -> accelerometer/magnetometer
            only; no magnetometer -> yaw relative to the start).
        carried
            (N,) where the user is carried vertically (the barometric altitude still moves,
            :attr:`pdr.phone.floors.FloorSamples.moving`): a stand there (in a moving elevator cabin) does not
            calibrate the gyro (:mod:`pdr.phone.attitude` module doc, gyro bias). None: nowhere.

        Returns
        -------
        q_nb
            (N, 4) posterior attitude after each sample.
        used
            (N,) int flags: ``USED_ACC | USED_MAG | STATIONARY``.
        """
        acc = np.ascontiguousarray(acc_b, dtype=np.float64)
        n = acc.shape[0]
        if acc.ndim != 2 or acc.shape[1] != 3:
            raise InputError(f"acc must be (N, 3), got {acc.shape}", source="attitude", field="acc")
        gyro = np.zeros((n, 3)) if gyro_b is None else np.ascontiguousarray(gyro_b, dtype=np.float64)
        mag = np.zeros((n, 3)) if mag_b is None else np.ascontiguousarray(mag_b, dtype=np.float64)
        riding = np.zeros(n, dtype=np.bool_) if carried is None else np.ascontiguousarray(carried, dtype=np.bool_)
        if gyro.shape != (n, 3) or mag.shape != (n, 3) or riding.shape != (n,):
            raise InputError("gyro, mag and carried must have the length of acc", source="attitude")
        if n == 0:
            return np.zeros((0, 4)), np.zeros(0, dtype=np.int64)
        s = self.state
        decl = math.sin(math.radians(self.config.mag_declination_deg))
        return run_kernel(acc, gyro, mag, gyro_b is not None, mag_b is not None, 1.0 / self.rate_hz, s.q, s.P,
                           s.bias, s.aux, self._params, self.method == "ukf", decl, riding)


def yaw_of_axis(q_nb: FloatArray, axis_b: FloatArray) -> FloatArray:
    """Yaw (rad, CCW from east) of the horizontal projection of a body axis, per attitude (N,)."""
    v = quat.rotate(q_nb, np.broadcast_to(np.asarray(axis_b, dtype=np.float64), q_nb.shape[:-1] + (3,)))
    return np.arctan2(v[..., 1], v[..., 0])
