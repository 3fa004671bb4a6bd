"""Context-aided inertial navigation by belief condensation (seed 000).

State (Sec. II.A, 22 numbers): position ``p``, velocity ``v`` and acceleration ``a`` (m, m/s, m/s^2, ENU),
attitude quaternion ``q`` (4), angular rate ``omega`` (rad/s) and the accelerometer and gyroscope biases
``b = [b_f, b_omega]``. Its uncertainty is a Gaussian over the 21-dimensional error state (the quaternion's
error is a 3-vector rotation, ``q_true = exp(dtheta) q``).

* Dynamic model (eqs. 2-4): constant acceleration for ``(p, v, a)`` (eq. 2), attitude driven by the angular
  rate held over the interval (eq. 3), constant angular rate and random-walk biases (eq. 4), with the process
  noise of Table I.
* Measurement model (eqs. 5-6): the accelerometer measures ``C(q)^T (a - g) + b_f`` and the gyroscope
  ``omega + b_omega``; linearised (an EKF update), as the seed does for eq. 3 (Appendix B).
* Context (eqs. 7-9, 16-17): the potential ``f(c | x) = sum_i alpha_i N(P x; mu_i, Sigma_i)`` over
  ``P x = [v, a, omega]`` (9 numbers). The expert model (eq. 17, Sec. V.B) has two zero-mean components:
  stance with standard deviations 0.05 m/s, 0.3 m/s^2, 0.2 rad/s and swing with 2.5 m/s, 7.5 m/s^2, 2 rad/s,
  ``alpha = 0.5``. :func:`learn_context` fits an m-component model by EM to states of a conventional ZUPT run
  (Sec. V.C), initialised from the expert model.
* Belief condensation (Algorithm 2, eqs. 13-15): the posterior ``f(y|x) f(c|x) pi^+`` is replaced by the
  Gaussian with its mean and covariance (KL projection, eq. 13). With a Gaussian ``pi^+`` (after the
  linearised measurement update) and a potential that is a Gaussian mixture in a linear function of the
  state, the integrals of eqs. 14-15 are exact and closed-form: the product is a mixture of Gaussians, each a
  Kalman update of ``pi^+`` by the "measurement" ``P x = mu_i`` with noise ``Sigma_i``, weighted by
  ``alpha_i N(mu_i; P mu, P Sigma P^T + Sigma_i)``; its moments are those of eqs. 14-15. The broadest
  component (the swing) is weighted so but pulls nothing (:attr:`BCConfig.background`).

Deviation from the text: the angular rate is kept in the body frame (the gyroscope's, so that eq. 6 holds as
written); the context's Gaussian components are isotropic per quantity, so the frame does not change them.

Noise values for real foot IMUs (issue #5; :class:`BCConfig` documents each): Table I belongs to the seed's
100 Hz XSens walks ("dynamic-related values roughly 50 % of their maximum, measurement-related values from
specification", Sec. VI). On the 200 Hz LORD IMUs of PyShoe and foot_stride_gcp they made the filter diverge
(:meth:`BCConfig.table_i` on PyShoe): heel strikes far beyond the Table I jerk went into the tilt, a loose attitude
process noise let accelerometer and context residuals re-fit the attitude at every sample, and a free gyroscope
bias learnt the foot's rolling in stance. The defaults apply the seed's own rules to these IMUs (jerk at half
the measured maximum, the exactly discretised white-jerk model, gyroscope noise from the data sheet, no
gyroscope bias state as in seed 001); :meth:`BCConfig.table_i` keeps Table I.

Against the ZUPT-aided INS (``pdr eval foot /work/shared/data --method all --hde on --smoother both`` prints the
figures): the seed compares with a conventional ZUPT filter, whose detector has one fixed threshold (row
``zupt/plain``, the best single threshold for the PyShoe trials). Belief condensation ties with it on PyShoe (a
lower median ARMSE, lower on half the trials, the paired test inconclusive) and beats it on foot_stride_gcp; the
gait-adaptive detector of :mod:`pdr.foot.detectors` beats both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import quat_exp, quat_mul, rotate_yaw, rotmat
from pdr.filters.small_linalg import congruence, matmul, matmul_bt, matvec, quadratic_form, symmetric_inverse
from pdr.foot.drift import drift_predict, drift_update, initial_state
from pdr.foot.saturation import CLIP_EXCESS_FRACTION, add_clip_attitude_noise, clip_variance, clip_variance_peak
from pdr.foot.zupt import ZuptConfig, check_imu, coarse_start
from pdr.frames import GRAVITY_MPS2

Array = NDArray[np.float64]

# Error-state layout (21): dp, dv, da, dtheta, domega, db_f, db_omega.
P_, V_, A_, TH, W_, BF, BW = 0, 3, 6, 9, 12, 15, 18
N_ERR = 21
#: Context variables P x = [v, a, omega] (9).
N_CTX = 9


@dataclass(frozen=True)
class ContextModel:
    """Gaussian-mixture context potential over ``[v, a, omega]`` (seed 000 eq. 9).

    Attributes
    ----------
    weights
        (m,) mixture weights ``alpha_i`` (sum 1).
    means
        (m, 9) component means ``mu_i`` (m/s, m/s^2, rad/s).
    sds
        (m, 9) component standard deviations (diagonal ``Sigma_i``).
    """

    weights: Array
    means: Array
    sds: Array

    def __post_init__(self) -> None:
        w = np.asarray(self.weights, dtype=np.float64).reshape(-1)
        mu = np.asarray(self.means, dtype=np.float64)
        sd = np.asarray(self.sds, dtype=np.float64)
        m = w.size
        if m < 1 or mu.shape != (m, N_CTX) or sd.shape != (m, N_CTX):
            raise InputError(f"need m weights and (m, {N_CTX}) means and standard deviations", field="context")
        if not (np.all(np.isfinite(w)) and np.all(w >= 0) and abs(w.sum() - 1.0) < 1e-6):
            raise InputError("mixture weights must be non-negative and sum to 1", field="context.weights")
        if not (np.all(np.isfinite(mu)) and np.all(np.isfinite(sd)) and np.all(sd > 0)):
            raise InputError("means must be finite and standard deviations positive", field="context.sds")
        for name, arr in (("weights", w), ("means", mu), ("sds", sd)):
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @classmethod
    def expert(cls, alpha: float = 0.5) -> ContextModel:
        """The two-component stance/swing model of Sec. V.B (eq. 17)."""
        stance = np.repeat([0.05, 0.3, 0.2], 3)
        swing = np.repeat([2.5, 7.5, 2.0], 3)
        return cls(np.array([alpha, 1.0 - alpha]), np.zeros((2, N_CTX)), np.stack([stance, swing]))


#: Values of :attr:`BCConfig.background` and :attr:`BCConfig.clip_model`.
BACKGROUNDS: tuple[str, ...] = ("scored", "divided", "applied")
CLIP_MODELS: tuple[str, ...] = ("peak", "constant", "off")


@dataclass(frozen=True)
class BCConfig:
    """Noise model of the belief-condensation filter (seed 000 Table I) and its context.

    Attributes
    ----------
    jerk_psd
        Power spectral density ``q`` of the white jerk that drives the constant-acceleration model (eq. 2),
        (m/s^3)^2 s: the acceleration variance grows by ``q dt`` per step, as the ``Sigma^{d,1}`` of Table I.
        Table I's 275 is "roughly 50 % of the maximum" (Sec. VI) of the seed's 100 Hz XSens walks; a real
        heel strike changes the specific force by 20-50 m/s^2 within one 5 ms sample (PyShoe and
        foot_stride_gcp, 200 Hz: jerks up to 1.4e4 m/s^3), and half of that maximum is ``(25 m/s^2)^2 / 5 ms
        = 1.25e5``. With 275 an impact cannot be followed by the acceleration state and the accelerometer
        update (eq. 5) puts a large part of it into the tilt: a 20 degree tilt error, a phantom 4 m/s^2
        horizontal acceleration and a velocity that runs away (the divergence of issue #5).
    exact_jerk
        Discretise the white jerk exactly (Bar-Shalom's white-noise-jerk model, the seed's ref. [36]): the
        full correlated ``q [[dt^5/20, dt^4/8, dt^3/6], [dt^4/8, dt^3/3, dt^2/2], [dt^3/6, dt^2/2, dt]]``.
        Table I writes only a diagonal ``q (dt^3/6, dt^2/2, dt)``, i.e. an extra velocity random walk of
        ``q dt / 2`` (m/s)^2 per second that no measurement observes: with the ``q`` of real heel strikes it
        is 300 (m/s)^2/s and the swing velocity becomes as uncertain as the swing component of the context,
        which then cannot recognise the next stance. ``False`` gives Table I's diagonal.
    sigma_quat
        Table I ``Sigma^{d,2} = sigma_quat dt^2 / 2`` per quaternion component (1/s^2); the attitude error
        variance per step is ``4 * sigma_quat dt^2 / 2`` (rad^2, a quaternion error ``dtheta / 2``). It is the
        error of holding the angular rate over a sample (eq. 3, footnote 2), which the gyroscope measures at
        every sample. Table I's 0.2 is an attitude random walk of 2.6 deg/sqrt(s) at 200 Hz, 6000 times what
        the gyroscope noise adds: the filter then re-fits the attitude to every accelerometer and context
        residual (heel-off rolling taken as stance moves the pitch by 5 deg, the heading by several degrees
        per stride; measured on foot_stride_gcp walk 32: -3 deg/s of heading drift). Default 1e-5.
    omega_psd
        ``Sigma^{d,3} = 10 dt`` (rad/s^2)^2 s.
    bias_psd
        ``Sigma^{d,4} = 1e-5 dt`` for the accelerometer bias, (m/s^2)^2 / s.
    gyro_bias_psd
        ``Sigma^{d,4}`` for the gyroscope bias, (rad/s)^2 / s (Table I: 1e-5, default 0).
    var_acc
        Accelerometer measurement variance ``Sigma^f`` (Table I: 8e-3), (m/s^2)^2.
    var_gyro
        Gyroscope measurement variance ``Sigma^omega``, (rad/s)^2. Table I's 6e-3 "comes from specification"
        (Sec. VI) of the seed's XSens MTi; the foot IMUs here (LORD MicroStrain 3DM-GX3/GX5, noise density
        0.03 deg/s/sqrt(Hz) or better) give (0.03 deg/s * sqrt(100 Hz))^2 = 3e-5 at 200 Hz.
    init_sigma_bias_acc, init_sigma_bias_gyro
        Prior standard deviations of the biases, m/s^2 and rad/s. The gyroscope bias is observable only
        through the context's zero-mean angular rate in stance; a real foot rolls while on the ground (mean
        rate over the detector's stance samples 0.1 rad/s, against a bias of 0.001 rad/s in the initial rest
        of the same recordings), so a free gyroscope bias learns the rolling (0.1-0.3 rad/s) and turns it into
        heading drift. Default 0: not estimated, as in the ZUPT-aided INS (seed 001).
    init_sigma_tilt, init_sigma_yaw
        Prior attitude standard deviations after the coarse alignment, rad.
    context
        Context potential; ``None`` for the expert model.
    gravity
        m/s^2.
    init_window_s
        Stationary period used for the coarse alignment, s.
    background
        How the broadest context component (the swing of the expert model) enters. ``"scored"`` (default): every
        component is the seed's Gaussian (eq. 17, ``f(Px)`` constant as eq. 7 allows) and is weighted by its
        eq. 14 normaliser over the belief, ``alpha_i N(mu_i; P mu, P Sigma P^T + Sigma_i)``; the broadest one
        applies no pull on the moments (its spread is the "no constraint" of the swing). ``"divided"``: eq. 7
        with ``f(Px)`` the broadest component, which then becomes the constant 1 (variance ``inf``) and the
        narrower ones ``phi_i / phi_b`` (:func:`potential_factors`). ``"applied"``: eq. 17 as written, every
        component a Kalman update of the belief. Why not ``"applied"``: at the IMU rate the swing component's
        pull to zero velocity with 2.5 m/s shortens every stride (half the distance on a noise-free simulated
        walk). Why not ``"divided"``: the constant does not widen with the belief, while the stance weight
        falls with the determinant of ``P Sigma P^T`` (a ratio ``sqrt(|Sigma_b| / |P Sigma P^T + Sigma_i'|)``),
        so once the belief is as uncertain as the swing itself the stance can no longer win -- the mode collapse
        of the filter bank's eq. 12d constant (issue #5); with ``"scored"`` the ratio tends to 1 instead.
    clip_model, clip_excess
        Attitude process noise of clipped gyroscope samples (:mod:`pdr.foot.saturation`): ``"peak"`` (default,
        :func:`~pdr.foot.saturation.clip_variance_peak`: the excess of a smooth peak cut at full scale, sized by
        the run's length and its edge slopes), ``"constant"`` (:func:`~pdr.foot.saturation.clip_variance`, an
        excess with the standard deviation ``clip_excess * |w|`` over the whole run) or ``"off"``. Why ``peak``
        (issue #5, figures from ``pdr eval foot /work/shared/data --method bc --hde on``): without clip noise the
        fast foot_stride_gcp walk runs away; the ``constant`` excess makes a short run's attitude spread so wide that
        a running stance's acceleration constraint pushes its accelerations into the tilt (one PyShoe running trial
        then ends tens of metres off); the ``peak`` excess, sized by the run, keeps both in check.
    hde
        Heuristic drift elimination of the heading (:mod:`pdr.foot.drift`): its ``hde_*``, ``sigma_drift*`` and
        ``sigma_heading_rw`` settings, the same as the ZUPT INS's (``ZuptConfig(hde_directions=0)``: off). It
        measures the heading error on the condensed position's strides, a stride ending when the stance
        component's weight falls below 0.5. Its ZUPT-INS settings ``zaru`` and ``interval_samples`` have no
        counterpart here (the IMU samples are measurements of the state, not integrated) and are refused.
    """

    jerk_psd: float = 1.25e5
    exact_jerk: bool = True
    sigma_quat: float = 1e-5
    omega_psd: float = 10.0
    bias_psd: float = 1e-5
    gyro_bias_psd: float = 0.0
    var_acc: float = 8e-3
    var_gyro: float = 3e-5
    init_sigma_bias_acc: float = 0.05
    init_sigma_bias_gyro: float = 0.0
    init_sigma_tilt: float = math.radians(1.0)
    init_sigma_yaw: float = math.radians(0.1)
    context: ContextModel | None = None
    gravity: float = GRAVITY_MPS2
    init_window_s: float = 0.5
    background: str = "scored"
    clip_model: str = "peak"
    clip_excess: float = CLIP_EXCESS_FRACTION
    hde: ZuptConfig = field(default_factory=ZuptConfig)

    def __post_init__(self) -> None:
        for name in ("jerk_psd", "sigma_quat", "omega_psd", "bias_psd", "var_acc", "var_gyro",
                     "init_sigma_bias_acc", "init_sigma_tilt", "init_sigma_yaw", "gravity", "init_window_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"must be a positive number, got {v}", field=name)
        for name in ("gyro_bias_psd", "init_sigma_bias_gyro", "clip_excess"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"must be a non-negative number, got {v}", field=name)
        if self.background not in BACKGROUNDS:
            raise InputError(f"expected one of {BACKGROUNDS}, got {self.background!r}", field="background")
        if self.clip_model not in CLIP_MODELS:
            raise InputError(f"expected one of {CLIP_MODELS}, got {self.clip_model!r}", field="clip_model")
        for name in ("zaru", "interval_samples"):
            if getattr(self.hde, name):
                raise InputError(f"belief condensation has no '{name}' setting (a ZUPT-INS setting): the IMU samples "
                                 "are measurements of its state", field=name)

    @classmethod
    def table_i(cls, **changes: object) -> BCConfig:
        """The seed's own values (Table I, diagonal ``Sigma^{d,1}``, free biases): its 100 Hz XSens walks."""
        kw: dict[str, object] = {"jerk_psd": 275.0, "exact_jerk": False, "sigma_quat": 0.2, "var_gyro": 6e-3,
                                 "gyro_bias_psd": 1e-5, "init_sigma_bias_gyro": 0.01}
        kw.update(changes)
        return cls(**kw)  # type: ignore[arg-type]


@dataclass(frozen=True)
class BCTrack:
    """Output of :func:`run_bc`, one row per IMU sample.

    Attributes
    ----------
    t_s
        (N,) s.
    pos_n, vel_n, acc_n
        (N, 3) position (m), velocity (m/s), acceleration (m/s^2), ENU.
    q_nb
        (N, 4) attitude.
    omega_b
        (N, 3) angular rate, rad/s, body frame.
    bias
        (N, 6) accelerometer (m/s^2) and gyroscope (rad/s) biases.
    pos_var, vel_var, att_var
        (N, 3) variances (m^2, m^2/s^2, rad^2).
    stance_prob
        (N,) posterior weight of the context component with the smallest velocity spread.
    start_index
        First navigated sample.
    warnings
        Problems found in the input.
    """

    t_s: Array
    pos_n: Array
    vel_n: Array
    acc_n: Array
    q_nb: Array
    omega_b: Array
    bias: Array
    pos_var: Array
    vel_var: Array
    att_var: Array
    stance_prob: Array
    start_index: int
    warnings: tuple[str, ...] = ()

    @property
    def yaw(self) -> Array:
        """(N,) yaw, rad, counter-clockwise from east."""
        return quat.to_euler(self.q_nb)[2]

    @property
    def zero_velocity(self) -> NDArray[np.bool_]:
        """(N,) True where the stance component dominates the condensed posterior."""
        return np.asarray(self.stance_prob > 0.5)


@cached_njit()
def _skew(x: Array) -> Array:  # pragma: no cover - compiled
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


@cached_njit()
def _imu_rows(c: Array, s_n: Array, bf: Array, w: Array, bw: Array, f_k: Array,
              w_k: Array) -> tuple[Array, Array]:  # pragma: no cover - compiled
    # Rows of the IMU measurement (eqs. 5-6) and their residuals y - h: the accelerometer h_f = C^T s_n + b_f with
    # s_n = a - g_n the specific force in the navigation frame (d h_f / d dtheta = C^T [s_n]x, true C = exp(dtheta)
    # est), the gyroscope h_w = omega + b_omega.
    e = np.zeros(6)
    H = np.zeros((6, N_ERR))
    ct = c.T
    h_f = ct @ s_n + bf
    for i in range(3):
        e[i] = f_k[i] - h_f[i]
        e[3 + i] = w_k[i] - (w[i] + bw[i])
    sk = _skew(s_n)
    cts = ct @ sk
    for i in range(3):
        for j in range(3):
            H[i, A_ + j] = ct[i, j]
            H[i, TH + j] = cts[i, j]
        H[i, BF + i] = 1.0
        H[3 + i, W_ + i] = 1.0
        H[3 + i, BW + i] = 1.0
    return H, e


@cached_njit()
def _bc_kernel(t: Array, f_b: Array, w_b: Array, start: int, q0: Array, g_n: Array, P0: Array,
               jerk: float, squat: float, somega: float, sbias: float, sbias_w: float, r_f: float, r_w: float,
               alpha: Array, mu: Array, var: Array, logc: Array, stance: int,
               pos: Array, vel: Array, acc: Array, qs: Array, om: Array, bias: Array,
               pvar: Array, vvar: Array, avar: Array, sprob: Array,
               exact: bool, hde_par: Array, hde: Array, sat_var: Array,
               scored: int) -> None:  # pragma: no cover - compiled
    n = t.size
    hde_on = hde_par[0] > 0
    was_stance = True                                   # aligned at rest
    m = alpha.size
    p = np.zeros(3)
    v = np.zeros(3)
    a = np.zeros(3)
    q = q0.copy()
    w = w_b[start].copy()
    bf = np.zeros(3)
    bw = np.zeros(3)
    P = P0.copy()
    log2pi = math.log(2.0 * math.pi)
    for k in range(start + 1, n):
        dt = t[k] - t[k - 1]
        # --- prediction pi^+ (eqs. 2-4) ---
        for i in range(3):
            p[i] += v[i] * dt + 0.5 * a[i] * dt * dt
            v[i] += a[i] * dt
        c_old = rotmat(q)
        q = quat_mul(q, quat_exp(w * dt))
        q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
        F = np.eye(N_ERR)
        for i in range(3):
            F[P_ + i, V_ + i] = dt
            F[P_ + i, A_ + i] = 0.5 * dt * dt
            F[V_ + i, A_ + i] = dt
            for j in range(3):
                F[TH + i, W_ + j] = c_old[i, j] * dt        # body-rate error turns the attitude
        P = congruence(F, P)
        for i in range(3):
            if exact:                                   # white jerk, exactly discretised (BCConfig.exact_jerk)
                P[P_ + i, P_ + i] += jerk * dt ** 5 / 20.0
                P[P_ + i, V_ + i] += jerk * dt ** 4 / 8.0
                P[V_ + i, P_ + i] += jerk * dt ** 4 / 8.0
                P[P_ + i, A_ + i] += jerk * dt ** 3 / 6.0
                P[A_ + i, P_ + i] += jerk * dt ** 3 / 6.0
                P[V_ + i, V_ + i] += jerk * dt ** 3 / 3.0
                P[V_ + i, A_ + i] += jerk * dt ** 2 / 2.0
                P[A_ + i, V_ + i] += jerk * dt ** 2 / 2.0
            else:                                       # Table I's diagonal
                P[P_ + i, P_ + i] += jerk * dt ** 3 / 6.0
                P[V_ + i, V_ + i] += jerk * dt ** 2 / 2.0
            P[A_ + i, A_ + i] += jerk * dt
            P[TH + i, TH + i] += 4.0 * squat * dt * dt / 2.0
            P[W_ + i, W_ + i] += somega * dt
            P[BF + i, BF + i] += sbias * dt
            P[BW + i, BW + i] += sbias_w * dt
        if sat_var[k].max() > 0.0:
            # Clipped gyroscope axes (pdr.foot.saturation): the unknown excess rate turns the attitude.
            add_clip_attitude_noise(P, TH, c_old, sat_var[k], dt)
        # --- measurement update f(y_k | x_k), linearised (eqs. 5-6) ---
        H, e = _imu_rows(rotmat(q), a - g_n, bf, w, bw, f_b[k], w_b[k])
        S = congruence(H, P)
        for i in range(3):
            S[i, i] += r_f
            S[3 + i, 3 + i] += r_w
        K = matmul(matmul_bt(P, H), symmetric_inverse(S)[0])
        dx = matvec(K, e)
        ikh = np.eye(N_ERR) - matmul(K, H)
        P = congruence(ikh, P)
        for i in range(3):
            for j in range(N_ERR):
                for jj in range(N_ERR):
                    P[j, jj] += K[j, i] * r_f * K[jj, i] + K[j, 3 + i] * r_w * K[jj, 3 + i]
        # --- belief condensation with the context potential (Algorithm 2, eqs. 13-15) ---
        # Context variables of the state after the measurement update (error-state form: P x = ctx + Pd dx).
        ctx = np.empty(N_CTX)
        for i in range(3):
            ctx[i] = v[i] + dx[V_ + i]
            ctx[3 + i] = a[i] + dx[A_ + i]
            ctx[6 + i] = w[i] + dx[W_ + i]
        idx = np.array([V_, V_ + 1, V_ + 2, A_, A_ + 1, A_ + 2, W_, W_ + 1, W_ + 2])
        Pc = np.empty((N_CTX, N_CTX))
        PcX = np.empty((N_CTX, N_ERR))
        for i in range(N_CTX):
            for j in range(N_CTX):
                Pc[i, j] = P[idx[i], idx[j]]
            for j in range(N_ERR):
                PcX[i, j] = P[idx[i], j]
        logb = np.empty(m)
        means = np.empty((m, N_ERR))
        covs = np.empty((m, N_ERR, N_ERR))
        for c_i in range(m):
            if var[c_i, 0] == np.inf:                   # the background component: a constant factor
                means[c_i] = dx
                covs[c_i] = P
                logb[c_i] = math.log(max(alpha[c_i], 1e-300)) + logc[c_i]
                continue
            Sc = Pc.copy()
            for i in range(N_CTX):
                Sc[i, i] += var[c_i, i]
            Sc_inv, logdet = symmetric_inverse(Sc)
            r = mu[c_i] - ctx
            if c_i == scored:
                # Scored background (BCConfig.background): eq. 14's normaliser of this component over the
                # belief, alpha N(mu; P mu_pi, P Sigma_pi P^T + Sigma_i), without its pull on the moments.
                means[c_i] = dx
                covs[c_i] = P
            else:
                Kc = matmul(PcX.T, Sc_inv)
                means[c_i] = dx + matvec(Kc, r)
                covs[c_i] = P - matmul(Kc, PcX)
            logb[c_i] = (math.log(max(alpha[c_i], 1e-300)) + logc[c_i]
                         - 0.5 * (N_CTX * log2pi + logdet + quadratic_form(r, Sc_inv)))
        mx = logb.max()
        beta = np.exp(logb - mx)
        beta /= beta.sum()
        dmean = np.zeros(N_ERR)
        for c_i in range(m):
            dmean += beta[c_i] * means[c_i]
        Pn = np.zeros((N_ERR, N_ERR))
        for c_i in range(m):
            d = means[c_i] - dmean
            for i in range(N_ERR):
                for j in range(N_ERR):
                    Pn[i, j] += beta[c_i] * (covs[c_i, i, j] + d[i] * d[j])
        P = 0.5 * (Pn + Pn.T)
        sprob[k] = beta[stance]
        # Feedback of the condensed error mean into the nominal state.
        for i in range(3):
            p[i] += dmean[P_ + i]
            v[i] += dmean[V_ + i]
            a[i] += dmean[A_ + i]
            w[i] += dmean[W_ + i]
            bf[i] += dmean[BF + i]
            bw[i] += dmean[BW + i]
        q = quat_mul(quat_exp(dmean[TH:TH + 3]), q)
        q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
        if hde_on:
            # Heuristic drift elimination (pdr.foot.drift) on the condensed estimate; a stance ends when the
            # stance component's weight falls below 0.5.
            rotate_yaw(q, drift_predict(hde, dt, hde_par))
            in_stance = sprob[k] > 0.5
            if was_stance and not in_stance:
                turn = drift_update(hde, p[0], p[1], hde_par)
                if turn != 0.0:
                    rotate_yaw(q, turn)
            was_stance = in_stance
        pos[k] = p
        vel[k] = v
        acc[k] = a
        qs[k] = q
        om[k] = w
        bias[k, :3] = bf
        bias[k, 3:] = bw
        for i in range(3):
            pvar[k, i] = P[P_ + i, P_ + i]
            vvar[k, i] = P[V_ + i, V_ + i]
            avar[k, i] = P[TH + i, TH + i]


def run_bc(t_s: ArrayLike, acc_b: ArrayLike, gyro_b: ArrayLike, zero_velocity: ArrayLike,
           config: BCConfig | None = None) -> BCTrack:
    """Belief-condensation filter over a recording (seed 000 Algorithm 2).

    Parameters
    ----------
    t_s
        (N,) strictly increasing times, s.
    acc_b, gyro_b
        (N, 3) specific force (m/s^2) and angular rate (rad/s), sensor frame.
    zero_velocity
        (N,) detector flags, used only to find the first stationary period for the coarse alignment; the
        context potential does the rest.
    config
        Noise model and context.
    """
    cfg = config or BCConfig()
    t, f_b, w_b = check_imu(t_s, acc_b, gyro_b)
    zv = np.asarray(zero_velocity, dtype=bool)
    if zv.shape != t.shape:
        raise InputError(f"expected shape {t.shape}, got {zv.shape}", field="zero_velocity")
    n = t.size
    rate = 1.0 / float(np.median(np.diff(t)))
    a0, q0, warning = coarse_start(t, f_b, zv, rate, cfg.init_window_s)
    ctx = cfg.context or ContextModel.expert()
    P0 = np.zeros((N_ERR, N_ERR))
    for i in range(3):
        P0[V_ + i, V_ + i] = 0.01**2
        P0[A_ + i, A_ + i] = 0.1**2
        P0[W_ + i, W_ + i] = 0.01**2
        P0[BF + i, BF + i] = cfg.init_sigma_bias_acc**2
        P0[BW + i, BW + i] = cfg.init_sigma_bias_gyro**2
    P0[TH, TH] = P0[TH + 1, TH + 1] = cfg.init_sigma_tilt**2
    P0[TH + 2, TH + 2] = cfg.init_sigma_yaw**2
    stance = int(np.argmin(ctx.sds[:, 0] + 1e3 * (ctx.weights == 0)))
    var, logc = potential_factors(ctx, cfg.background == "divided")
    scored = int(np.argmax(np.sum(np.log(var), axis=1))) if cfg.background == "scored" and var.shape[0] > 1 else -1
    if cfg.clip_model == "peak":
        sat_var = clip_variance_peak(w_b)
    else:
        sat_var = clip_variance(w_b, cfg.clip_excess if cfg.clip_model == "constant" else 0.0)
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    acc = np.zeros((n, 3))
    qs = np.tile(q0, (n, 1))
    om = np.zeros((n, 3))
    bias = np.zeros((n, 6))
    pvar = np.zeros((n, 3))
    vvar = np.zeros((n, 3))
    avar = np.zeros((n, 3))
    sprob = np.zeros(n)
    sprob[: a0 + 1] = 1.0
    _bc_kernel(t, np.ascontiguousarray(f_b), np.ascontiguousarray(w_b), a0, q0, np.array([0.0, 0.0, -cfg.gravity]),
               P0, cfg.jerk_psd, cfg.sigma_quat, cfg.omega_psd, cfg.bias_psd, cfg.gyro_bias_psd, cfg.var_acc,
               cfg.var_gyro,
               np.ascontiguousarray(ctx.weights), np.ascontiguousarray(ctx.means),
               var, logc, stance, pos, vel, acc, qs, om, bias, pvar, vvar, avar, sprob, cfg.exact_jerk,
               cfg.hde.hde_params(), initial_state(cfg.hde.sigma_drift0),
               sat_var, scored)
    return BCTrack(t, pos, vel, acc, quat.normalize(qs), om, bias, pvar, vvar, avar, sprob, a0,
                   (warning,) if warning else ())


def potential_factors(context: ContextModel, divide_by_prior: bool) -> tuple[Array, Array]:
    """Per-component variances and log scale factors of the potential as the filter applies it (eq. 7).

    Without the division: the components' own variances, factors 0. With it, each component ``i`` narrower
    than the broadest one ``b`` becomes ``phi(x; 0, S_i) / phi(x; 0, S_b) = c_i N(x; 0, S_i')`` with
    ``S_i' = (S_i^-1 - S_b^-1)^-1`` and ``log c_i = d/2 log 2 pi + (log|S_i'| - log|S_i| + log|S_b|) / 2``;
    ``b`` itself becomes the constant 1 (variance ``inf``). Diagonal covariances only; zero means assumed for
    the division (as in the expert and learned models).
    """
    var = np.asarray(context.sds, dtype=np.float64) ** 2
    m = var.shape[0]
    if not divide_by_prior or m == 1:
        return np.ascontiguousarray(var), np.zeros(m)
    b = int(np.argmax(np.sum(np.log(var), axis=1)))
    out = np.empty_like(var)
    logc = np.zeros(m)
    for i in range(m):
        if i == b:
            out[i] = np.inf
            continue
        prec = 1.0 / var[i] - 1.0 / var[b]
        if np.any(prec <= 0):
            raise InputError("with divide_by_prior every component must be narrower than the broadest on every "
                             "variable", field="context.sds")
        out[i] = 1.0 / prec
        logc[i] = 0.5 * (N_CTX * math.log(2 * math.pi) + np.sum(np.log(out[i])) - np.sum(np.log(var[i]))
                         + np.sum(np.log(var[b])))
    return np.ascontiguousarray(out), logc


def context_samples(vel_n: ArrayLike, q_nb: ArrayLike, acc_b: ArrayLike, gyro_b: ArrayLike,
                    gravity: float = GRAVITY_MPS2) -> Array:
    """(N, 9) ``[v, a, omega]`` of a navigation solution: ``a = C(q) f + g`` (m/s^2, ENU), ``omega`` = gyro."""
    f = np.asarray(acc_b, dtype=np.float64)
    a = quat.rotate(np.asarray(q_nb, dtype=np.float64), f) + np.array([0.0, 0.0, -gravity])
    return np.concatenate([np.asarray(vel_n, dtype=np.float64), a, np.asarray(gyro_b, dtype=np.float64)], axis=1)


def learn_context(samples: ArrayLike, m: int = 4, iterations: int = 50, seed: int = 0) -> ContextModel:
    """Fit an m-component context potential by EM to ``[v, a, omega]`` samples (seed 000 Sec. V.C).

    Components are zero-mean with diagonal covariances whose two horizontal velocity and acceleration axes
    share one variance, so that the potential does not depend on the walking direction (a learned mean
    velocity would pull every track towards the training walk's heading). EM starts from the expert model's
    two components; further components start between them (geometric interpolation of the spreads).

    Parameters
    ----------
    samples
        (K, 9) context variables (e.g. :func:`context_samples` of a ZUPT-EKF run).
    m
        Number of components (>= 1).
    iterations
        EM iterations.
    seed
        Unused by the deterministic initialisation; kept for a stable signature.
    """
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != N_CTX or x.shape[0] < 10 * max(1, m) or not np.all(np.isfinite(x)):
        raise InputError(f"need at least {10 * max(1, m)} finite (., {N_CTX}) samples", field="samples")
    if m < 1:
        raise InputError("m must be at least 1", field="m")
    expert = ContextModel.expert()
    lo, hi = np.log(expert.sds[0]), np.log(expert.sds[1])
    frac = np.linspace(0.0, 1.0, m) if m > 1 else np.array([0.5])
    sd = np.exp(lo[None, :] + frac[:, None] * (hi - lo)[None, :])
    var = sd**2
    w = np.full(m, 1.0 / m)
    groups = [[0, 1], [2], [3, 4], [5], [6], [7], [8]]             # tied horizontal axes of v and a
    x2 = x**2
    for _ in range(iterations):
        # E step: responsibilities of zero-mean diagonal Gaussians.
        logp = (np.log(w)[None, :] - 0.5 * np.sum(np.log(2 * np.pi * var), axis=1)[None, :]
                - 0.5 * x2 @ (1.0 / var).T)
        logp -= logp.max(axis=1, keepdims=True)
        r = np.exp(logp)
        r /= r.sum(axis=1, keepdims=True)
        nk = r.sum(axis=0) + 1e-12
        w = nk / nk.sum()
        s2 = (r.T @ x2) / nk[:, None]
        for g in groups:
            s2[:, g] = s2[:, g].mean(axis=1, keepdims=True)
        var = np.maximum(s2, 1e-8)
    order = np.argsort(var[:, 0])
    return ContextModel(w[order] / w.sum(), np.zeros((m, N_CTX)), np.sqrt(var[order]))
