"""Walking heading per step: RMPCA, improved RMPCA in the reference frame, the second UKF, device heading.

All angles here are internal yaw: radians counter-clockwise from east (seed 003 measures user heading
counter-clockwise from north; the difference is a constant pi/2 that cancels in every difference used).

RMPCA (seed 003 Sec. 2, ref. [14])
    The specific force of each sample of the step is rotated to the navigation frame with the attitude,
    ``a^GCS = R(q) a^DCS`` (eqs. 16-18), its horizontal components are centred and the principal axis
    of their 2x2 scatter matrix is the walking direction, up to 180 degrees.

Improved RMPCA in the reference frame RCS (eqs. 21-32, 41)
    All samples are first expressed in the device frame at one instant ``t1`` (eqs. 14-16), which makes
    the scatter matrix ``M = sum a^DCS1 a^DCS1^T`` a function of the single attitude ``q(t1)``. The
    horizontal scatter in RCS, ``A~(q) = C Q(q) M Q(q)^T C^T`` (eq. 27), is rotated by the RMPCA yaw ``psi0``
    so that the walking direction is near the RCS x axis, and ``f(q)`` is the angle of its principal axis:
    ``f(q) = 0.5 atan2(2 a~12, a~11 - a~22)``. (Setting the derivative of eq. 28 to zero gives
    ``tan(2 dtheta) = 2 a~12 / (a~11 - a~22)``; seed 003 eqs. 31-32 drop the factor 2. The two-argument
    arctangent picks the maximum, not the minimum, of eq. 28 and holds for ``|dtheta| < pi/2``.)
    ``f`` is the landmark measurement of the first UKF (eq. 32) and the state equation of the second
    UKF (eq. 41): ``UH = psi0 + f(q(t1)) + w``.

Second UKF (eqs. 41-42)
    The sigma points of ``q(t1)`` with the attitude covariance give the mean and variance of ``UH``
    (unscented transform of eq. 41); a landmark heading ``UH_landmark = UH + nu`` (eq. 42) updates it.

180-degree ambiguity (documented rule)
    The principal axis is a line. Hand-held/torso: the direction within 90 degrees of the device's
    forward axis. Trouser pocket: the direction in which the thigh's swing is fast (:func:`thigh_swing_evidence`),
    decided by evidence accumulated over the strides (:class:`DirectionVote`, with the centripetal turn cue as a
    light second vote) and carried between steps in the device frame
    (:class:`pdr.phone.walking_direction.DeviceFrameDirection`).

    Physics: a pocket phone rotates with the thigh about the hip's lateral axis. Seen from the walker's
    right, flexion (knee moving forward) is a positive rotation about ``r = f x u`` (f: walking direction,
    u: up), so the horizontal angular rate is ``omega_h = thetadot r``. Over a gait cycle the thigh covers
    the same angle twice: extending slowly during stance (about 60 % of the cycle) and flexing quickly during
    swing (about 40 %), so ``thetadot`` is positively skewed: ``sum thetadot^3 > 0`` over a stride. For a
    candidate direction ``p`` the flexion rate is ``omega_h . (p x u)``, which is ``+thetadot`` for ``p = f``
    and ``-thetadot`` for ``p = -f``: the sign of its third moment picks the direction. Rules that read the
    direction from the acceleration at heel strike fail in a pocket: there the thigh's own rotation adds
    forward or backward acceleration depending on the subject (on the MobiFall walks the norm peaks' forward
    share ranges from well under to well over half).

    Checked on real walks without direction truth by the centripetal acceleration in turns: walking at speed
    ``V`` with yaw rate ``Omega``, the mean horizontal acceleration over a stride is ``V Omega (u x f)``, which
    gives ``f`` with its sign from the gyro's yaw rate and no gait assumption. On the turning strides of the
    MobiFall walks the swing evidence agrees with it far more often than a heel-strike deceleration rule, and the
    vote over strides more often still; ``pdr eval pocket-heading --data /work/shared/data`` prints the direction
    flips (consecutive steps more than 120 degrees apart) of the MobiFall and Oxford front/back-pocket walks
    (Oxford: accelerometer only, the rate comes from the tilt) and the simulated pocket walks' error (both
    thighs, random mounts; ``tools/pocket_direction_check.py`` checks that no simulated step points backwards).

Device heading (hand-held and torso)
    The yaw of the device forward axis averaged over the step (seed 004 eq. 21, on the unwrapped yaw),
    plus an offset: zero by default, or the running doubled-angle mean of ``RMPCA - device yaw`` reduced
    to (-90, 90] degrees when ``offset="pca"``.

Heuristic drift elimination of the step heading (:class:`StepDriftElimination`)
    Indoors the magnetometer-referenced heading is deflected by the building's steel by tens of degrees,
    differently from place to place, while the walks follow a few dominant directions. The heuristic drift
    elimination of the foot navigators (:mod:`pdr.foot.drift`: a two-state Kalman filter of the heading
    error, straight strides near a dominant direction measure it) is applied to the per-step heading: its
    stride positions are those of the corrected step headings and lengths, and the correction is added to
    the heading of the following steps (positions already output are not moved). The dominant directions
    are learnt online from the walk itself (no map): the circular mean of ``n_dir psi`` over the raw
    (uncorrected) directions of the strides in straight runs of at least ``learn_min_strides`` strides,
    so a short stretch (or the handling before a walk) does not set them.

    The parameters (``DriftEliminationConfig``) were chosen on the IPIN 2023 track-3 repetition-01 hand-held
    files, where the landmark p75 is flat over a wide range of the direction sigma, the random walk and
    ``learn_min_strides`` (not tuned to a point), and checked on the held-out repetition-02 files;
    ``pdr eval ipin /work/shared/data/ipin2023_t3/logfiles --placement hand`` prints the landmark median and p75
    (causal and smoothed). What limits it: the dominant directions come from the walk's
    magnetometer-referenced headings, whose mean over a walk is itself deflected (by up to 20 deg on some
    routes), so the true grid direction does better.

    A site description may give that grid (``Site.grid_deg``, the compass bearing of one of the building's main
    axes): the dominant directions are then fixed to it instead of learnt. The IPIN 2023 museum's grid, from its
    landmark survey (the length-weighted circular mean of the legs' directions mod 90 deg), has the compass bearing
    69.5 deg; ``pdr eval ipin DIR --placement hand --site grid.json`` with ``{"grid_deg": 69.5, "landmarks": []}``
    prints the figures with it. That is a map input, so the IPIN target figures never use it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.filters.compiled import kernel
from pdr.filters.numpy_reductions import column_sums, pairwise_sum
from pdr.filters.ukf import SigmaPoints
from pdr.foot import drift
from pdr.frames import wrap_angle, wrap_angle_float

FloatArray = NDArray[np.float64]


def pca_axis(horizontal: FloatArray) -> tuple[float, float]:
    """Principal axis of centred (M, 2) horizontal vectors: (yaw in (-pi/2, pi/2], eigenvalue ratio)."""
    h = np.asarray(horizontal, dtype=np.float64)
    if h.ndim != 2 or h.shape[1] != 2 or h.shape[0] < 2:
        raise InputError("need (M >= 2, 2) horizontal vectors", source="heading")
    # The scatter's product stays numpy's (BLAS's, whose order a kernel would not reproduce); its entries as Python
    # floats (the same IEEE operations as on numpy scalars, without their dispatch per step).
    d = _centred(h)
    s00, s01, _s10, s11 = (d.T @ d).ravel().tolist()
    ang = 0.5 * math.atan2(2.0 * s01, s00 - s11)
    tr = s00 + s11
    det = s00 * s11 - s01 ** 2
    disc = math.sqrt(max(tr * tr / 4 - det, 0.0))
    l1, l2 = tr / 2 + disc, tr / 2 - disc
    return float(ang), float(l1 / max(l2, 1e-12))


@kernel
def _centred(h: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """``h - h.mean(axis=0)`` of (M, k) samples, bit for bit (numpy's column sums, :mod:`pdr.filters.numpy_reductions`,
    over M), as a new C-ordered array like numpy's.
    """
    m, k = h.shape
    mean = column_sums(h) / m
    d = np.empty((m, k))
    for i in range(m):
        for j in range(k):
            d[i, j] = h[i, j] - mean[j]
    return d


def resolve_direction(axis_yaw: float, prior_yaw: float) -> float:
    """The direction along ``axis_yaw`` (a line) within 90 degrees of ``prior_yaw`` (rad)."""
    a = wrap_angle_float(axis_yaw)
    return a if abs(wrap_angle_float(a - prior_yaw)) <= math.pi / 2 else wrap_angle_float(a + math.pi)


def flexion_rate(q_nb: FloatArray, rate_hz: float, yaw: float, smooth_s: float = 0.09) -> FloatArray:
    """Thigh flexion rate (rad/s) about ``p x u`` for the candidate walking yaw ``yaw`` (rad, ENU).

    The navigation-frame angular rate comes from consecutive attitudes, ``q_{k+1} = dq q_k`` with
    ``dq = exp(omega_n / rate_hz)`` (so it exists with or without a gyroscope), and is smoothed by a
    ``smooth_s`` moving average against the heel-strike ringing. Shape (N - 1 - w + 1,) for N attitudes.
    """
    q = np.asarray(q_nb, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 3:
        raise InputError("need (N >= 3, 4) attitude quaternions", source="heading")
    omega = quat.to_rotvec(quat.multiply(q[1:], quat.conjugate(q[:-1]))) * rate_hz
    r = np.array([math.sin(yaw), -math.cos(yaw)])               # p x u for p = (cos yaw, sin yaw, 0)
    rate = omega[:, :2] @ r
    w = min(max(int(round(smooth_s * rate_hz)), 1), rate.size)
    return np.convolve(rate, np.full(w, 1.0 / w), mode="valid")


def thigh_swing_evidence(q_nb: FloatArray, rate_hz: float, yaw: float) -> float:
    """Evidence in [-1, 1] that ``yaw`` (rad) points forward, from one stride of a pocket phone's attitude.

    The normalised third moment ``sum x^3 / (sum x^2)^1.5`` of the flexion rate ``x`` (:func:`flexion_rate`),
    i.e. its skewness about zero over ``sqrt(N)`` for N samples (about 0.1-0.2 for a real 100 Hz stride):
    positive when the fast phase of the thigh's swing rotates the knee towards ``yaw`` (module doc). It is
    odd in the direction: the opposite yaw gives the opposite value. Pass a whole stride (two steps).
    """
    x = flexion_rate(q_nb, rate_hz, yaw)
    m2 = float(np.sum(x * x))
    return float(np.sum(x ** 3) / m2 ** 1.5) if m2 > 0.0 else 0.0


@dataclass
class DirectionVote:
    """Sequential decision between a walking direction and its opposite from per-stride evidence.

    ``score`` is the exponentially weighted sum (memory ``1 / (1 - decay)`` strides) of the evidence for
    the current direction. During the first ``settle`` strides the direction follows the sign of the score;
    afterwards it is reversed only when the score falls below ``-margin``, so weak or noisy strides do not
    flip the heading, while a wrong direction (at the start, or after a turn the continuity rule misread) is
    undone within a few strides. A reversal reverses the score with the direction.
    """

    decay: float = 0.9
    margin: float = 0.5
    settle: int = 4
    score: float = 0.0
    n: int = 0

    def update(self, evidence: float) -> bool:
        """Add one stride's evidence for the current direction; True when the direction must be reversed."""
        self.score = self.decay * self.score + evidence
        self.n += 1
        if self.score < (0.0 if self.n <= self.settle else -self.margin):
            self.score = -self.score
            return True
        return False


