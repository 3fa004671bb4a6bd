"""Device attitude: the first UKF of seed 003 (Sec. 4) and the EKF of the original RMPCA as a baseline.

State: the attitude quaternion ``q_nb`` (Hamilton, scalar first, body -> ENU; seed 003 eqs. 4-5 call
``R(q) = R_GCS^DCS`` what :func:`pdr.quaternion.to_rotmat` calls ``C_nb``; ``h_DCS = R(q)^T h_GCS``).

Time update (eqs. 6-9, 34): ``q_{k+1} = F_k q_k`` with ``F_k = exp(0.5 Ts Omega(omega_k))`` (eq. 7; the
closed form ``cos(|w| Ts/2) I + sin(|w| Ts/2)/|w| Omega`` is used), ``omega`` the bias-corrected gyro rate;
``P = F P F^T + W`` with ``W = Xi W_gyro Xi^T`` (eqs. 8-9). Seed 003 prints ``Xi`` for a vector-first
quaternion; the scalar-first form ``Xi = Ts/2 [-e^T; q0 I + [e x]]`` is used here (same covariance).

Measurement update (eqs. 10-13, 35-40): ``z = [a; m] = [R(q)^T g; R(q)^T h] + v`` with the unscented
transform of the paper (``alpha = 1e-3``, ``beta = 2``, ``kappa = 0``, ``L = 4``). Rows are used only
when eq. 12 (accelerometer: ``| |a| - |g| | < eps_a1`` and ``var(|a|) < eps_a2``, quasi-static) or eq. 13
(magnetometer: ``| |m| - |h| | < eps_m1`` and ``var(|m|) < eps_m2``; a dip-angle check is added) accept
them; otherwise their variance is infinite, i.e. the rows are dropped. The variances of eqs. 12-13 are
computed over a trailing exponential window (time constant ``var_window_s``) instead of the centred
window of the paper, so the filter is causal and can run online. The quaternion is renormalised after
each update. The landmark row ``Delta UH = f(q)`` (eqs. 14-32) is applied once per step by
:func:`landmark_update` (see :mod:`pdr.phone.heading`).

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
moves only in azimuth, at constant magnitude and dip, while a hand-held phone rotates still enters the bias.

Magnetometer rows (eq. 13, adapted to disturbed buildings): the reference magnitude and dip follow the
measured field with time constant ``mag_ref_tau_s`` (so the gates reject abrupt disturbances, not a
building whose field differs from the first sample's), rows are not used while the user stands (one spot
gives one, possibly disturbed, measurement of north however many samples it has), and at the end of the
first stationary period that gives gyro-bias rows (at least one complete ``bias_hold_s`` block; a shorter
stand would make the reopening depend on where the recording starts) the yaw variance is reopened to
``init_yaw_sigma_deg``: the yaw propagated through the calibration motion with a still unknown gyro bias is
not trusted, and the walk's magnetometer rows, averaged by a large ``sigma_m``, set it.

The :class:`AttitudeFilter` ``method="ekf"`` runs the same models with a linearised update
(finite-difference Jacobian of ``phi(q)``), the attitude filter of the original RMPCA (seed 003 ref. [14]),
as the baseline the UKF is compared with.

The recursion is a numba-compiled kernel; :class:`AttitudeFilter` holds the configuration, the state
(serialisable with :meth:`AttitudeState.state`) and feeds uniform-rate batches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.filters.small_linalg import cholesky_lower, congruence, matmul, matmul_bt, matvec, solve_symmetric
from pdr.frames import GRAVITY_MPS2

FloatArray = NDArray[np.float64]

# Layout of the filter's auxiliary state vector (one float64 array so the kernel stays simple).
_AUX_VAR_A_MEAN, _AUX_VAR_A_SQ, _AUX_VAR_M_MEAN, _AUX_VAR_M_SQ = 0, 1, 2, 3
_AUX_STATIC_S, _AUX_H_READY, _AUX_H_N, _AUX_H_U, _AUX_G, _AUX_N = 4, 5, 6, 7, 8, 9
_AUX_VAR_W_SQ = 10                      # trailing variance of the gyro (sum over axes)
_AUX_W_MEAN = 11                        # (3) trailing mean of the gyro
_AUX_VS_A, _AUX_VS_M = 14, 17           # (3 each) low-passed unit vectors of a and m (bias estimator)
_AUX_CW_A, _AUX_CW_M = 20, 23           # (3 each) low-passed cross products u x omega_raw
_AUX_BN, _AUX_BR = 26, 35               # (9) normal matrix and (3) right-hand side of the bias least squares
_AUX_WAS_STILL, _AUX_BIAS_READY = 38, 39  # previous sample stationary; first stationary period over
_AUX_P0, _AUX_P1, _AUX_BLOCK_S = 40, 52, 64  # (12 each) pending blocks of gravity bias rows, age of the newer (s)
_AUX_M0, _AUX_M1 = 65, 77               # (12 each) pending blocks of magnetic-field bias rows
_AUX_V0, _AUX_V1 = 89, 101              # (12 each) pending blocks of vertical mean-gyro bias rows
_AUX_ML = 113                           # (3) low-passed magnetic field (uT, body frame)
_AUX_FREF = 116                         # (2) field invariants at the start of the stationary period (uT)
_AUX_FBAD = 118                         # (3) field moved: in the older block, in the newer block, in the period
_AUX_SIZE = 121
_AUX_SIZE_V1 = 65                       # size of the layout before the blocks above
#: Bit flags of the per-sample ``used`` output.
USED_ACC, USED_MAG, STATIONARY = 1, 2, 4


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
        the deflections do not average out: 20 gives 4.87 -> 4.49 m landmark p75 on the repetition-01
        files it was chosen on and 4.17 -> 3.86 m on the repetition-02 files.
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
        estimate back for the first minute (IPIN p75 3.79 -> 4.44 m with it), so it keeps ``bias_prior_s``.
    gravity_tau_s
        Time constant of the local gravity magnitude estimate during stationary periods (s).
    mag_ref_tau_s
        Time constant (s) with which the reference field's magnitude and dip follow the measured field
        (0: fixed at the first quasi-static sample).
    mag_when_static
        Use magnetometer rows while stationary (False: a standing user sees one, possibly disturbed,
        field; its repeated samples are not independent measurements of north).
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

    def params(self) -> FloatArray:
        return np.array([self.sigma_gyro, self.sigma_a, self.sigma_m, self.eps_a1, self.eps_a2, self.eps_m1,
                         self.eps_m2, math.radians(self.eps_dip_deg), self.var_window_s, self.alpha, self.beta,
                         self.kappa, self.static_gyro_std, self.static_acc_std, self.static_min_s,
                         self.bias_tau_s, self.bias_smooth_s, self.bias_prior_s, self.gravity_tau_s,
                         self.mag_ref_tau_s, float(self.mag_when_static), math.radians(self.init_yaw_sigma_deg),
                         self.static_mag_std, self.bias_hold_s, self.bias_field_uT,
                         math.radians(self.bias_dip_deg)])


GRAVITY = GRAVITY_MPS2

#: Smallest median difference (rad/s, norm) between the uncalibrated and the calibrated gyro streams that shows the
#: OS applying a bias estimate (one LSB of a phone gyro is about 1e-3 rad/s; equal streams differ by 0).
OS_BIAS_MIN = 1e-5


def gyro_compensated(t_gyro_s: FloatArray, gyro: FloatArray, t_uncal_s: FloatArray, gyro_uncal: FloatArray) -> bool:
    """Whether a log's ``gyro`` stream (N, 3, rad/s, at times ``t_gyro_s``) is the OS's bias-compensated one: at the
    sample times the two streams share (the same sensor events), its ``gyro_uncal`` stream (M, 3) differs from it by
    a bias estimate (median norm of the difference above :data:`OS_BIAS_MIN`). Android's TYPE_GYROSCOPE subtracts
    the estimate that TYPE_GYROSCOPE_UNCALIBRATED reports beside its raw rates; a phone without an estimate gives
    equal streams, and streams with no common sample time give no evidence (False).
    """
    _, ia, ib = np.intersect1d(np.asarray(t_gyro_s), np.asarray(t_uncal_s), return_indices=True)
    if ia.size == 0:
        return False
    d = np.asarray(gyro_uncal, dtype=np.float64)[ib] - np.asarray(gyro, dtype=np.float64)[ia]
    return bool(np.median(np.linalg.norm(d, axis=1)) > OS_BIAS_MIN)


@numba.njit(cache=True)
def _rotmat(q: FloatArray) -> FloatArray:
    """C_nb of a (not necessarily unit) quaternion, normalised first (eq. 5)."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    w, x, y, z = q[0] / n, q[1] / n, q[2] / n, q[3] / n
    c = np.empty((3, 3))
    c[0, 0] = 1 - 2 * (y * y + z * z)
    c[0, 1] = 2 * (x * y - w * z)
    c[0, 2] = 2 * (x * z + w * y)
    c[1, 0] = 2 * (x * y + w * z)
    c[1, 1] = 1 - 2 * (x * x + z * z)
    c[1, 2] = 2 * (y * z - w * x)
    c[2, 0] = 2 * (x * z - w * y)
    c[2, 1] = 2 * (y * z + w * x)
    c[2, 2] = 1 - 2 * (x * x + y * y)
    return c


