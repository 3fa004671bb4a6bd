"""Offline smoothing of a finished phone track's step headings: gyro yaw plus a bias learnt from the magnetometer.

Why
    The causal hand-held/torso heading follows the magnetometer-referenced device yaw within seconds (the
    attitude UKF's yaw noise is large there, :attr:`pdr.phone.pipeline.PipelineConfig.device_heading_sigma_gyro`), so a
    building's steel deflects it by 10-25 degrees over whole corridors. The gyro alone keeps the shape of a route
    to a few degrees once its bias about the vertical is known, but that bias (tenths of a deg/s on the IPIN 2023
    phones, more on some walks; the stationary estimate of :mod:`pdr.phone.attitude` is missing when the user
    never stands still; each step event carries it as ``gyro_bias_dps``) turns it by tens of degrees within
    minutes, and a causal filter cannot tell
    the bias from a deflection until minutes of magnetometer data have passed (a causal version of this model,
    tried on the IPIN walks, was worse than the magnetometer heading). Once the whole walk is known, a
    fixed-interval smoother can: the magnetometer's deflections vary from place to place, the bias does not.

Model (per step ``k`` at time ``t_k``, yaw in rad counter-clockwise from east)
    ``psi_k = g_k + d_k`` where ``g_k`` is the gyro yaw of the step (:class:`pdr.phone.pipeline.PdrPipeline`
    integrates the gyro's rate about the vertical; its origin is arbitrary) and the state ``x = (d, beta)`` is the
    offset of the gyro yaw and its drift rate (the gyro bias about the vertical, rad/s):

    - transition ``d_k = d_{k-1} + beta_{k-1} dt + w_d``, ``beta_k = beta_{k-1} + w_beta``: a random walk of the offset
      (``heading_rw_deg`` per sqrt(s): gyro noise, the device turning in the hand) and an integrated random walk of
      the bias (``bias_rw_deg`` deg/s per sqrt(s)), with the exact discrete covariance of the integrated walk;
    - measurement ``z_k = wrap(m_k - g_k) = d_k + v_k``: ``m_k`` is the causal step heading before the drift
      elimination (magnetometer-referenced device heading), ``v_k`` with standard deviation ``sigma_mag_deg``
      (a deflection, not sensor noise); a step whose heading a site landmark set keeps that landmark's sigma.

    A Kalman filter forward and the Rauch-Tung-Striebel recursion backward give ``d_k`` from all steps; the
    smoothed heading is ``g_k + d_k``.

    Stationary bias: when the user stood still at some time in the walk, the attitude filter measured the gyro bias
    ``b`` (device frame, :mod:`pdr.phone.attitude`), and the step events carry it (``gyro_bias_dps``) with the
    device-frame up direction integrated over the walk (``up_time_s``). The bias added ``up_time_s . b`` to the gyro
    yaw; the walk's last estimate is removed from ``g_k`` first and ``beta`` is then only what is left of it, with a
    prior of ``stationary_bias_sigma_deg`` instead of ``bias_sigma_deg``. Without it the magnetometer has to teach the
    bias, and a deflection that changes steadily along a route, or a walk too short for its deflections to average
    out, passes for one. The drift elimination of the causal track (its dominant directions are learnt
    from the deflected headings) is not applied: measured on the IPIN 2023 hand-held walks it only adds back the
    deflection the smoother removed.

Model checks (:func:`smooth_track`)
    The model assumes a gyro whose residual bias is small once the stationary estimate is removed, and measured
    offsets ``z_k`` that scatter about a slowly moving ``d`` by deflections of ``sigma_mag_deg``. Both are tested on
    the plain forward filter's innovations ``nu_k`` and their variances ``S_k`` (:func:`check_model`), with the
    steps within ``deflection_corr_s`` counted as one measurement (a deflection stays while the walker crosses it):

    - **Stationary bias**: a likelihood-ratio test of the stationary prior (``stationary_bias_sigma_deg``) against
      the wide one (``bias_sigma_deg``). Above the chi-square (1 degree of freedom) quantile at
      ``consistency_p``, the magnetometer contradicts the stationary estimate (an attitude filter that learnt a
      wrong bias while the user stood, or a bias that changed since), and the bias is learnt from the
      magnetometer as on a walk without a stationary estimate. On a turning-rich walk this matters most: a
      turn makes the vertical axis sweep the device frame, so a wrong bias vector turns the gyro yaw by a
      different amount on every leg, and no short straight stretch shows it.
    - **Innovation consistency**: the sum of ``nu_k^2 / S_k`` against its chi-square bound is reported in the
      summary. It is not acted upon: on the Tyrex motion-capture walks it flags a few walks (pocket walks among
      them), and on each the smoothed heading beats the causal one (``pdr eval heading`` prints both per
      recording), so falling back to the causal heading there was worse. The pocket measurement (RMPCA, lagging
      through turns) is not the model's
      white deflection, and the robust reweighting already handles it.

Track
    Positions are re-integrated with the causal step lengths,
    ``p_k = p_k^causal + sum_j L_j (u(psi_j) - u(psi_j^causal))`` over the steps since the last position fix (a site
    landmark), so fixes and floors stay as they were (:func:`pdr.phone.track.redo_steps`).

Figures: ``pdr eval ipin /work/shared/data/ipin2023_t3/logfiles --placement hand`` scores the causal and the
smoothed tracks side by side (landmark median and p75, absolute and with the first segment aligned). The parameters
were chosen on the repetition-01 files, where the landmark p75 is flat over a wide range of ``sigma_mag_deg``, either
random walk and the bias prior (not tuned to a point), and checked on the held-out repetition-02 files; the
stationary bias prior is the one setting the repetition-01 figure is sensitive to (the tighter, the better, down to
0.01 deg/s). What is left is mostly the deflection averaged over a whole walk (about 18 deg on both walks of one
IPIN trial), which no magnetometer-referenced heading can see.

Trouser pocket: ``m_k`` is the pocket step's causal heading, the RMPCA walking direction (:mod:`pdr.phone.heading`),
and the gyro yaw is that of a device axis (:mod:`pdr.phone.gyro_yaw`; the vertical rate integrated directly would gain
the swinging thigh's geometric phase, 1-2 deg per stride). The offset is the phone's yaw in the pocket relative to the
walking direction, fixed while the phone stays put, so the smoother mostly removes the RMPCA's lag through turns; a
walk-long bias of the RMPCA direction stays: ``pdr eval pocket-heading --data /work/shared/data`` prints the simulated
pocket walks' causal and smoothed errors (the smoothed mean falls; the median, that walk-long bias, hardly moves).

The service streams the causal track; this smoother runs where the whole walk is at hand (``pdr track``, the
evaluations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters.rotation_kernels import wrap_pi
from pdr.filters.rts import rts_smooth
from pdr.frames import heading_deg_to_yaw, wrap_angle
from pdr.phone.track import redo_steps

FloatArray = NDArray[np.float64]

#: Placements the smoother handles: hand-held and torso (the step heading is the device heading plus an offset),
#: trouser pocket and swinging hand (the step heading is the walking direction from the thigh's or arm's motion;
#: the phone's yaw keeps a fixed offset to it while it stays in the pocket or the hand's grip).
SMOOTHED_PLACEMENTS = ("hand", "torso", "pocket", "swinging")


@dataclass(frozen=True)
class HeadingSmootherConfig:
    """Noise of the smoother's model (module doc).

    Attributes
    ----------
    sigma_mag_deg
        Standard deviation of a step's magnetometer-referenced heading about the true one (deg).
    heading_rw_deg
        Random walk of the gyro yaw's offset (deg per sqrt(s)).
    bias_rw_deg
        Random walk of the gyro's residual bias about the vertical (deg/s per sqrt(s)).
    bias_sigma_deg
        Prior standard deviation of that bias at the first step (deg/s) when the walk has no stationary bias
        estimate (the user never stood still): the bias is then learnt from the magnetometer alone.
    stationary_bias_sigma_deg
        The same when the attitude filter estimated the gyro bias while the user stood (the step events'
        ``gyro_bias_dps``): the gyro yaw is corrected with the walk's last estimate and the smoother learns only
        what is left of it (deg/s).
    robust_k, iterations
        Robust reweighting (:func:`smooth_offsets`): a step's measurement variance is multiplied by
        ``1 + (residual / (robust_k sigma))^2`` (Cauchy weights) from the previous pass, over ``iterations``
        passes (1: plain smoother).
    jump_deg
        A change of ``m - g`` by more than this between consecutive steps (deg) restarts the offset: the phone
        was turned about a horizontal axis, which moves the device heading but not the rotation about the vertical
        (the IPIN walks' opening calibration motion). A deflection that changes by as much within one step is
        taken for the same: the bias is then learnt from the stretches between such places only. On the IPIN
        repetition-01 files the landmark p75 is flat from 20 to 30 deg, a little worse at 45 deg and several times
        worse without the restart (``pdr eval ipin`` with ``jump_deg`` changed).
    pocket_jump_deg
        ``jump_deg`` for trouser-pocket steps. Their measurement is the RMPCA walking direction, which lags through
        a turn by 30-60 deg for a step or two, so 20 deg would restart the offset at every turn; a phone turned
        round in the pocket still restarts it. On the simulated pocket walks (``pdr eval pocket-heading``, with this
        changed) the smoothed error falls as the threshold rises from 20 to 90 deg and stays from 90 to 180 deg.
    """

    sigma_mag_deg: float = 30.0
    heading_rw_deg: float = 0.1
    bias_rw_deg: float = 0.0057
    bias_sigma_deg: float = 2.0
    stationary_bias_sigma_deg: float = 0.02
    robust_k: float = 2.0
    jump_deg: float = 20.0
    pocket_jump_deg: float = 90.0
    consistency_p: float = 0.01
    deflection_corr_s: float = 10.0
    iterations: int = 4

    def __post_init__(self) -> None:
        if not 0.0 < self.consistency_p < 1.0:
            raise InputError(f"consistency_p must lie in (0, 1), got {self.consistency_p}", field="consistency_p",
                             source="heading smoother")
        if self.iterations < 1:
            raise InputError(f"iterations must be >= 1, got {self.iterations}", field="iterations",
                             source="heading smoother")
        for name in ("sigma_mag_deg", "heading_rw_deg", "bias_rw_deg", "bias_sigma_deg", "stationary_bias_sigma_deg",
                     "robust_k", "jump_deg", "pocket_jump_deg", "deflection_corr_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be a positive number, got {v}", field=name, source="heading smoother")


def _offset_measurements(t_s: FloatArray, gyro_yaw: FloatArray, meas_yaw: FloatArray, jump_deg: float
                         ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Step times (s), the measured offsets ``z = wrap(m - g)`` (rad) and where the offset jumps between consecutive
    steps by more than ``jump_deg`` (deg): the phone was turned about a horizontal axis (handled, turned over, put
    away), which moves its device heading but not the gyro's rotation about the vertical.
    """
    t = np.asarray(t_s, dtype=np.float64)
    if np.any(np.diff(t) < 0):
        raise InputError("step times must be non-decreasing", field="t_s", source="heading smoother")
    z = np.asarray(wrap_angle(np.asarray(meas_yaw) - np.asarray(gyro_yaw)), dtype=np.float64)
    jump = np.zeros(t.size, dtype=bool)
    jump[1:] = np.abs(np.asarray(wrap_angle(np.diff(z)))) > math.radians(jump_deg)
    return t, z, jump


def smooth_offsets(t_s: FloatArray, gyro_yaw: FloatArray, meas_yaw: FloatArray, meas_sigma: FloatArray,
                   config: HeadingSmootherConfig | None = None, bias_sigma_deg: float | None = None
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Smoothed offset ``d`` (rad), its standard deviation (rad) and the bias ``beta`` (rad/s) per step.

    ``t_s`` (s, increasing), ``gyro_yaw`` and ``meas_yaw`` (rad) and ``meas_sigma`` (rad) have one value per step;
    ``bias_sigma_deg`` is the prior standard deviation of ``beta`` about zero (deg/s; default
    ``config.bias_sigma_deg``).
    Robust: the offset restarts where it jumps between steps (``config.jump_deg``), and the smoother is rerun
    ``config.iterations`` times with each step's measurement variance inflated by its last residual, so steps whose
    device heading is not the walking direction lose their pull.
    """
    c = config or HeadingSmootherConfig()
    t, z, jump = _offset_measurements(t_s, gyro_yaw, meas_yaw, c.jump_deg)
    n = t.size
    if n == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    sigma = np.asarray(meas_sigma, dtype=np.float64)
    resid = np.zeros(n)
    bias_sigma = math.radians(c.bias_sigma_deg if bias_sigma_deg is None else bias_sigma_deg)
    for _ in range(c.iterations):
        r = sigma ** 2 * (1.0 + (resid / (c.robust_k * sigma)) ** 2)      # Cauchy weights
        d, d_sigma, beta = _rts(t, z, r, jump, bias_sigma, c)
        resid = np.abs(np.asarray(wrap_angle(z - d)))
    return d, d_sigma, beta


@dataclass(frozen=True)
class ModelCheck:
    """How well the smoother's model explains a walk's measured offsets (module doc "Model checks").

    Attributes
    ----------
    log_likelihood
        Log-likelihood of the offsets under the model: the plain forward filter's (no robust reweighting)
        Gaussian innovations ``nu_k`` with variances ``S_k = P_k|k-1 + R_k`` (rad^2), summed over ``dof`` steps.
    nis
        Sum of the normalised innovation squares ``nu_k^2 / S_k`` over those steps: chi-square with ``dof``
        degrees of freedom when the model holds.
    dof
        Steps counted: all but the first and those where the offset restarts (a jump).
    """

    log_likelihood: float
    nis: float
    dof: int


def check_model(t_s: FloatArray, gyro_yaw: FloatArray, meas_yaw: FloatArray, meas_sigma: FloatArray,
                config: HeadingSmootherConfig | None = None, bias_sigma_deg: float | None = None) -> ModelCheck:
    """The innovations of the smoother's forward filter against their stated variances (:class:`ModelCheck`).

    Same arguments as :func:`smooth_offsets`; one plain forward pass with the stated measurement variances
    ``meas_sigma ** 2``.
    """
    c = config or HeadingSmootherConfig()
    t, z, jump = _offset_measurements(t_s, gyro_yaw, meas_yaw, c.jump_deg)
    n = t.size
    xf, pf = np.zeros((n, 2)), np.zeros((n, 2, 2))
    xp, pp = np.zeros((n, 2)), np.zeros((n, 2, 2))
    r = np.asarray(meas_sigma, dtype=np.float64) ** 2
    bias_sigma = math.radians(c.bias_sigma_deg if bias_sigma_deg is None else bias_sigma_deg)
    if n:
        _forward(t, z, r, jump, bias_sigma ** 2, math.radians(c.heading_rw_deg) ** 2,
                 math.radians(c.bias_rw_deg) ** 2, xf, pf, xp, pp)
    used = ~jump
    used[:1] = False
    nu = np.asarray(wrap_angle(z - xp[:, 0]))[used]
    s = (pp[:, 0, 0] + r)[used]
    nis = float(np.sum(nu ** 2 / s))
    return ModelCheck(log_likelihood=float(-0.5 * (np.sum(np.log(2.0 * math.pi * s)) + nis)), nis=nis,
                      dof=int(used.sum()))


def _rts(t: FloatArray, z: FloatArray, r: FloatArray, jump: NDArray[np.bool_], bias_sigma: float,
         c: HeadingSmootherConfig) -> tuple[FloatArray, FloatArray, FloatArray]:
    """One forward Kalman filter (:func:`_forward`) and the backward pass (:func:`pdr.filters.rts.rts_smooth`)
    of the module's model (``bias_sigma``: prior standard deviation of the bias, rad/s).
    """
    n = t.size
    xf, pf = np.zeros((n, 2)), np.zeros((n, 2, 2))      # filtered
    xp, pp = np.zeros((n, 2)), np.zeros((n, 2, 2))      # predicted
    fs = np.tile(np.eye(2), (n, 1, 1))                  # fs[k]: transition from step k - 1 to k
    fs[1:, 0, 1] = np.diff(t)
    _forward(t, z, r, jump, bias_sigma ** 2, math.radians(c.heading_rw_deg) ** 2, math.radians(c.bias_rw_deg) ** 2,
             xf, pf, xp, pp)
    xs, ps = rts_smooth(xf, pf, xp, pp, fs)
    return xs[:, 0], np.sqrt(np.maximum(ps[:, 0, 0], 0.0)), xs[:, 1]


@njit(cache=True)
def _forward(t: FloatArray, z: FloatArray, r: FloatArray, jump: NDArray[np.bool_], bias_var: float, q_d: float,
             q_b: float, xf: FloatArray, pf: FloatArray, xp: FloatArray,
             pp: FloatArray) -> None:  # pragma: no cover - compiled
    """The forward filter of the offset ``d`` (rad) and bias ``beta`` (rad/s) over the steps, in place.

    Transition ``d_k = d_k-1 + dt beta_k-1`` with the integrated random walks ``q_b`` (bias, rad^2/s^3) and
    ``q_d`` (offset, rad^2/s), the offset's variance raised by pi^2 at a ``jump``; measurement ``z_k = d_k``
    (wrapped innovation) with variance ``r_k`` (rad^2). Writes the predicted ``xp, pp`` and filtered ``xf, pf``
    means (K, 2) and covariances (K, 2, 2) that :func:`pdr.filters.rts.rts_smooth` takes. A compiled loop: the
    smoothed track of a 2-hour session (13 000 steps, four passes) is served on request.
    """
    x0, x1 = z[0], 0.0
    p00, p01, p10, p11 = r[0], 0.0, 0.0, bias_var
    for k in range(t.size):
        if k:
            dt = t[k] - t[k - 1]
            q00 = q_b * dt ** 3 / 3.0 + q_d * dt + (math.pi ** 2 if jump[k] else 0.0)
            q01 = q_b * dt ** 2 / 2.0
            x0 = x0 + dt * x1
            # F P F^T + Q with F = [[1, dt], [0, 1]].
            a00 = p00 + dt * p10
            a01 = p01 + dt * p11
            p00, p01, p10, p11 = a00 + dt * a01 + q00, a01 + q01, p10 + dt * p11 + q01, p11 + q_b * dt
        xp[k, 0], xp[k, 1] = x0, x1
        pp[k, 0, 0], pp[k, 0, 1], pp[k, 1, 0], pp[k, 1, 1] = p00, p01, p10, p11
        innov = wrap_pi(z[k] - x0)
        g0 = p00 / (p00 + r[k])
        g1 = p10 / (p00 + r[k])
        x0 += g0 * innov
        x1 += g1 * innov
        p00, p01, p10, p11 = p00 - g0 * p00, p01 - g0 * p01, p10 - g1 * p00, p11 - g1 * p01
        xf[k, 0], xf[k, 1] = x0, x1
        pf[k, 0, 0], pf[k, 0, 1], pf[k, 1, 0], pf[k, 1, 1] = p00, p01, p10, p11


def smooth_track(steps: list[dict[str, Any]], config: HeadingSmootherConfig | None = None
                 ) -> tuple[list[dict[str, Any]], str | None]:
    """Smoothed copies of a finished walk's step events (:mod:`pdr.phone.pipeline`) and a one-line summary.

    Steps of other placements, or without a gyro, are returned unchanged with the reason as the summary.
    The copies carry ``"smoothed": True``, the smoothed ``heading_deg`` and ``heading_sigma_deg`` and the
    re-integrated ``east_m``/``north_m``.
    """
    out = [dict(s) for s in steps]
    if not out:
        return out, None
    usable = [s.get("placement") in SMOOTHED_PLACEMENTS and s.get("gyro_heading_deg") is not None for s in out]
    if not all(usable):
        return out, ("heading not smoothed: the smoother needs a hand-held, torso or trouser-pocket phone with a "
                     f"gyroscope ({sum(usable)} of {len(out)} steps qualify)")
    c = config or HeadingSmootherConfig()
    if any(s.get("placement") in ("pocket", "swinging") for s in out):
        # A swinging phone's step heading (thigh or arm) jumps more than a held one's; a walk whose placement
        # changed has the offset jump at the change.
        c = replace(c, jump_deg=c.pocket_jump_deg)
    t = np.array([s["t_s"] for s in out], dtype=np.float64)
    gyro = np.asarray(heading_deg_to_yaw(np.array([s["gyro_heading_deg"] for s in out])), dtype=np.float64)
    raw = np.asarray(heading_deg_to_yaw(np.array([s["heading_raw_deg"] for s in out])), dtype=np.float64)
    sigma = np.array([math.radians(s["heading_sigma_deg"]) if s.get("landmark_heading") else
                      math.radians(c.sigma_mag_deg) for s in out])
    bias_sigma = None
    notes: list[str] = []
    # Steps per deflection: the checks' statistics count independent deflections, not steps (deflection_corr_s).
    per_deflection = max(1.0, c.deflection_corr_s * (len(out) - 1) / max(float(t[-1] - t[0]), 1e-9))
    known = [s for s in out if s.get("gyro_bias_dps") is not None and s.get("up_time_s") is not None]
    if known:
        # The walk's last stationary bias estimate (device frame), removed from the gyro yaw: it added
        # up_time . b to it (pdr.phone.pipeline); the smoother then learns only the residual.
        b = np.radians(np.asarray(known[-1]["gyro_bias_dps"], dtype=np.float64))
        up_time = np.array([s.get("up_time_s") or [math.nan] * 3 for s in out], dtype=np.float64)
        if np.isfinite(up_time).all():
            gyro = gyro - up_time @ b
            bias_sigma = c.stationary_bias_sigma_deg
            # Likelihood-ratio test of the stationary estimate (module doc "Model checks"): does the magnetometer
            # agree with a residual bias near zero, or does it need the wide prior of a walk without one?
            tight = check_model(t, gyro, raw, sigma, c, c.stationary_bias_sigma_deg)
            wide = check_model(t, gyro, raw, sigma, c, c.bias_sigma_deg)
            lr = 2.0 * (wide.log_likelihood - tight.log_likelihood) / per_deflection
            if lr > chi2_quantile(1.0 - c.consistency_p, 1.0):
                bias_sigma = c.bias_sigma_deg
                notes.append(f"the stationary gyro bias estimate disagrees with the magnetometer (likelihood ratio "
                             f"{lr:.1f}): the bias is learnt from the magnetometer")
    check = check_model(t, gyro, raw, sigma, c, bias_sigma)
    dof = check.dof / per_deflection
    bound = chi2_quantile(1.0 - c.consistency_p, max(dof, 1.0))
    if check.dof and check.nis / per_deflection > bound:
        # Reported, not acted on (module doc "Model checks": falling back to the causal heading there was worse).
        notes.append(f"the magnetometer-gyro offsets are inconsistent with the model (innovation chi-square "
                     f"{check.nis / per_deflection:.0f} over {dof:.0f} deflections, {100 * (1 - c.consistency_p):.0f}% "
                     f"bound {bound:.0f})")
    d, d_sigma, beta = smooth_offsets(t, gyro, raw, sigma, c, bias_sigma)
    yaw = np.asarray(wrap_angle(gyro + d), dtype=np.float64)
    out = redo_steps(out, yaw)
    for k, s in enumerate(out):
        s["heading_sigma_deg"] = math.degrees(float(d_sigma[k]))
        s["smoothed"] = True
    return out, (f"heading smoothed over {len(out)} steps: residual gyro bias about the vertical "
                 f"{math.degrees(float(np.median(beta))):+.3f} deg/s" + "".join(f"; {n}" for n in notes))


def chi2_quantile(q: float, dof: float) -> float:
    """The ``q`` quantile (0 < q < 1) of the chi-square distribution with ``dof`` degrees of freedom:
    ``2 P^-1(dof / 2, q)``, ``P`` the regularised lower incomplete gamma function.

    The value ``scipy.stats.chi2.ppf(q, dof)`` gives, bit for bit (it computes the same expression), without
    importing :mod:`scipy.stats` (about 2 s of a ``pdr track`` process's CPU).
    """
    from scipy.special import gammaincinv  # imported when a walk is smoothed (about 0.3 s)
    return float(2.0 * gammaincinv(dof / 2.0, q))


def smoothed_rows(rows: list[dict[str, Any]], notices: list[str]) -> list[dict[str, Any]]:
    """The offline-smoothed track (:func:`smooth_track`); its summary joins ``notices``."""
    out, summary = smooth_track(rows)
    if summary:
        notices.append(summary)
    return out