def rmpca(q_nb: FloatArray, acc_b: FloatArray) -> tuple[float, float]:
    """RMPCA walking axis of one step: (yaw of the principal horizontal axis (rad), eigenvalue ratio)."""
    f_n = quat.rotate(q_nb, acc_b)
    return pca_axis(f_n[:, :2])


def scatter_at(q_nb: FloatArray, acc_b: FloatArray, q1: FloatArray) -> FloatArray:
    """``M = sum_j a^DCS1(j) a^DCS1(j)^T`` (eqs. 14-16, 26): the step's centred samples in the device frame
    at the instant of attitude ``q1`` (3, 3).
    """
    return scatter_of(quat.rotate(q_nb, acc_b), q1)


def scatter_of(f_n: FloatArray, q1: FloatArray) -> FloatArray:
    """:func:`scatter_at` from the step's specific force already in the navigation frame (M, 3).

    ``a^DCS1(j) = C_nb(q1)^T f_n(j)`` (eqs. 14-16), so ``M = C^T (F^T F) C`` with ``F`` the centred samples.
    """
    d = f_n - f_n.mean(axis=0)
    c = quat.to_rotmat(q1)
    return np.asarray(c.T @ (d.T @ d) @ c)


def scatter_in_frame(m_dcs1: FloatArray, q1: FloatArray, q2: FloatArray) -> FloatArray:
    """A scatter matrix expressed in the device frame of ``q1`` carried into that of ``q2`` (3, 3).

    ``a^DCS2 = R^T a^DCS1`` with ``R = C_nb(q1)^T C_nb(q2)`` the temporary rotation from DCS2 to DCS1
    (eqs. 14-15), so ``M2 = R^T M1 R``; then ``f(q2, M2) = f(q1, M1)`` (the samples do not move in GCS).
    """
    r = quat.to_rotmat(np.asarray(q1, dtype=np.float64)).T @ quat.to_rotmat(np.asarray(q2, dtype=np.float64))
    return np.asarray(r.T @ np.asarray(m_dcs1, dtype=np.float64) @ r)