@numba.njit(cache=True)
def _phi(q: FloatArray, g_ref: FloatArray, h_ref: FloatArray, use_a: bool, use_m: bool, m: int) -> FloatArray:
    """Measurement function of eq. 10 restricted to the accepted rows: [R^T g; R^T h]."""
    c = _rotmat(q)
    out = np.empty(m)
    k = 0
    if use_a:
        for i in range(3):
            out[k + i] = c[0, i] * g_ref[0] + c[1, i] * g_ref[1] + c[2, i] * g_ref[2]
        k += 3
    if use_m:
        for i in range(3):
            out[k + i] = c[0, i] * h_ref[0] + c[1, i] * h_ref[1] + c[2, i] * h_ref[2]
    return out


@numba.njit(cache=True)
def _transition(w: FloatArray, ts: float) -> FloatArray:
    """F = exp(0.5 Ts Omega(w)) (eqs. 6-7) in closed form."""
    om = np.zeros((4, 4))
    om[0, 1], om[0, 2], om[0, 3] = -w[0], -w[1], -w[2]
    om[1, 0], om[1, 2], om[1, 3] = w[0], w[2], -w[1]
    om[2, 0], om[2, 1], om[2, 3] = w[1], -w[2], w[0]
    om[3, 0], om[3, 1], om[3, 2] = w[2], w[1], -w[0]
    nw = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    f = np.eye(4) * math.cos(0.5 * nw * ts)
    if nw > 1e-12:
        f += om * (math.sin(0.5 * nw * ts) / nw)
    else:
        f += om * (0.5 * ts)
    return f


