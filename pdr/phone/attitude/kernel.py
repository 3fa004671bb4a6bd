"""The compiled recursion of the attitude filters (numba): time update (seed 003 eqs. 6-9, 34), the UKF
measurement update (eqs. 35-40, the product's one UKF), the EKF baseline, the gyro-bias rows and the TRIAD
initialisation. The state arrays are updated in place; the layout of ``aux`` is in :mod:`.state`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel
from pdr.filters.rotation_kernels import rotate_yaw
from pdr.filters.small_linalg import (
    cholesky_lower,
    congruence,
    congruence_into,
    cross3,
    matmul,
    matmul_bt,
    matvec,
    matvec3_into,
    matvec_into,
    outer,
    solve_symmetric,
    substitute,
)
from pdr.frames import GRAVITY_MPS2
from pdr.phone.attitude.state import (
    AUX_BIAS_READY,
    AUX_BLOCK_S,
    AUX_BN,
    AUX_BR,
    AUX_CW_A,
    AUX_CW_M,
    AUX_FBAD,
    AUX_FREF,
    AUX_G,
    AUX_H_N,
    AUX_H_READY,
    AUX_H_U,
    AUX_IN_MAGNET,
    AUX_M0,
    AUX_M1,
    AUX_MAG_DYAW,
    AUX_ML,
    AUX_N,
    AUX_NO_FIELD_S,
    AUX_NU,
    AUX_P0,
    AUX_P1,
    AUX_STATIC_S,
    AUX_V0,
    AUX_V1,
    AUX_VAR_A_MEAN,
    AUX_VAR_A_SQ,
    AUX_VAR_M_MEAN,
    AUX_VAR_M_SQ,
    AUX_VAR_W_SQ,
    AUX_VS_A,
    AUX_VS_M,
    AUX_W_MEAN,
    AUX_WAS_STILL,
)

FloatArray = NDArray[np.float64]


@kernel
def _rotmat(q: FloatArray) -> FloatArray:
    """C_nb of a (not necessarily unit) quaternion, normalised first (eq. 5)."""
    c = np.empty((3, 3))
    _rotmat_into(q, c)
    return c


@kernel
def _rotmat_entries(q: FloatArray) -> tuple[float, float, float, float, float, float, float, float, float]:
    """The entries ``c00, c01, ..., c22`` (row by row) of :func:`_rotmat` as scalars (kept in registers)."""
    return _rotmat_entries_of(q[0], q[1], q[2], q[3])


@kernel
def _rotmat_entries_of(q0: float, q1: float, q2: float, q3: float
                       ) -> tuple[float, float, float, float, float, float, float, float, float]:
    """:func:`_rotmat_entries` of the quaternion ``(q0, q1, q2, q3)`` given as scalars."""
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    w, x, y, z = q0 / n, q1 / n, q2 / n, q3 / n
    return (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))


@kernel
def _rotmat_into(q: FloatArray, c: FloatArray) -> None:
    """:func:`_rotmat` into ``c`` (3, 3)."""
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = _rotmat_entries(q)
    c[0, 0], c[0, 1], c[0, 2] = c00, c01, c02
    c[1, 0], c[1, 1], c[1, 2] = c10, c11, c12
    c[2, 0], c[2, 1], c[2, 2] = c20, c21, c22


@kernel
def measurement(q: FloatArray, g_ref: FloatArray, h_ref: FloatArray, use_a: bool, use_m: bool, m: int) -> FloatArray:
    """Measurement function of eq. 10 restricted to the accepted rows: [R^T g; R^T h]."""
    out = np.empty((1, m))
    _measurement_rows(q.reshape(1, 4), g_ref, h_ref, use_a, use_m, out)
    return out[0]


@kernel
def _measurement_rows(qs: FloatArray, g_ref: FloatArray, h_ref: FloatArray, use_a: bool, use_m: bool,
                      out: FloatArray) -> None:
    """:func:`measurement` of each quaternion ``qs[i]`` ((K, 4): the UKF's sigma points) into the first columns of
    ``out[i]``.

    The quaternion's components and the rotation's entries stay scalars, read and written by index: a row view per
    sigma point (``qs[i]``, ``out[i]``), like a (3, 3) array, cost more than the arithmetic.
    """
    for i in range(qs.shape[0]):
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = _rotmat_entries_of(qs[i, 0], qs[i, 1], qs[i, 2], qs[i, 3])
        k = 0
        if use_a:
            g0, g1, g2 = g_ref[0], g_ref[1], g_ref[2]
            out[i, 0] = c00 * g0 + c10 * g1 + c20 * g2
            out[i, 1] = c01 * g0 + c11 * g1 + c21 * g2
            out[i, 2] = c02 * g0 + c12 * g1 + c22 * g2
            k = 3
        if use_m:
            h0, h1, h2 = h_ref[0], h_ref[1], h_ref[2]
            out[i, k] = c00 * h0 + c10 * h1 + c20 * h2
            out[i, k + 1] = c01 * h0 + c11 * h1 + c21 * h2
            out[i, k + 2] = c02 * h0 + c12 * h1 + c22 * h2


@kernel
def _transition(w: FloatArray, ts: float) -> FloatArray:
    """F = exp(0.5 Ts Omega(w)) (eqs. 6-7) in closed form."""
    f = np.empty((4, 4))
    _transition_into(w, ts, f, np.empty((4, 4)))
    return f


@kernel
def _transition_into(w: FloatArray, ts: float, f: FloatArray, om: FloatArray) -> None:
    """:func:`_transition` into ``f`` (4, 4), with ``om`` (4, 4) as scratch."""
    om[:, :] = 0.0
    om[0, 1], om[0, 2], om[0, 3] = -w[0], -w[1], -w[2]
    om[1, 0], om[1, 2], om[1, 3] = w[0], w[2], -w[1]
    om[2, 0], om[2, 1], om[2, 3] = w[1], -w[2], w[0]
    om[3, 0], om[3, 1], om[3, 2] = w[2], w[1], -w[0]
    nw = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    cs = math.cos(0.5 * nw * ts)
    sn = math.sin(0.5 * nw * ts) / nw if nw > 1e-12 else 0.5 * ts
    for i in range(4):
        for j in range(4):
            f[i, j] = (1.0 if i == j else 0.0) * cs + om[i, j] * sn     # I cos + Omega sin / |w|


@kernel
def _process_noise(q: FloatArray, ts: float, sigma_gyro: float) -> FloatArray:
    """W = Xi W_gyro Xi^T (eqs. 8-9), scalar-first Xi = Ts/2 [-e^T; q0 I + [e x]]."""
    out = np.empty((4, 4))
    _process_noise_into(q, ts, sigma_gyro, out, np.empty((4, 3)))
    return out


@kernel
def _process_noise_into(q: FloatArray, ts: float, sigma_gyro: float, out: FloatArray, xi: FloatArray) -> None:
    """:func:`_process_noise` into ``out`` (4, 4), with ``xi`` (4, 3) as scratch."""
    q0, e1, e2, e3 = q[0], q[1], q[2], q[3]
    xi[0, 0], xi[0, 1], xi[0, 2] = -e1, -e2, -e3
    xi[1, 0], xi[1, 1], xi[1, 2] = q0, -e3, e2
    xi[2, 0], xi[2, 1], xi[2, 2] = e3, q0, -e1
    xi[3, 0], xi[3, 1], xi[3, 2] = -e2, e1, q0
    s2 = (0.5 * ts * sigma_gyro) ** 2
    for i in range(4):
        for j in range(i + 1):
            v = s2 * (xi[i, 0] * xi[j, 0] + xi[i, 1] * xi[j, 1] + xi[i, 2] * xi[j, 2])
            out[i, j] = v
            out[j, i] = v


@kernel
def _normalise(q: FloatArray) -> None:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    s = 1.0 / n if q[0] >= 0 else -1.0 / n
    for i in range(4):
        q[i] *= s


@kernel
def _sqrt_psd(sym: FloatArray, low: FloatArray) -> FloatArray:
    """Lower Cholesky factor of the symmetric ``sym`` (into ``low``, which is returned); falls back to an
    eigen-decomposition with clipped eigenvalues (a new array).
    """
    if cholesky_lower(sym, low):
        return low
    vals, vecs = np.linalg.eigh(sym)
    for i in range(vals.size):
        vals[i] = math.sqrt(max(vals[i], 1e-18))
    return vecs * vals


@kernel
def ukf_workspace() -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray,
                             FloatArray, FloatArray, FloatArray]:
    """Scratch arrays of :func:`ukf_update_into` for up to 6 measurement rows (state dimension 4)."""
    return (np.empty((4, 4)), np.empty((4, 4)), np.empty((9, 4)), np.empty((9, 6)), np.empty(6), np.empty((6, 6)),
            np.empty((4, 6)), np.empty(6), np.empty((6, 4)), np.empty((6, 6)))


@kernel
def ukf_update(q: FloatArray, p: FloatArray, z: FloatArray, r_diag: FloatArray, g_ref: FloatArray,
                h_ref: FloatArray, use_a: bool, use_m: bool, alpha: float, beta: float, kappa: float) -> None:
    """Unscented measurement update (eqs. 35-40), in place."""
    ukf_update_into(q, p, z, r_diag, g_ref, h_ref, use_a, use_m, alpha, beta, kappa, ukf_workspace())


@kernel
def ukf_update_into(q: FloatArray, p: FloatArray, z: FloatArray, r_diag: FloatArray, g_ref: FloatArray,
                    h_ref: FloatArray, use_a: bool, use_m: bool, alpha: float, beta: float, kappa: float,
                    ws: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray,
                              FloatArray, FloatArray, FloatArray]) -> None:
    """:func:`ukf_update` with the scratch arrays ``ws`` of :func:`ukf_workspace` (no allocation unless the
    covariance needs the eigen-decomposition or the innovation covariance the LU fallback).
    """
    n = 4
    m = z.size
    sym, low, sig, zs_ws, zm_ws, pzz_ws, pqz_ws, dz, kt_ws, l_ws = ws
    zs, zm, pzz, pqz = zs_ws[:, :m], zm_ws[:m], pzz_ws[:m, :m], pqz_ws[:, :m]
    lam = alpha * alpha * (n + kappa) - n
    c = n + lam
    for i in range(n):
        for j in range(n):
            sym[i, j] = 0.5 * (c * p[i, j] + c * p[j, i])
    s = _sqrt_psd(sym, low)
    for j in range(n):
        sig[0, j] = q[j]
    for i in range(n):
        for j in range(n):
            sig[1 + i, j] = q[j] + s[j, i]
            sig[1 + n + i, j] = q[j] - s[j, i]
    wm0 = lam / c
    wc0 = wm0 + (1.0 - alpha * alpha + beta)
    wi = 0.5 / c
    _measurement_rows(sig, g_ref, h_ref, use_a, use_m, zs)
    # eq. 38: predicted mean. The centre point is subtracted first to avoid cancellation of the
    # large weights (wm0 is about -1e6 for alpha = 1e-3).
    for a in range(m):
        zm[a] = zs[0, a]
    for i in range(1, 2 * n + 1):
        for a in range(m):
            zm[a] += wi * (zs[i, a] - zs[0, a])
    pzz[:, :] = 0.0
    pqz[:, :] = 0.0
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
    # K^T = P_zz^-1 P_qz^T (eq. 39): by Cholesky, or by LU when it fails (as solve_symmetric).
    if cholesky_lower(pzz, l_ws[:m, :m]):
        kt = kt_ws[:m]
        for b in range(m):
            for j in range(n):
                kt[b, j] = pqz[j, b]
        substitute(l_ws[:m, :m], kt)
    else:
        kt = np.linalg.solve(pzz, pqz.T)  # type: ignore[assignment]  # float64 in, float64 out
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


@kernel
def ekf_update(q: FloatArray, p: FloatArray, z: FloatArray, r_diag: FloatArray, g_ref: FloatArray,
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
        h[:, j] = (measurement(qp, g_ref, h_ref, use_a, use_m, m)
                   - measurement(qm, g_ref, h_ref, use_a, use_m, m)) / (2 * eps)
    zm = measurement(q, g_ref, h_ref, use_a, use_m, m)
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


@kernel
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
    c0, c1, c2 = cross3(u, w_raw)
    aux[cw] += ks * (c0 - aux[cw])
    aux[cw + 1] += ks * (c1 - aux[cw + 1])
    aux[cw + 2] += ks * (c2 - aux[cw + 2])
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


@kernel
def _vertical_rows(aux: FloatArray, o: int, w_raw: FloatArray, ts: float) -> None:
    """Add the row ``us^T b = us^T omega_raw`` (``us`` the low-passed unit specific force, i.e. up in the body
    frame) to the pending block at ``aux[o:o + 12]``: a standing user's device does not turn about the
    vertical on average, so there the gyro mean is the bias. It completes the gravity rows (rank 2, blind to
    this component): their normal matrices add up to ``|us|^2 I``.
    """
    s0, s1, s2 = aux[AUX_VS_A], aux[AUX_VS_A + 1], aux[AUX_VS_A + 2]
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


@kernel
def _field_invariants(aux: FloatArray) -> tuple[float, float]:
    """Vertical and horizontal components (uT) of the low-passed field relative to the low-passed gravity
    direction: the two quantities a device rotation leaves unchanged while the field is fixed in the navigation
    frame (the magnitude and dip of eq. 13).
    """
    s0, s1, s2 = aux[AUX_VS_A], aux[AUX_VS_A + 1], aux[AUX_VS_A + 2]
    nn = max(math.sqrt(s0 * s0 + s1 * s1 + s2 * s2), 1e-9)
    m0, m1, m2 = aux[AUX_ML], aux[AUX_ML + 1], aux[AUX_ML + 2]
    v = (m0 * s0 + m1 * s1 + m2 * s2) / nn
    h2 = m0 * m0 + m1 * m1 + m2 * m2 - v * v
    return v, math.sqrt(max(h2, 0.0))


@kernel
def _commit_block(aux: FloatArray, bias: FloatArray, has_mag: bool, fb: float, bias_prior: float) -> None:
    """Add the older pending block of bias rows (gravity rows, and the field's rows if neither block saw the field
    move, else the vertical mean-gyro rows) to the forgotten normal equations (factor ``fb``), move the newer
    block into its place, and solve for the gyro bias (ridge ``bias_prior`` towards zero), in place.
    """
    mag_ok = has_mag and aux[AUX_FBAD] == 0 and aux[AUX_FBAD + 1] == 0
    extra = AUX_M0 if mag_ok else AUX_V0
    for i in range(12):
        aux[AUX_BN + i] = fb * aux[AUX_BN + i] + aux[AUX_P0 + i] + aux[extra + i]
        aux[AUX_P0 + i] = aux[AUX_P1 + i]
        aux[AUX_M0 + i] = aux[AUX_M1 + i]
        aux[AUX_V0 + i] = aux[AUX_V1 + i]
        aux[AUX_P1 + i] = 0.0
        aux[AUX_M1 + i] = 0.0
        aux[AUX_V1 + i] = 0.0
    if aux[AUX_BN] + aux[AUX_BN + 4] + aux[AUX_BN + 8] > 0:
        nm = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                nm[i, j] = aux[AUX_BN + 3 * i + j] + (bias_prior if i == j else 0.0)
        rhs = np.empty(3)
        for i in range(3):
            rhs[i] = aux[AUX_BR + i]
        sol = np.linalg.solve(nm, rhs)
        for i in range(3):
            bias[i] = sol[i]


def _filter_kernel(unscented: bool) -> Any:
    """The filter's loop (:func:`run_kernel`) compiled with one measurement update: the UKF's (``unscented``) or the
    EKF's. ``unscented`` is a constant of the closure, so numba drops the other update's branch before it types the
    loop and compiles only the update in use (the EKF's, with its ``np.linalg`` and ``@``, took about 6 s of a fresh
    install's first compile); numba's cache tells the two apart by the closure's value.
    """
    @kernel
    def run(acc: FloatArray, gyro: FloatArray, mag: FloatArray, has_gyro: bool, has_mag: bool, ts: float,
            q: FloatArray, p: FloatArray, bias: FloatArray, aux: FloatArray, prm: FloatArray,
            h_east: float, carried: NDArray[np.bool_]) -> tuple[FloatArray, NDArray[np.int64]]:
        """:func:`run_kernel` with the update of ``unscented``."""
        sigma_gyro, sigma_a, sigma_m = prm[0], prm[1], prm[2]
        eps_a1, eps_a2, eps_m1, eps_m2, eps_dip = prm[3], prm[4], prm[5], prm[6], prm[7]
        var_tau, alpha, beta, kappa = prm[8], prm[9], prm[10], prm[11]
        static_gyro_std, static_acc_std, static_min_s = prm[12], prm[13], prm[14]
        bias_tau, bias_smooth, bias_prior, gravity_tau = prm[15], prm[16], prm[17], prm[18]
        mag_ref_tau, mag_when_static, init_yaw_sigma, static_mag_std = prm[19], prm[20] > 0.5, prm[21], prm[22]
        bias_hold_s, bias_field, bias_dip = prm[23], prm[24], prm[25]
        mag_yaw_only = prm[26] > 0.5
        earth_max = prm[27]
        sigma_a_moving = prm[28]
        mag_bias_gain = prm[29]
        k_nu = ts / (prm[30] + ts)
        nu_steady = prm[31]
        undo_keep = math.exp(-ts / prm[32]) if prm[32] > 0 else 0.0
        magnet_rise = prm[33]
        earth_dip = prm[34]                 # NaN: unknown (AttitudeConfig.earth_dip_deg)
        stand_bias = prm[35]
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
        # Scratch arrays, allocated once per call (the loop below allocates nothing in the common case).
        u = np.empty(3)
        f = np.empty((4, 4))
        om = np.empty((4, 4))
        wq = np.empty((4, 4))
        xi = np.empty((4, 3))
        fp = np.empty((4, 4))
        pn = np.empty((4, 4))
        qn = np.empty(4)
        q_prior = np.empty(4)
        z_ws = np.empty(6)
        r_ws = np.empty(6)
        ws = ukf_workspace()
        c33 = np.empty((3, 3))
        hn_ws = np.empty(3)
        for k in range(n):
            a = acc[k]
            an = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            # Trailing exponential mean and variance of |a|, |m| and the gyro (eqs. 12-13, causal windows).
            if aux[AUX_N] == 0:
                aux[AUX_VAR_A_MEAN] = an
                aux[AUX_VAR_A_SQ] = 0.0
                for i in range(3):
                    aux[AUX_W_MEAN + i] = gyro[k, i]
                    aux[AUX_VS_A + i] = a[i] / max(an, 1e-9)
                aux[AUX_VAR_W_SQ] = 0.0
            da = an - aux[AUX_VAR_A_MEAN]
            aux[AUX_VAR_A_MEAN] += ka * da
            aux[AUX_VAR_A_SQ] = (1 - ka) * (aux[AUX_VAR_A_SQ] + ka * da * da)
            dw2 = 0.0
            for i in range(3):
                dw = gyro[k, i] - aux[AUX_W_MEAN + i]
                aux[AUX_W_MEAN + i] += ka * dw
                dw2 += dw * dw
            aux[AUX_VAR_W_SQ] = (1 - ka) * (aux[AUX_VAR_W_SQ] + ka * dw2)
            mn = 0.0
            if has_mag:
                mv = mag[k]
                mn = math.sqrt(mv[0] * mv[0] + mv[1] * mv[1] + mv[2] * mv[2])
                if aux[AUX_N] == 0:
                    aux[AUX_VAR_M_MEAN] = mn
                    aux[AUX_VAR_M_SQ] = 0.0
                    for i in range(3):
                        aux[AUX_VS_M + i] = mv[i] / max(mn, 1e-9)
                if aux[AUX_N] == 0 or (aux[AUX_ML] == 0 and aux[AUX_ML + 1] == 0 and aux[AUX_ML + 2] == 0):
                    for i in range(3):
                        aux[AUX_ML + i] = mv[i]
                for i in range(3):
                    aux[AUX_ML + i] += ks * (mv[i] - aux[AUX_ML + i])
                dm = mn - aux[AUX_VAR_M_MEAN]
                aux[AUX_VAR_M_MEAN] += ka * dm
                aux[AUX_VAR_M_SQ] = (1 - ka) * (aux[AUX_VAR_M_SQ] + ka * dm * dm)
            if aux[AUX_N] == 0:
                # Initial attitude: tilt from gravity, yaw from the magnetic field (TRIAD) or zero.
                _init_attitude(q, a, mag[k] if has_mag else np.zeros(3), has_mag, h_east)
                aux[AUX_G] = GRAVITY_MPS2
            aux[AUX_N] += 1
            quasi_static = abs(an - aux[AUX_G]) < eps_a1 and aux[AUX_VAR_A_SQ] < eps_a2
            # Stationary user (for the gyro bias): quasi-static, small trailing spread of |a| and of the gyro.
            still = (quasi_static and aux[AUX_VAR_A_SQ] < static_acc_std * static_acc_std
                     and aux[AUX_VAR_W_SQ] < static_gyro_std * static_gyro_std)
            if has_mag:
                still = still and aux[AUX_VAR_M_SQ] < static_mag_std * static_mag_std
            if still:
                aux[AUX_STATIC_S] += ts
            else:
                aux[AUX_STATIC_S] = 0.0
            stationary = aux[AUX_STATIC_S] >= static_min_s
            # A stand that calibrates the gyro: not in a moving cabin, which carries the user through the building's
            # field (the field's rows would take its change for a turn) and in which the user may turn slowly (the
            # stillness tests see the spread of the rate, not its mean).
            calibrating = stationary and not carried[k]
            period_start = calibrating and aux[AUX_WAS_STILL] == 0
            period_end = not calibrating and aux[AUX_WAS_STILL] > 0
            aux[AUX_WAS_STILL] = 1.0 if calibrating else 0.0
            if has_gyro:
                # Gyro bias by least squares over the calibrating stands (not in a moving cabin, ``carried``).
                # Gravity is fixed in the navigation frame while the user stands; the local magnetic field only while
                # the field does not move (the stand's disturbance test below), and only then may its rows set the
                # bias component about the vertical. Otherwise that component comes from the gyro alone (at rest the
                # mean of the gyro about the vertical is the bias).
                d = max(an, 1e-9)
                for i in range(3):
                    u[i] = a[i] / d
                _bias_rows(aux, AUX_VS_A, AUX_CW_A, u, gyro[k], ks, ts, calibrating, 1.0, AUX_P1)
                if has_mag:
                    d = max(mn, 1e-9)
                    for i in range(3):
                        u[i] = mag[k, i] / d
                    _bias_rows(aux, AUX_VS_M, AUX_CW_M, u, gyro[k], ks, ts, calibrating, 1.0, AUX_M1)
                if stationary:
                    used[k] |= 4
                if calibrating:
                    _vertical_rows(aux, AUX_V1, gyro[k], ts)
                    if has_mag:
                        # Magnetic-disturbance test of eq. 13 for the bias rows: a field fixed in the navigation frame
                        # keeps its magnitude and dip relative to gravity, i.e. its vertical and horizontal components,
                        # under any rotation of the device. A departure from the values at the start of the stationary
                        # period by more than the stillness spread of |m| marks the field as moving for the rest of
                        # the period (a slowly moving field may stay within a single block's spread).
                        fv, fh = _field_invariants(aux)
                        if period_start:
                            aux[AUX_FREF], aux[AUX_FREF + 1] = fv, fh
                            aux[AUX_FBAD + 2] = 0.0
                        elif (abs(math.hypot(fv, fh) - math.hypot(aux[AUX_FREF], aux[AUX_FREF + 1])) > bias_field
                              or abs(math.atan2(fv, fh) - math.atan2(aux[AUX_FREF], aux[AUX_FREF + 1])) > bias_dip):
                            aux[AUX_FBAD + 2] = 1.0
                        if aux[AUX_FBAD + 2] > 0 or aux[AUX_VAR_W_SQ] < 3.0 * sigma_gyro * sigma_gyro:
                            # Disturbed field, or a device that does not rotate (gyro spread within its white
                            # noise, eq. 9): there the gyro mean about the vertical is the bias and the field's
                            # rows would only add its changes (a cabin carried through the building's field).
                            aux[AUX_FBAD + 1] = 1.0
                    aux[AUX_G] += kg * (an - aux[AUX_G])
                    aux[AUX_BLOCK_S] += ts
                    if aux[AUX_BLOCK_S] >= bias_hold_s:
                        # Rows are committed one block late: the trailing detectors notice the end of a
                        # stationary period (first step, phone lifted) only after a delay, and the rows of that
                        # delay (linear acceleration) must not enter the bias. Likewise a field that starts to move
                        # is noticed late: the older block's magnetic rows count only if neither block saw it move.
                        _commit_block(aux, bias, has_mag, decay ** (aux[AUX_BLOCK_S] / ts), bias_prior)
                        aux[AUX_FBAD] = aux[AUX_FBAD + 1]
                        aux[AUX_FBAD + 1] = aux[AUX_FBAD + 2]
                        aux[AUX_BLOCK_S] = 0.0
                else:
                    if aux[AUX_BLOCK_S] >= var_tau:
                        # End of standing after a partial block at least as long as the detectors' trailing window
                        # (time constant var_window_s, within which they notice the first step): the delay's rows
                        # lie in the partial block, so the complete block before it is clean and enters now. (A
                        # stand of just under two blocks, e.g. the opening stand of a walk, otherwise left no bias.)
                        _commit_block(aux, bias, has_mag, decay ** (aux[AUX_BLOCK_S] / ts), bias_prior)
                    for o in (AUX_P0, AUX_M0, AUX_V0):
                        for i in range(24):
                            aux[o + i] = 0.0
                    for i in range(3):
                        aux[AUX_FBAD + i] = 0.0
                    aux[AUX_BLOCK_S] = 0.0
                if period_end and aux[AUX_BIAS_READY] == 0 and aux[AUX_BN] + aux[AUX_BN + 4] + aux[AUX_BN + 8] > 0:
                    # End of the first stationary period that gave the gyro bias rows (a stand too short to complete
                    # a block gives none): the bias is now known, but the yaw propagated before it (with an unknown
                    # bias, through the calibration motion) is not; reopen it so the walk's magnetometer rows set it.
                    if has_mag:
                        _set_yaw_covariance(q, p, init_yaw_sigma)
                    aux[AUX_BIAS_READY] = 1.0
                # Time update (eqs. 6-9, 34).
                for i in range(3):
                    w[i] = gyro[k, i] - bias[i]
                _transition_into(w, ts, f, om)
                _process_noise_into(q, ts, sigma_gyro, wq, xi)     # from the prior q (eq. 9)
                congruence_into(f, p, fp, pn)
                for i in range(4):
                    for j in range(4):
                        p[i, j] = pn[i, j] + wq[i, j]
                matvec_into(f, q, qn)
                q[:] = qn
                if stand_bias > 0 and stationary and aux[AUX_H_READY] == 1:
                    # A stand gives the yaw no field rows (mag_when_static), and the gyro's residual bias turns it by
                    # up to b T over T seconds: the yaw's variance grows to (b T)^2 (AttitudeConfig.stand_bias_dps).
                    t_gap = aux[AUX_NO_FIELD_S]
                    _add_yaw_variance(q, p, stand_bias * stand_bias * (2.0 * t_gap + ts) * ts)
                    aux[AUX_NO_FIELD_S] = t_gap + ts
            else:
                # Without a gyro the attitude is a random walk driven by a large rate noise.
                _process_noise_into(q, ts, 1.0, wq, xi)
                for i in range(4):
                    for j in range(4):
                        p[i, j] += wq[i, j]
            for i in range(4):
                p[i, i] += 1e-12
            # Accept rows of the measurement model (eqs. 12-13).
            use_a = quasi_static or not has_gyro or sigma_a_moving > 0
            use_m = False
            stronger = False
            if has_mag:
                mv = mag[k]
                if aux[AUX_H_READY] == 0 and quasi_static:
                    # At the first quasi-static sample: re-initialise the attitude (TRIAD) and take the
                    # reference field in ENU from it; the yaw is uncertain by init_yaw_sigma.
                    _init_attitude(q, a, mv, True, h_east)
                    c = _rotmat(q)
                    hn = c @ mv
                    aux[AUX_H_N] = math.sqrt(hn[0] * hn[0] + hn[1] * hn[1])
                    aux[AUX_H_U] = hn[2]
                    aux[AUX_H_READY] = 1
                    _set_yaw_covariance(q, p, init_yaw_sigma)
                if aux[AUX_H_READY] == 1:
                    href_n = math.sqrt(aux[AUX_H_N] ** 2 + aux[AUX_H_U] ** 2)
                    dip_ref = math.atan2(-aux[AUX_H_U], aux[AUX_H_N])
                    c = c33
                    _rotmat_into(q, c)
                    hn = hn_ws
                    matvec3_into(c, mv, hn)         # c @ mv
                    dip = math.atan2(-hn[2], math.sqrt(hn[0] * hn[0] + hn[1] * hn[1]))
                    use_m = (abs(mn - href_n) < eps_m1 and aux[AUX_VAR_M_SQ] < eps_m2 and abs(dip - dip_ref) < eps_dip
                             and mn <= earth_max and not abs(dip - earth_dip) >= eps_dip)
                    stronger = mn > href_n + magnet_rise
                    if undo_keep > 0:
                        # A field stronger than the earth's: the rows of the seconds before saw it coming and turned
                        # the yaw with it; take that turn back (AttitudeConfig.magnet_undo_tau_s).
                        magnet = mn > earth_max
                        if magnet and aux[AUX_IN_MAGNET] == 0:
                            rotate_yaw(q, -aux[AUX_MAG_DYAW])
                            aux[AUX_MAG_DYAW] = 0.0
                        aux[AUX_IN_MAGNET] = 1.0 if magnet else 0.0
                        aux[AUX_MAG_DYAW] *= undo_keep
                    if stationary and not mag_when_static:
                        use_m = False
                    if k_ref > 0 and not stationary:
                        # The reference magnitude and dip follow the measured field slowly (innovations clipped).
                        nn = min(href_n + k_ref * max(-3 * eps_m1, min(3 * eps_m1, mn - href_n)), earth_max)
                        dd = dip_ref + k_ref * max(-3 * eps_dip, min(3 * eps_dip, dip - dip_ref))
                        aux[AUX_H_N] = nn * math.cos(dd)
                        aux[AUX_H_U] = -nn * math.sin(dd)
                    if (use_m and has_gyro and mag_bias_gain > 0 and not stationary
                            and hn[0] * hn[0] + hn[1] * hn[1] > 1e-12):
                        # The gyro's residual bias about the vertical from the field's yaw innovations (the integral
                        # term of a complementary filter, AttitudeConfig.mag_bias_gain): a bias b turns the estimate by
                        # b per second counter-clockwise, so the field seen through it turns clockwise (a negative
                        # innovation), steadily; a disturbance turns it back and forth as the user walks through it.
                        nu = _field_yaw_innovation(hn, h_east)
                        dn = nu - aux[AUX_NU]
                        aux[AUX_NU] += k_nu * dn
                        aux[AUX_NU + 1] = (1 - k_nu) * (aux[AUX_NU + 1] + k_nu * dn * dn)
                        if aux[AUX_NU + 1] < nu_steady * nu_steady:
                            for i in range(3):
                                bias[i] -= mag_bias_gain * nu * ts * c[2, i]     # c[2]: up in the device frame
            # The field's rows on the yaw alone when so configured (AttitudeConfig.mag_yaw_only), after the
            # accelerometer's.
            yaw_row = use_m and mag_yaw_only
            if yaw_row:
                use_m = False
                used[k] |= 2
            # The rows' turn counts while the field is stronger than the reference: what a magnet being approached does.
            field_turn = undo_keep > 0 and (use_m or yaw_row) and stronger
            if field_turn:
                q_prior[:] = q
            if use_a or use_m:
                m = 3 * (int(use_a) + int(use_m))
                z = z_ws[:m]
                r = r_ws[:m]
                j = 0
                if use_a:
                    g_ref[0], g_ref[1], g_ref[2] = 0.0, 0.0, aux[AUX_G]
                    sa = sigma_a if quasi_static else (sigma_a_moving if has_gyro else 10.0 * sigma_a)
                    for i in range(3):
                        z[i] = a[i]
                        r[i] = sa * sa
                    j = 3
                    used[k] |= 1
                if use_m:
                    # Magnetic north rotated by the declination (east positive) from true north.
                    h_ref[0] = aux[AUX_H_N] * h_east
                    h_ref[1] = aux[AUX_H_N] * math.sqrt(max(0.0, 1 - h_east * h_east))
                    h_ref[2] = aux[AUX_H_U]
                    for i in range(3):
                        z[j + i] = mag[k, i]
                        r[j + i] = sigma_m * sigma_m
                    used[k] |= 2
                if unscented:
                    ukf_update_into(q, p, z, r, g_ref, h_ref, use_a, use_m, alpha, beta, kappa, ws)
                else:
                    ekf_update(q, p, z, r, g_ref, h_ref, use_a, use_m)
            else:
                _normalise(q)
            if yaw_row:
                mag_yaw_update(q, p, mag[k], h_east, sigma_m)
            if use_m or yaw_row:
                aux[AUX_NO_FIELD_S] = 0.0
            if field_turn:
                # The yaw this sample's field rows turned the attitude by: dq = 0.5 dpsi g (mag_yaw_update).
                aux[AUX_MAG_DYAW] += 2.0 * (-q_prior[3] * (q[0] - q_prior[0]) - q_prior[2] * (q[1] - q_prior[1])
                                            + q_prior[1] * (q[2] - q_prior[2]) + q_prior[0] * (q[3] - q_prior[3]))
            out[k] = q
        return out, used

    return run


#: The filter's loop with the UKF's and with the EKF's measurement update (:func:`_filter_kernel`).
run_ukf = _filter_kernel(True)
run_ekf = _filter_kernel(False)


def run_kernel(acc: FloatArray, gyro: FloatArray, mag: FloatArray, has_gyro: bool, has_mag: bool, ts: float,
               q: FloatArray, p: FloatArray, bias: FloatArray, aux: FloatArray, prm: FloatArray,
               unscented: bool, h_east: float, carried: NDArray[np.bool_]) -> tuple[FloatArray, NDArray[np.int64]]:
    """Run the filter over uniform samples; state arrays are updated in place. ``carried`` (N,): the user is carried
    vertically (a moving cabin), so a stand there gives no gyro bias rows. ``unscented``: the UKF's measurement
    update (seed 003), else the EKF baseline's (:func:`_filter_kernel`).

    Returns the (N, 4) posterior attitudes and (N,) bit flags (USED_ACC, USED_MAG, STATIONARY).
    """
    return (run_ukf if unscented else run_ekf)(acc, gyro, mag, has_gyro, has_mag, ts, q, p, bias, aux, prm, h_east,
                                                carried)


@kernel
def _field_yaw_innovation(h_n: FloatArray, h_east: float) -> float:
    """Azimuth (rad, clockwise from north, in [-pi, pi)) of the field ``h_n`` (uT, ENU: the measured field carried
    into the navigation frame by the current attitude) less the reference's (magnetic north turned by the
    declination, ``h_east`` its east component).
    """
    az_ref = math.atan2(h_east, math.sqrt(max(0.0, 1 - h_east * h_east)))
    return (math.atan2(h_n[0], h_n[1]) - az_ref + math.pi) % (2 * math.pi) - math.pi


@kernel
def mag_yaw_update(q: FloatArray, p: FloatArray, m_b: FloatArray, h_east: float, sigma_m: float) -> None:
    """The magnetometer's row on the yaw alone, in place (``AttitudeConfig.mag_yaw_only``).

    The innovation is the azimuth (rad) of the measured field ``m_b`` (uT, device frame) carried into the navigation
    frame by the current attitude, less the reference's (magnetic north turned by the declination, ``h_east`` its
    east component); its noise is ``sigma_m`` (uT, eq. 13) over the field's horizontal magnitude. The row acts
    along the rotation about up, ``dq = 0.5 dpsi g`` with ``g = [0, 0, 0, 1] * q`` (so ``dpsi = 2 g . dq``), a
    linear Kalman update of ``q`` and ``P`` that leaves the tilt to gravity.
    """
    c = _rotmat(q)
    hn = c @ m_b
    hh = math.sqrt(hn[0] * hn[0] + hn[1] * hn[1])
    if hh < 1e-6:
        return
    nu = _field_yaw_innovation(hn, h_east)
    g = np.array(_yaw_direction(q))
    h = 2.0 * g
    ph = p @ h
    s = h @ ph + (sigma_m / hh) ** 2
    gain = ph / s
    for i in range(4):
        q[i] += gain[i] * nu
    _normalise(q)
    pn = p - outer(gain, ph)
    p[:, :] = 0.5 * (pn + pn.T)


@kernel
def _yaw_direction(q: FloatArray) -> tuple[float, float, float, float]:
    """``g = [0, 0, 0, 1] * q``: the direction in which a rotation ``dpsi`` (rad) about the navigation up axis moves
    ``q_nb``, ``dq = 0.5 dpsi g`` (a tuple: no allocation).
    """
    return -q[3], -q[2], q[1], q[0]


@kernel
def _set_yaw_covariance(q: FloatArray, p: FloatArray, sigma_yaw: float) -> None:
    """Covariance of ``q`` for a yaw uncertainty ``sigma_yaw`` (rad) about the navigation up axis, tilt kept.

    A rotation ``dpsi`` about up moves ``q`` by ``0.5 [0, 0, 0, dpsi] * q = 0.5 dpsi g`` with
    ``g = [0, 0, 0, 1] * q``; the tilt part of the existing covariance is kept.
    """
    g = np.array(_yaw_direction(q))
    pg = p @ g
    gpg = g @ pg
    # Remove the existing variance along g, then add the new one.
    pn = p - outer(pg, pg) / max(gpg, 1e-18) + 0.25 * sigma_yaw * sigma_yaw * outer(g, g)
    p[:, :] = 0.5 * (pn + pn.T)


@kernel
def _add_yaw_variance(q: FloatArray, p: FloatArray, var_yaw: float) -> None:
    """Add ``var_yaw`` (rad^2) to the covariance of ``q`` along the rotation about the navigation up axis, in place
    (``dq = 0.5 dpsi g``, ``g = [0, 0, 0, 1] * q``, as :func:`_set_yaw_covariance`).
    """
    g = _yaw_direction(q)
    c = 0.25 * var_yaw
    for i in range(4):
        for j in range(4):
            p[i, j] += c * g[i] * g[j]


@kernel
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
    # cross3, not numba's np.cross, which would make loading this kernel from the cache import numba's array-math
    # module (0.25-0.4 s of a process's start).
    east = np.array(cross3(north, up))
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