def f_of_q(q1: FloatArray, m_dcs1: FloatArray, psi0: float) -> float:
    """``f(q(t1))`` of eqs. 27-32 (corrected factor 2, see module doc): principal-axis angle in RCS (rad)."""
    c_nb = quat.to_rotmat(q1)
    qm = c_nb[:2, :]                                            # Q(q) of eq. 19
    cr, sr = math.cos(psi0), math.sin(psi0)
    c = np.array([[cr, sr], [-sr, cr]])                         # eq. 22 (rotation by the RMPCA yaw)
    a = c @ qm @ m_dcs1 @ qm.T @ c.T                            # eq. 27
    return 0.5 * math.atan2(2.0 * a[0, 1], a[0, 0] - a[1, 1])   # eqs. 29-32


def axis_difference(a: FloatArray | float, b: FloatArray | float) -> FloatArray:
    """``a - b`` for angles of lines (period pi), reduced to (-pi/2, pi/2] (rad)."""
    return np.asarray(0.5 * wrap_angle(2.0 * (np.asarray(a, dtype=np.float64) - b)), dtype=np.float64)


def _quat_add(x: FloatArray, dx: FloatArray) -> FloatArray:
    y = x + dx
    return y / np.linalg.norm(y)


@dataclass(frozen=True)
class HeadingEstimate:
    """Mean and variance (rad, rad^2) of a step's walking yaw."""

    yaw: float
    var: float