@numba.njit(cache=True)
def _process_noise(q: FloatArray, ts: float, sigma_gyro: float) -> FloatArray:
    """W = Xi W_gyro Xi^T (eqs. 8-9), scalar-first Xi = Ts/2 [-e^T; q0 I + [e x]]."""
    xi = np.empty((4, 3))
    q0, e1, e2, e3 = q[0], q[1], q[2], q[3]
    xi[0, 0], xi[0, 1], xi[0, 2] = -e1, -e2, -e3
    xi[1, 0], xi[1, 1], xi[1, 2] = q0, -e3, e2
    xi[2, 0], xi[2, 1], xi[2, 2] = e3, q0, -e1
    xi[3, 0], xi[3, 1], xi[3, 2] = -e2, e1, q0
    s2 = (0.5 * ts * sigma_gyro) ** 2
    out = np.empty((4, 4))
    for i in range(4):
        for j in range(i + 1):
            v = s2 * (xi[i, 0] * xi[j, 0] + xi[i, 1] * xi[j, 1] + xi[i, 2] * xi[j, 2])
            out[i, j] = v
            out[j, i] = v
    return out


@numba.njit(cache=True)
def _normalise(q: FloatArray) -> None:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    s = 1.0 / n if q[0] >= 0 else -1.0 / n
    for i in range(4):
        q[i] *= s


@numba.njit(cache=True)
def _sqrt_psd(p: FloatArray) -> FloatArray:
    """Lower Cholesky factor; falls back to an eigen-decomposition with clipped eigenvalues."""
    n = p.shape[0]
    sym = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            sym[i, j] = 0.5 * (p[i, j] + p[j, i])
    low = np.empty((n, n))
    if cholesky_lower(sym, low):
        return low
    vals, vecs = np.linalg.eigh(sym)
    for i in range(vals.size):
        vals[i] = math.sqrt(max(vals[i], 1e-18))
    return vecs * vals


@numba.njit(cache=True)
def _ukf_update(q: FloatArray, p: FloatArray, z: FloatArray, r_diag: FloatArray, g_ref: FloatArray,
                h_ref: FloatArray, use_a: bool, use_m: bool, alpha: float, beta: float, kappa: float) -> None:
    """Unscented measurement update (eqs. 35-40), in place."""
    n = 4
    m = z.size
    lam = alpha * alpha * (n + kappa) - n
    c = n + lam
    s = _sqrt_psd(c * p)
    sig = np.empty((2 * n + 1, n))
    for j in range(n):
        sig[0, j] = q[j]
    for i in range(n):
        for j in range(n):
            sig[1 + i, j] = q[j] + s[j, i]
            sig[1 + n + i, j] = q[j] - s[j, i]
    wm0 = lam / c
    wc0 = wm0 + (1.0 - alpha * alpha + beta)
    wi = 0.5 / c
    zs = np.empty((2 * n + 1, m))
    for i in range(2 * n + 1):
        zs[i] = _phi(sig[i], g_ref, h_ref, use_a, use_m, m)
    # eq. 38: predicted mean. The centre point is subtracted first to avoid cancellation of the
    # large weights (wm0 is about -1e6 for alpha = 1e-3).
    zm = zs[0].copy()
    for i in range(1, 2 * n + 1):
        zm += wi * (zs[i] - zs[0])
    pzz = np.zeros((m, m))
    pqz = np.zeros((n, m))
    dz = np.empty(m)
    for i in range(2 * n + 1):
        w = wc0 if i == 0 else wi
        for a in range(m):
            dz[a] = zs[i, a] - zm[a]
        for a in range(m):
            for b in range(a + 1):
                pzz[a, b] += w * dz[a] * dz[b]
        if i > 0:                                  # eq. 39 uses xi_i - xi_0, zero for the centre point
            for j in range(n):
                dq = sig[i, j] - sig[0, j]
                for b in range(m):
                    pqz[j, b] += w * dq * dz[b]
    for a in range(m):
        pzz[a, a] += r_diag[a]
        for b in range(a):
            pzz[b, a] = pzz[a, b]
    kt = solve_symmetric(pzz, pqz.T)               # K^T = P_zz^-1 P_qz^T (eq. 39)
    for j in range(n):                             # eq. 40
        for b in range(m):
            q[j] += kt[b, j] * (z[b] - zm[b])
    for i in range(n):                             # P - K P_zz K^T = P - P_qz K^T
        for j in range(i + 1):
            acc = 0.0
            for b in range(m):
                acc += 0.5 * (pqz[i, b] * kt[b, j] + pqz[j, b] * kt[b, i])
            v = 0.5 * (p[i, j] + p[j, i]) - acc
            p[i, j] = v
            p[j, i] = v
    _normalise(q)


@numba.njit(cache=True)
def _ekf_update(q: FloatArray, p: FloatArray, z: FloatArray, r_diag: FloatArray, g_ref: FloatArray,
                h_ref: FloatArray, use_a: bool, use_m: bool) -> None:
    """Linearised (EKF) update with a central-difference Jacobian of phi, in place."""
    m = z.size
    h = np.empty((m, 4))
    eps = 1e-6
    for j in range(4):
        qp = q.copy()
        qm = q.copy()
        qp[j] += eps
        qm[j] -= eps
        h[:, j] = (_phi(qp, g_ref, h_ref, use_a, use_m, m) - _phi(qm, g_ref, h_ref, use_a, use_m, m)) / (2 * eps)
    zm = _phi(q, g_ref, h_ref, use_a, use_m, m)
    s = congruence(h, p)
    for i in range(m):
        s[i, i] += r_diag[i]
    k = solve_symmetric(s, matmul_bt(h, p)).T      # K = P H^T S^-1
    dq = matvec(k, z - zm)
    for j in range(4):
        q[j] += dq[j]
    ikh = np.eye(4) - matmul(k, h)
    # Joseph form keeps P symmetric positive semi-definite under rounding.
    pn = congruence(ikh, p)
    for i in range(4):
        for j in range(4):
            for b in range(m):
                pn[i, j] += k[i, b] * r_diag[b] * k[j, b]
    p[:, :] = pn
    _normalise(q)


