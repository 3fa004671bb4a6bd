"""State of the attitude filter: the layout of the kernel's auxiliary vector and :class:`AttitudeState`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]

# Layout of the filter's auxiliary state vector (one float64 array so the kernel stays simple).
AUX_VAR_A_MEAN, AUX_VAR_A_SQ, AUX_VAR_M_MEAN, AUX_VAR_M_SQ = 0, 1, 2, 3
AUX_STATIC_S, AUX_H_READY, AUX_H_N, AUX_H_U, AUX_G, AUX_N = 4, 5, 6, 7, 8, 9
AUX_VAR_W_SQ = 10                      # trailing variance of the gyro (sum over axes)
AUX_W_MEAN = 11                        # (3) trailing mean of the gyro
AUX_VS_A, AUX_VS_M = 14, 17            # (3 each) low-passed unit vectors of a and m (bias estimator)
AUX_CW_A, AUX_CW_M = 20, 23            # (3 each) low-passed cross products u x omega_raw
AUX_BN, AUX_BR = 26, 35                # (9) normal matrix and (3) right-hand side of the bias least squares
AUX_WAS_STILL, AUX_BIAS_READY = 38, 39  # previous sample stationary; first stationary period over
AUX_P0, AUX_P1, AUX_BLOCK_S = 40, 52, 64  # (12 each) pending blocks of gravity bias rows, age of the newer (s)
AUX_M0, AUX_M1 = 65, 77                # (12 each) pending blocks of magnetic-field bias rows
AUX_V0, AUX_V1 = 89, 101               # (12 each) pending blocks of vertical mean-gyro bias rows
AUX_ML = 113                           # (3) low-passed magnetic field (uT, body frame)
AUX_FREF = 116                         # (2) field invariants at the start of the stationary period (uT)
AUX_FBAD = 118                         # (3) field moved: in the older block, in the newer block, in the period
AUX_NU = 121                           # (2) trailing mean and variance of the field's yaw innovation (rad, rad^2)
AUX_MAG_DYAW = 123                     # yaw (rad) the field's rows turned the attitude by, recently (decaying sum)
AUX_IN_MAGNET = 124                    # the last field sample was stronger than the earth's (1) or not (0)
AUX_NO_FIELD_S = 125                   # time (s) stood since the field's rows were last used
AUX_SIZE = 126
AUX_SIZE_V1 = 65                       # size of the layout before the blocks above
AUX_SIZE_V2 = 121                      # size of the layout before the yaw innovation's moments
AUX_SIZE_V3 = 123                      # size of the layout before the recent field turn
AUX_SIZE_V4 = 125                      # size of the layout before the time without the field's rows
#: Bit flags of the per-sample ``used`` output.
USED_ACC, USED_MAG, STATIONARY = 1, 2, 4


@dataclass
class AttitudeState:
    """Serialisable state of an attitude filter: ``q_nb``, its 4x4 covariance, gyro bias (rad/s), auxiliaries."""

    q: FloatArray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    P: FloatArray = field(default_factory=lambda: np.eye(4) * 1e-2)
    bias: FloatArray = field(default_factory=lambda: np.zeros(3))
    aux: FloatArray = field(default_factory=lambda: np.zeros(AUX_SIZE))

    def state(self) -> dict[str, Any]:
        return {"q": self.q.tolist(), "P": self.P.tolist(), "bias": self.bias.tolist(), "aux": self.aux.tolist()}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> AttitudeState:
        try:
            st = cls(np.array(d["q"], dtype=np.float64), np.array(d["P"], dtype=np.float64),
                     np.array(d["bias"], dtype=np.float64), np.array(d["aux"], dtype=np.float64))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad attitude state ({exc})", source="attitude state") from None
        if st.aux.shape in ((AUX_SIZE_V1,), (AUX_SIZE_V2,), (AUX_SIZE_V3,), (AUX_SIZE_V4,)):
            # State saved before the magnetic and vertical bias rows had blocks of their own (nothing pending),
            # before the yaw innovation's moments (none yet), before the field's recent turn (none), or before the
            # time stood without the field's rows (none).
            st.aux = np.concatenate([st.aux, np.zeros(AUX_SIZE - st.aux.shape[0])])
        if st.q.shape != (4,) or st.P.shape != (4, 4) or st.bias.shape != (3,) or st.aux.shape != (AUX_SIZE,):
            raise InputError("attitude state arrays have wrong shapes", source="attitude state")
        return st