def improved_rmpca_ut(q1: FloatArray, p_q: FloatArray, m_dcs1: FloatArray, psi0: float,
                      process_var: float, points: SigmaPoints | None = None) -> HeadingEstimate:
    """Eq. 41 through the unscented transform: ``UH = psi0 + f(q) + w`` with ``q ~ N(q1, P_q)``."""
    sp = points or SigmaPoints(4, alpha=1e-3, beta=2.0, kappa=0.0)
    wm, wc = sp.weights()
    sig = sp.sigma_points(np.asarray(q1, dtype=np.float64), np.asarray(p_q, dtype=np.float64) + 1e-15 * np.eye(4),
                          _quat_add)
    f = np.array([f_of_q(s, m_dcs1, psi0) for s in sig])
    d = axis_difference(f, f[0])   # f is the angle of a line: sigma points pi apart agree
    mean_d = float(np.sum(wm[1:] * d[1:]))   # centre-subtracted mean (sum w = 1)
    mean = f[0] + mean_d
    var = float(np.sum(wc * (d - mean_d) ** 2)) + process_var
    return HeadingEstimate(wrap_angle_float(psi0 + mean), max(var, 1e-12))


def fuse_landmark(prior: HeadingEstimate, yaw_landmark: float, var_landmark: float) -> HeadingEstimate:
    """Second UKF measurement update (eq. 42): linear in the state, so the UKF update is exact here."""
    y = wrap_angle_float(yaw_landmark - prior.yaw)
    k = prior.var / (prior.var + var_landmark)
    return HeadingEstimate(wrap_angle_float(prior.yaw + k * y), (1 - k) * prior.var)