@numba.njit(cache=True)
def _bias_rows(aux: FloatArray, vs: int, cw: int, u: FloatArray, w_raw: FloatArray, ks: float, ts: float,
               accumulate: bool, weight: float, o: int) -> None:
    """Low-pass ``u`` and ``u x omega_raw``; if ``accumulate``, add the rows ``[us]x b = cw - d(us)/dt`` to the
    pending block at ``aux[o:o + 12]`` (9 normal-matrix then 3 right-hand-side entries).

    A vector fixed in the navigation frame obeys ``du/dt = u x (omega_raw - b)`` in the body frame; a
    linear low-pass keeps the relation, so ``us x b = LP(u x omega_raw) - d(us)/dt`` (3 rows, rank 2).
    """
    # Scalar code (no per-sample allocations): this runs at every sample.
    p0, p1, p2 = aux[vs], aux[vs + 1], aux[vs + 2]
    aux[vs] += ks * (u[0] - p0)
    aux[vs + 1] += ks * (u[1] - p1)
    aux[vs + 2] += ks * (u[2] - p2)
    aux[cw] += ks * (u[1] * w_raw[2] - u[2] * w_raw[1] - aux[cw])
    aux[cw + 1] += ks * (u[2] * w_raw[0] - u[0] * w_raw[2] - aux[cw + 1])
    aux[cw + 2] += ks * (u[0] * w_raw[1] - u[1] * w_raw[0] - aux[cw + 2])
    if not accumulate:
        return
    s0, s1, s2 = aux[vs], aux[vs + 1], aux[vs + 2]
    y0 = aux[cw] - (s0 - p0) / ts
    y1 = aux[cw + 1] - (s1 - p1) / ts
    y2 = aux[cw + 2] - (s2 - p2) / ts
    # Normal equations of S b = y with S = [us]x: S^T S = |us|^2 I - us us^T, S^T y = y x us.
    n2 = s0 * s0 + s1 * s1 + s2 * s2
    c = weight * ts
    aux[o] += c * (n2 - s0 * s0)
    aux[o + 1] -= c * s0 * s1
    aux[o + 2] -= c * s0 * s2
    aux[o + 3] -= c * s1 * s0
    aux[o + 4] += c * (n2 - s1 * s1)
    aux[o + 5] -= c * s1 * s2
    aux[o + 6] -= c * s2 * s0
    aux[o + 7] -= c * s2 * s1
    aux[o + 8] += c * (n2 - s2 * s2)
    aux[o + 9] += c * (y1 * s2 - y2 * s1)
    aux[o + 10] += c * (y2 * s0 - y0 * s2)
    aux[o + 11] += c * (y0 * s1 - y1 * s0)


@numba.njit(cache=True)
def _vertical_rows(aux: FloatArray, o: int, w_raw: FloatArray, ts: float) -> None:
    """Add the row ``us^T b = us^T omega_raw`` (``us`` the low-passed unit specific force, i.e. up in the body
    frame) to the pending block at ``aux[o:o + 12]``: a standing user's device does not turn about the
    vertical on average, so there the gyro mean is the bias. It completes the gravity rows (rank 2, blind to
    this component): their normal matrices add up to ``|us|^2 I``.
    """
    s0, s1, s2 = aux[_AUX_VS_A], aux[_AUX_VS_A + 1], aux[_AUX_VS_A + 2]
    nn = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    if nn < 1e-9:
        return
    s0, s1, s2 = s0 / nn, s1 / nn, s2 / nn
    y = s0 * w_raw[0] + s1 * w_raw[1] + s2 * w_raw[2]
    aux[o] += ts * s0 * s0
    aux[o + 1] += ts * s0 * s1
    aux[o + 2] += ts * s0 * s2
    aux[o + 3] += ts * s1 * s0
    aux[o + 4] += ts * s1 * s1
    aux[o + 5] += ts * s1 * s2
    aux[o + 6] += ts * s2 * s0
    aux[o + 7] += ts * s2 * s1
    aux[o + 8] += ts * s2 * s2
    aux[o + 9] += ts * s0 * y
    aux[o + 10] += ts * s1 * y
    aux[o + 11] += ts * s2 * y


@numba.njit(cache=True)
def _field_invariants(aux: FloatArray) -> tuple[float, float]:
    """Vertical and horizontal components (uT) of the low-passed field relative to the low-passed gravity
    direction: the two quantities a device rotation leaves unchanged while the field is fixed in the navigation
    frame (the magnitude and dip of eq. 13).
    """
    s0, s1, s2 = aux[_AUX_VS_A], aux[_AUX_VS_A + 1], aux[_AUX_VS_A + 2]
    nn = max(math.sqrt(s0 * s0 + s1 * s1 + s2 * s2), 1e-9)
    m0, m1, m2 = aux[_AUX_ML], aux[_AUX_ML + 1], aux[_AUX_ML + 2]
    v = (m0 * s0 + m1 * s1 + m2 * s2) / nn
    h2 = m0 * m0 + m1 * m1 + m2 * m2 - v * v
    return v, math.sqrt(max(h2, 0.0))


@numba.njit(cache=True)
def _commit_block(aux: FloatArray, bias: FloatArray, has_mag: bool, fb: float, bias_prior: float) -> None:
    """Add the older pending block of bias rows (gravity rows, and the field's rows if neither block saw the field
    move, else the vertical mean-gyro rows) to the forgotten normal equations (factor ``fb``), move the newer
    block into its place, and solve for the gyro bias (ridge ``bias_prior`` towards zero), in place.
    """
    mag_ok = has_mag and aux[_AUX_FBAD] == 0 and aux[_AUX_FBAD + 1] == 0
    extra = _AUX_M0 if mag_ok else _AUX_V0
    for i in range(12):
        aux[_AUX_BN + i] = fb * aux[_AUX_BN + i] + aux[_AUX_P0 + i] + aux[extra + i]
        aux[_AUX_P0 + i] = aux[_AUX_P1 + i]
        aux[_AUX_M0 + i] = aux[_AUX_M1 + i]
        aux[_AUX_V0 + i] = aux[_AUX_V1 + i]
        aux[_AUX_P1 + i] = 0.0
        aux[_AUX_M1 + i] = 0.0
        aux[_AUX_V1 + i] = 0.0
    if aux[_AUX_BN] + aux[_AUX_BN + 4] + aux[_AUX_BN + 8] > 0:
        nm = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                nm[i, j] = aux[_AUX_BN + 3 * i + j] + (bias_prior if i == j else 0.0)
        rhs = np.empty(3)
        for i in range(3):
            rhs[i] = aux[_AUX_BR + i]
        sol = np.linalg.solve(nm, rhs)
        for i in range(3):
            bias[i] = sol[i]