def landmark_attitude_update(q1: FloatArray, p_q: FloatArray, m_dcs1: FloatArray, psi0: float, d_uh: float,
                             var_uh: float, points: SigmaPoints | None = None) -> tuple[FloatArray, FloatArray]:
    """First UKF landmark row (eqs. 20, 32, 38-40): update ``q(t1)`` with ``Delta UH = UH_landmark - UH_RMPCA``.

    Returns the updated (4,) quaternion and (4, 4) covariance. Landmarks more than 45 degrees from the
    RMPCA heading are not used (seed 003 Sec. 4.2): the caller checks ``|d_uh|``.
    """
    sp = points or SigmaPoints(4, alpha=1e-3, beta=2.0, kappa=0.0)
    wm, wc = sp.weights()
    p = np.asarray(p_q, dtype=np.float64) + 1e-15 * np.eye(4)
    sig = sp.sigma_points(np.asarray(q1, dtype=np.float64), p, _quat_add)
    z = np.array([f_of_q(s, m_dcs1, psi0) for s in sig])
    dz = axis_difference(z, z[0])
    zm_d = float(np.sum(wm[1:] * dz[1:]))
    pzz = float(np.sum(wc * (dz - zm_d) ** 2)) + var_uh                      # eq. 38
    dx = sig - sig[0]
    pqz = (wc[:, None] * dx * (dz - zm_d)[:, None]).sum(axis=0)              # eq. 39
    k = pqz / pzz
    innov = wrap_angle_float(d_uh - (z[0] + zm_d))
    q_new = _quat_add(np.asarray(q1, dtype=np.float64), k * innov)           # eq. 40
    p_new = p - np.outer(k, k) * pzz
    # Repeated landmark rows (every step of a flight) on a rank-deficient quaternion covariance can leave
    # eigenvalues slightly below zero by rounding: project back onto the positive semi-definite cone.
    vals, vecs = np.linalg.eigh(0.5 * (p_new + p_new.T))
    p_new = (vecs * np.maximum(vals, 1e-12)) @ vecs.T
    return quat.normalize(q_new), 0.5 * (p_new + p_new.T)


def mean_yaw(yaw: FloatArray) -> float:
    """Average of a yaw sequence over a step (seed 004 eq. 21), as the circular mean (rad) so that the
    wrap at +/-pi does not matter (equal to the mean of the unwrapped angles for small spreads).
    """
    y = np.asarray(yaw, dtype=np.float64)
    # numpy's sines and cosines (vectorised: a loop's libm calls could differ in the last bit), numpy's sums compiled.
    return math.atan2(pairwise_sum(np.sin(y)), pairwise_sum(np.cos(y)))


def yaw_variance(q: FloatArray, p_q: FloatArray) -> float:
    """Variance (rad^2) of the yaw of any horizontal device axis under ``q ~ N(q, P_q)`` (4x4).

    A small navigation-frame rotation ``dphi`` moves ``q`` by ``dq = 0.5 [0, dphi] * q``; the yaw changes
    by ``dphi_z``, and ``dphi_z = 2 g^T dq`` with ``g = [0, 0, 0, 1] * q``, so ``var = 4 g^T P g``.
    """
    w, x, y, z = np.asarray(q, dtype=np.float64).tolist()
    g = np.array([-z, -y, x, w])                     # [0, 0, 0, 1] * q (Hamilton product)
    return max(float(4.0 * g @ p_q @ g), 1e-10)


class OffsetEstimator:
    """Running doubled-angle mean of ``RMPCA axis - device yaw`` reduced to (-pi/2, pi/2] (hand/torso offset)."""

    def __init__(self, weight: float = 0.05) -> None:
        self.weight = weight
        self.c = 0.0
        self.s = 0.0

    def update(self, axis_yaw: float, device_yaw: float, quality: float = 1.0) -> float:
        d = 2.0 * (axis_yaw - device_yaw)
        w = self.weight * quality
        self.c = (1 - w) * self.c + w * math.cos(d)
        self.s = (1 - w) * self.s + w * math.sin(d)
        return self.offset

    @property
    def offset(self) -> float:
        if self.c == 0.0 and self.s == 0.0:
            return 0.0
        return 0.5 * math.atan2(self.s, self.c)

    def state(self) -> dict[str, float]:
        return {"weight": self.weight, "c": self.c, "s": self.s}

    @classmethod
    def from_state(cls, d: dict[str, float]) -> OffsetEstimator:
        o = cls(float(d["weight"]))
        o.c, o.s = float(d["c"]), float(d["s"])
        return o


@dataclass(frozen=True)
class DriftEliminationConfig:
    """Parameters of :class:`StepDriftElimination` (angles in degrees, SI otherwise).

    Attributes
    ----------
    directions
        Number of evenly spaced dominant directions (4: a rectangular building).
    sigma_dir_deg
        Standard deviation of a straight stride's deviation from its dominant direction, as a measurement
        of the heading error.
    max_dev_deg
        Largest deviation from a dominant direction that is taken as heading error.
    straight_tol_deg
        Largest direction change between consecutive strides of a straight run.
    min_strides
        Straight strides in a row before a stride measures the heading error.
    learn_min_strides
        Straight strides in a row before a stride enters the dominant-direction estimate.
    min_stride_m
        Shortest stride (m); shorter ones (standing, shuffling) are skipped.
    sigma_heading_rw_deg
        Random walk of the heading error (deg/sqrt(s)).
    steps_per_stride
        Steps per stride (two: the left-right sway of the device heading cancels over a stride).
    """

    directions: int = 4
    sigma_dir_deg: float = 5.0
    max_dev_deg: float = 10.0
    straight_tol_deg: float = 5.0
    min_strides: int = 2
    learn_min_strides: int = 6
    min_stride_m: float = 0.5
    sigma_heading_rw_deg: float = 1.0
    steps_per_stride: int = 2

    def __post_init__(self) -> None:
        if self.directions < 1 or self.min_strides < 1 or self.learn_min_strides < 1 or self.steps_per_stride < 1:
            raise InputError("directions, min_strides, learn_min_strides and steps_per_stride must be >= 1",
                             source="config", field="drift_elimination")

    def params(self) -> FloatArray:
        """The parameter vector of :mod:`pdr.foot.drift` (no drift-rate state: the heading error is a random walk)."""
        return np.array([float(self.directions), math.radians(self.sigma_dir_deg) ** 2,
                         math.radians(self.max_dev_deg), math.radians(self.straight_tol_deg),
                         float(self.min_strides), self.min_stride_m, math.radians(self.sigma_heading_rw_deg) ** 2,
                         0.0])