@numba.njit(cache=True)
def _run_kernel(acc: FloatArray, gyro: FloatArray, mag: FloatArray, has_gyro: bool, has_mag: bool, ts: float,
                q: FloatArray, p: FloatArray, bias: FloatArray, aux: FloatArray, prm: FloatArray,
                unscented: bool, h_east: float) -> tuple[FloatArray, NDArray[np.int64]]:
    """Run the filter over uniform samples; state arrays are updated in place.

    Returns the (N, 4) posterior attitudes and (N,) bit flags (USED_ACC, USED_MAG, STATIONARY).
    """
    sigma_gyro, sigma_a, sigma_m = prm[0], prm[1], prm[2]
    eps_a1, eps_a2, eps_m1, eps_m2, eps_dip = prm[3], prm[4], prm[5], prm[6], prm[7]
    var_tau, alpha, beta, kappa = prm[8], prm[9], prm[10], prm[11]
    static_gyro_std, static_acc_std, static_min_s = prm[12], prm[13], prm[14]
    bias_tau, bias_smooth, bias_prior, gravity_tau = prm[15], prm[16], prm[17], prm[18]
    mag_ref_tau, mag_when_static, init_yaw_sigma, static_mag_std = prm[19], prm[20] > 0.5, prm[21], prm[22]
    bias_hold_s, bias_field, bias_dip = prm[23], prm[24], prm[25]
    n = acc.shape[0]
    out = np.empty((n, 4))
    used = np.zeros(n, dtype=np.int64)
    ka = ts / (var_tau + ts)
    kg = ts / (gravity_tau + ts)
    ks = ts / (bias_smooth + ts)
    k_ref = ts / (mag_ref_tau + ts) if mag_ref_tau > 0 else 0.0
    decay = 1.0 - ts / bias_tau
    g_ref = np.zeros(3)
    h_ref = np.zeros(3)
    w = np.zeros(3)
    for k in range(n):
        a = acc[k]
        an = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
        # Trailing exponential mean and variance of |a|, |m| and the gyro (eqs. 12-13, causal windows).
        if aux[_AUX_N] == 0:
            aux[_AUX_VAR_A_MEAN] = an
            aux[_AUX_VAR_A_SQ] = 0.0
            for i in range(3):
                aux[_AUX_W_MEAN + i] = gyro[k, i]
                aux[_AUX_VS_A + i] = a[i] / max(an, 1e-9)
            aux[_AUX_VAR_W_SQ] = 0.0
        da = an - aux[_AUX_VAR_A_MEAN]
        aux[_AUX_VAR_A_MEAN] += ka * da
        aux[_AUX_VAR_A_SQ] = (1 - ka) * (aux[_AUX_VAR_A_SQ] + ka * da * da)
        dw2 = 0.0
        for i in range(3):
            dw = gyro[k, i] - aux[_AUX_W_MEAN + i]
            aux[_AUX_W_MEAN + i] += ka * dw
            dw2 += dw * dw
        aux[_AUX_VAR_W_SQ] = (1 - ka) * (aux[_AUX_VAR_W_SQ] + ka * dw2)
        mn = 0.0
        if has_mag:
            mv = mag[k]
            mn = math.sqrt(mv[0] * mv[0] + mv[1] * mv[1] + mv[2] * mv[2])
            if aux[_AUX_N] == 0:
                aux[_AUX_VAR_M_MEAN] = mn
                aux[_AUX_VAR_M_SQ] = 0.0
                for i in range(3):
                    aux[_AUX_VS_M + i] = mv[i] / max(mn, 1e-9)
            if aux[_AUX_N] == 0 or (aux[_AUX_ML] == 0 and aux[_AUX_ML + 1] == 0 and aux[_AUX_ML + 2] == 0):
                for i in range(3):
                    aux[_AUX_ML + i] = mv[i]
            for i in range(3):
                aux[_AUX_ML + i] += ks * (mv[i] - aux[_AUX_ML + i])
            dm = mn - aux[_AUX_VAR_M_MEAN]
            aux[_AUX_VAR_M_MEAN] += ka * dm
            aux[_AUX_VAR_M_SQ] = (1 - ka) * (aux[_AUX_VAR_M_SQ] + ka * dm * dm)
        if aux[_AUX_N] == 0:
            # Initial attitude: tilt from gravity, yaw from the magnetic field (TRIAD) or zero.
            _init_attitude(q, a, mag[k] if has_mag else np.zeros(3), has_mag, h_east)
            aux[_AUX_G] = GRAVITY
        aux[_AUX_N] += 1
        quasi_static = abs(an - aux[_AUX_G]) < eps_a1 and aux[_AUX_VAR_A_SQ] < eps_a2
        # Stationary user (for the gyro bias): quasi-static, small trailing spread of |a| and of the gyro.
        still = (quasi_static and aux[_AUX_VAR_A_SQ] < static_acc_std * static_acc_std
                 and aux[_AUX_VAR_W_SQ] < static_gyro_std * static_gyro_std)
        if has_mag:
            still = still and aux[_AUX_VAR_M_SQ] < static_mag_std * static_mag_std
        if still:
            aux[_AUX_STATIC_S] += ts
        else:
            aux[_AUX_STATIC_S] = 0.0
        stationary = aux[_AUX_STATIC_S] >= static_min_s
        period_start = stationary and aux[_AUX_WAS_STILL] == 0
        period_end = not stationary and aux[_AUX_WAS_STILL] > 0
        aux[_AUX_WAS_STILL] = 1.0 if stationary else 0.0
        if has_gyro:
            # Gyro bias by least squares over stationary samples. Gravity is fixed in the navigation frame while
            # the user stands (also in a moving elevator cabin: its acceleration is vertical); the local magnetic
            # field only while the user is not carried through the building's field (elevator, escalator), and
            # only then may its rows set the bias component about the vertical. Otherwise that component comes
            # from the gyro alone (at rest the mean of the gyro about the vertical is the bias).
            u = a / max(an, 1e-9)
            _bias_rows(aux, _AUX_VS_A, _AUX_CW_A, u, gyro[k], ks, ts, stationary, 1.0, _AUX_P1)
            if has_mag:
                _bias_rows(aux, _AUX_VS_M, _AUX_CW_M, mag[k] / max(mn, 1e-9), gyro[k], ks, ts, stationary, 1.0,
                           _AUX_M1)
            if stationary:
                used[k] |= 4
                _vertical_rows(aux, _AUX_V1, gyro[k], ts)
                if has_mag:
                    # Magnetic-disturbance test of eq. 13 for the bias rows: a field fixed in the navigation frame
                    # keeps its magnitude and dip relative to gravity, i.e. its vertical and horizontal components,
                    # under any rotation of the device. A departure from the values at the start of the stationary
                    # period by more than the stillness spread of |m| marks the field as moving for the rest of
                    # the period (a slowly moving field may stay within a single block's spread).
                    fv, fh = _field_invariants(aux)
                    if period_start:
                        aux[_AUX_FREF], aux[_AUX_FREF + 1] = fv, fh
                        aux[_AUX_FBAD + 2] = 0.0
                    elif (abs(math.hypot(fv, fh) - math.hypot(aux[_AUX_FREF], aux[_AUX_FREF + 1])) > bias_field
                          or abs(math.atan2(fv, fh) - math.atan2(aux[_AUX_FREF], aux[_AUX_FREF + 1])) > bias_dip):
                        aux[_AUX_FBAD + 2] = 1.0
                    if aux[_AUX_FBAD + 2] > 0 or aux[_AUX_VAR_W_SQ] < 3.0 * sigma_gyro * sigma_gyro:
                        # Disturbed field, or a device that does not rotate (gyro spread within its white
                        # noise, eq. 9): there the gyro mean about the vertical is the bias and the field's
                        # rows would only add its changes (a cabin carried through the building's field).
                        aux[_AUX_FBAD + 1] = 1.0
                aux[_AUX_G] += kg * (an - aux[_AUX_G])
                aux[_AUX_BLOCK_S] += ts
                if aux[_AUX_BLOCK_S] >= bias_hold_s:
                    # Rows are committed one block late: the trailing detectors notice the end of a
                    # stationary period (first step, phone lifted) only after a delay, and the rows of that
                    # delay (linear acceleration) must not enter the bias. Likewise a field that starts to move
                    # is noticed late: the older block's magnetic rows count only if neither block saw it move.
                    _commit_block(aux, bias, has_mag, decay ** (aux[_AUX_BLOCK_S] / ts), bias_prior)
                    aux[_AUX_FBAD] = aux[_AUX_FBAD + 1]
                    aux[_AUX_FBAD + 1] = aux[_AUX_FBAD + 2]
                    aux[_AUX_BLOCK_S] = 0.0
            else:
                if aux[_AUX_BLOCK_S] >= var_tau:
                    # End of standing after a partial block at least as long as the detectors' trailing window
                    # (time constant var_window_s, within which they notice the first step): the delay's rows
                    # lie in the partial block, so the complete block before it is clean and enters now. (A
                    # stand of just under two blocks, e.g. the opening stand of a walk, otherwise left no bias.)
                    _commit_block(aux, bias, has_mag, decay ** (aux[_AUX_BLOCK_S] / ts), bias_prior)
                for o in (_AUX_P0, _AUX_M0, _AUX_V0):
                    for i in range(24):
                        aux[o + i] = 0.0
                for i in range(3):
                    aux[_AUX_FBAD + i] = 0.0
                aux[_AUX_BLOCK_S] = 0.0
            if period_end and aux[_AUX_BIAS_READY] == 0 and aux[_AUX_BN] + aux[_AUX_BN + 4] + aux[_AUX_BN + 8] > 0:
                # End of the first stationary period that gave the gyro bias rows (a stand too short to complete
                # a block gives none): the bias is now known, but the yaw propagated before it (with an unknown
                # bias, through the calibration motion) is not; reopen it so the walk's magnetometer rows set it.
                if has_mag:
                    _set_yaw_covariance(q, p, init_yaw_sigma)
                aux[_AUX_BIAS_READY] = 1.0
            # Time update (eqs. 6-9, 34).
            for i in range(3):
                w[i] = gyro[k, i] - bias[i]
            f = _transition(w, ts)
            wq = _process_noise(q, ts, sigma_gyro)         # from the prior q (eq. 9)
            p[:, :] = congruence(f, p) + wq
            q[:] = matvec(f, q)
        else:
            # Without a gyro the attitude is a random walk driven by a large rate noise.
            p += _process_noise(q, ts, 1.0)
        for i in range(4):
            p[i, i] += 1e-12
        # Accept rows of the measurement model (eqs. 12-13).
        use_a = quasi_static or not has_gyro
        use_m = False
        if has_mag:
            mv = mag[k]
            if aux[_AUX_H_READY] == 0 and quasi_static:
                # At the first quasi-static sample: re-initialise the attitude (TRIAD) and take the
                # reference field in ENU from it; the yaw is uncertain by init_yaw_sigma.
                _init_attitude(q, a, mv, True, h_east)
                c = _rotmat(q)
                hn = c @ mv
                aux[_AUX_H_N] = math.sqrt(hn[0] * hn[0] + hn[1] * hn[1])
                aux[_AUX_H_U] = hn[2]
                aux[_AUX_H_READY] = 1
                _set_yaw_covariance(q, p, init_yaw_sigma)
            if aux[_AUX_H_READY] == 1:
                href_n = math.sqrt(aux[_AUX_H_N] ** 2 + aux[_AUX_H_U] ** 2)
                dip_ref = math.atan2(-aux[_AUX_H_U], aux[_AUX_H_N])
                c = _rotmat(q)
                hn = c @ mv
                dip = math.atan2(-hn[2], math.sqrt(hn[0] * hn[0] + hn[1] * hn[1]))
                use_m = abs(mn - href_n) < eps_m1 and aux[_AUX_VAR_M_SQ] < eps_m2 and abs(dip - dip_ref) < eps_dip
                if stationary and not mag_when_static:
                    use_m = False
                if k_ref > 0 and not stationary:
                    # The reference magnitude and dip follow the measured field slowly (innovations clipped).
                    nn = href_n + k_ref * max(-3 * eps_m1, min(3 * eps_m1, mn - href_n))
                    dd = dip_ref + k_ref * max(-3 * eps_dip, min(3 * eps_dip, dip - dip_ref))
                    aux[_AUX_H_N] = nn * math.cos(dd)
                    aux[_AUX_H_U] = -nn * math.sin(dd)
        if use_a or use_m:
            m = 3 * (int(use_a) + int(use_m))
            z = np.empty(m)
            r = np.empty(m)
            j = 0
            if use_a:
                g_ref[0], g_ref[1], g_ref[2] = 0.0, 0.0, aux[_AUX_G]
                sa = sigma_a if has_gyro else 10.0 * sigma_a
                for i in range(3):
                    z[i] = a[i]
                    r[i] = sa * sa
                j = 3
                used[k] |= 1
            if use_m:
                # Magnetic north rotated by the declination (east positive) from true north.
                h_ref[0] = aux[_AUX_H_N] * h_east
                h_ref[1] = aux[_AUX_H_N] * math.sqrt(max(0.0, 1 - h_east * h_east))
                h_ref[2] = aux[_AUX_H_U]
                for i in range(3):
                    z[j + i] = mag[k, i]
                    r[j + i] = sigma_m * sigma_m
                used[k] |= 2
            if unscented:
                _ukf_update(q, p, z, r, g_ref, h_ref, use_a, use_m, alpha, beta, kappa)
            else:
                _ekf_update(q, p, z, r, g_ref, h_ref, use_a, use_m)
        else:
            _normalise(q)
        out[k] = q
    return out, used