class StepDriftElimination:
    """Heuristic drift elimination of a per-step walking heading (module doc; :mod:`pdr.foot.drift`).

    Feed every step in order with :meth:`step`; it returns the corrected yaw of that step (rad, ENU).
    """

    def __init__(self, config: DriftEliminationConfig | None = None, grid_yaw: float | None = None) -> None:
        """``grid_yaw``: yaw (rad, ENU) of one of the building's main axes, fixing the dominant directions
        (None: learnt from the walk).
        """
        self.config = config or DriftEliminationConfig()
        self.grid_yaw = grid_yaw
        self._par = self.config.params()
        self.hde = drift.initial_state(0.0)
        drift.drift_update(self.hde, 0.0, 0.0, self._par)      # the first stride starts at the origin
        self.correction = 0.0          # added to the raw yaw (rad)
        self.pos = [0.0, 0.0]          # corrected stride positions (m)
        self.raw = [0.0, 0.0, 0.0, 0.0]  # raw positions now and at the last stride end (m)
        self.dominant = [0.0, 0.0]     # sum of w (cos, sin)(n_dir psi) over learning strides
        self.n_steps = 0
        self.last_t = 0.0

    def step(self, yaw: float, length_m: float, t_s: float) -> float:
        """Corrected yaw (rad) of a step of raw yaw ``yaw`` (rad), length ``length_m`` (m), ending at ``t_s`` (s)."""
        par = self._par
        if self.n_steps and t_s > self.last_t:
            self.correction += drift.drift_predict(self.hde, t_s - self.last_t, par)
        self.last_t = t_s
        out = wrap_angle_float(yaw + self.correction)
        self.pos[0] += length_m * math.cos(out)
        self.pos[1] += length_m * math.sin(out)
        self.raw[0] += length_m * math.cos(yaw)
        self.raw[1] += length_m * math.sin(yaw)
        self.n_steps += 1
        if self.n_steps % self.config.steps_per_stride == 0:
            c, s = self.dominant
            if self.grid_yaw is not None:
                self.hde[drift.HDE_REF] = self.grid_yaw                 # the site's grid
                self.hde[drift.HDE_HAVE_REF] = 1.0
            elif c != 0.0 or s != 0.0:
                self.hde[drift.HDE_REF] = math.atan2(s, c) / par[0]
                self.hde[drift.HDE_HAVE_REF] = 1.0
            turn = drift.drift_update(self.hde, self.pos[0], self.pos[1], par)
            dx, dy = self.raw[0] - self.raw[2], self.raw[1] - self.raw[3]
            if self.hde[drift.HDE_COUNT] >= self.config.learn_min_strides and math.hypot(dx, dy) >= par[5]:
                psi, w = math.atan2(dy, dx), math.hypot(dx, dy)
                self.dominant[0] += w * math.cos(par[0] * psi)
                self.dominant[1] += w * math.sin(par[0] * psi)
            self.raw[2], self.raw[3] = self.raw[0], self.raw[1]
            self.correction = wrap_angle_float(self.correction + turn)
        return out

    @property
    def updates(self) -> int:
        """Number of strides that measured the heading error."""
        return int(self.hde[drift.HDE_UPDATES])

    def state(self) -> dict[str, object]:
        return {"hde": self.hde.tolist(), "correction": self.correction, "pos": list(self.pos), "raw": list(self.raw),
                "dominant": list(self.dominant), "n_steps": self.n_steps, "last_t": self.last_t}

    @classmethod
    def from_state(cls, d: dict[str, Any], config: DriftEliminationConfig | None = None,
                  grid_yaw: float | None = None) -> StepDriftElimination:
        o = cls(config, grid_yaw)
        o.hde = np.array(d["hde"], dtype=np.float64)
        o.correction = float(d["correction"])
        o.pos = [float(v) for v in d["pos"]]
        o.raw = [float(v) for v in d["raw"]]
        o.dominant = [float(v) for v in d["dominant"]]
        o.n_steps, o.last_t = int(d["n_steps"]), float(d["last_t"])
        return o