@numba.njit(cache=True)
def _set_yaw_covariance(q: FloatArray, p: FloatArray, sigma_yaw: float) -> None:
    """Covariance of ``q`` for a yaw uncertainty ``sigma_yaw`` (rad) about the navigation up axis, tilt kept.

    A rotation ``dpsi`` about up moves ``q`` by ``0.5 [0, 0, 0, dpsi] * q = 0.5 dpsi g`` with
    ``g = [0, 0, 0, 1] * q``; the tilt part of the existing covariance is kept.
    """
    g = np.array([-q[3], -q[2], q[1], q[0]])
    pg = p @ g
    gpg = g @ pg
    # Remove the existing variance along g, then add the new one.
    pn = p - np.outer(pg, pg) / max(gpg, 1e-18) + 0.25 * sigma_yaw * sigma_yaw * np.outer(g, g)
    p[:, :] = 0.5 * (pn + pn.T)


@numba.njit(cache=True)
def _init_attitude(q: FloatArray, a: FloatArray, m: FloatArray, has_mag: bool, h_east: float) -> None:
    """TRIAD: up from the specific force, north from the horizontal magnetic field (or device y)."""
    up = a / math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    ref = m.copy() if has_mag else np.array([0.0, 1.0, 0.0])
    north = ref - (ref @ up) * up
    nn = math.sqrt(north @ north)
    if nn < 1e-9:
        ref = np.array([0.0, 1.0, 0.0]) if abs(up[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        north = ref - (ref @ up) * up
        nn = math.sqrt(north @ north)
    north = north / nn
    east = np.cross(north, up)
    # Rows of C_bn are the ENU axes in the body frame: C_nb = [east; north; up] (rows).
    c = np.empty((3, 3))
    c[0], c[1], c[2] = east, north, up
    # Rotate about up by the declination: magnetic north is `decl` clockwise from true north.
    ce = math.sqrt(max(0.0, 1 - h_east * h_east))
    se = h_east
    rz = np.array([[ce, se, 0.0], [-se, ce, 0.0], [0.0, 0.0, 1.0]])
    c = rz @ c if has_mag else c
    # Shepperd: quaternion of C_nb.
    tr = c[0, 0] + c[1, 1] + c[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q[0] = 0.25 * s
        q[1] = (c[2, 1] - c[1, 2]) / s
        q[2] = (c[0, 2] - c[2, 0]) / s
        q[3] = (c[1, 0] - c[0, 1]) / s
    elif c[0, 0] > c[1, 1] and c[0, 0] > c[2, 2]:
        s = math.sqrt(1.0 + c[0, 0] - c[1, 1] - c[2, 2]) * 2
        q[0] = (c[2, 1] - c[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (c[0, 1] + c[1, 0]) / s
        q[3] = (c[0, 2] + c[2, 0]) / s
    elif c[1, 1] > c[2, 2]:
        s = math.sqrt(1.0 + c[1, 1] - c[0, 0] - c[2, 2]) * 2
        q[0] = (c[0, 2] - c[2, 0]) / s
        q[1] = (c[0, 1] + c[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (c[1, 2] + c[2, 1]) / s
    else:
        s = math.sqrt(1.0 + c[2, 2] - c[0, 0] - c[1, 1]) * 2
        q[0] = (c[1, 0] - c[0, 1]) / s
        q[1] = (c[0, 2] + c[2, 0]) / s
        q[2] = (c[1, 2] + c[2, 1]) / s
        q[3] = 0.25 * s
    _normalise(q)


@dataclass
class AttitudeState:
    """Serialisable state of an attitude filter: ``q_nb``, its 4x4 covariance, gyro bias (rad/s), auxiliaries."""

    q: FloatArray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    P: FloatArray = field(default_factory=lambda: np.eye(4) * 1e-2)
    bias: FloatArray = field(default_factory=lambda: np.zeros(3))
    aux: FloatArray = field(default_factory=lambda: np.zeros(_AUX_SIZE))

    def state(self) -> dict[str, Any]:
        return {"q": self.q.tolist(), "P": self.P.tolist(), "bias": self.bias.tolist(), "aux": self.aux.tolist()}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> AttitudeState:
        try:
            st = cls(np.array(d["q"], dtype=np.float64), np.array(d["P"], dtype=np.float64),
                     np.array(d["bias"], dtype=np.float64), np.array(d["aux"], dtype=np.float64))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad attitude state ({exc})", source="attitude state") from None
        if st.aux.shape == (_AUX_SIZE_V1,):
            # State saved before the magnetic and vertical bias rows had blocks of their own: nothing pending.
            st.aux = np.concatenate([st.aux, np.zeros(_AUX_SIZE - _AUX_SIZE_V1)])
        if st.q.shape != (4,) or st.P.shape != (4, 4) or st.bias.shape != (3,) or st.aux.shape != (_AUX_SIZE,):
            raise InputError("attitude state arrays have wrong shapes", source="attitude state")
        return st


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
        return bool(self.state.aux[_AUX_BIAS_READY] > 0)

    def set_config(self, config: AttitudeConfig) -> None:
        """Use new noise and gating parameters from the next sample on (the state is kept)."""
        self.config = config
        self._params = config.params()

    def run(self, acc_b: FloatArray, gyro_b: FloatArray | None = None, mag_b: FloatArray | None = None
            ) -> tuple[FloatArray, NDArray[np.int64]]:
        """Filter a batch of uniform samples.

        Parameters
        ----------
        acc_b, gyro_b, mag_b
            (N, 3) specific force (m/s^2), angular rate (rad/s) and magnetic field (uT), body frame;
            gyro and magnetometer may be None (the filter degrades: no gyro -> accelerometer/magnetometer
            only; no magnetometer -> yaw relative to the start).

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
        if gyro.shape != (n, 3) or mag.shape != (n, 3):
            raise InputError("gyro and mag must have the shape of acc", source="attitude")
        if n == 0:
            return np.zeros((0, 4)), np.zeros(0, dtype=np.int64)
        s = self.state
        decl = math.sin(math.radians(self.config.mag_declination_deg))
        return _run_kernel(acc, gyro, mag, gyro_b is not None, mag_b is not None, 1.0 / self.rate_hz, s.q, s.P,
                           s.bias, s.aux, self._params, self.method == "ukf", decl)

def yaw_of_axis(q_nb: FloatArray, axis_b: FloatArray) -> FloatArray:
    """Yaw (rad, CCW from east) of the horizontal projection of a body axis, per attitude (N,)."""
    v = quat.rotate(q_nb, np.broadcast_to(np.asarray(axis_b, dtype=np.float64), q_nb.shape[:-1] + (3,)))
    return np.arctan2(v[..., 1], v[..., 0])
