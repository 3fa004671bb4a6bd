"""Walking direction of a swinging phone (trouser pocket, swinging hand): the swing plane's axis and the
forward/backward decision from the centripetal acceleration in turns.

All angles are internal yaw (rad, counter-clockwise from east, ENU). The figures these mechanisms achieve are
printed by the evaluations, not kept here: ``pdr eval heading /work/shared/data/attitude_smartphones`` (the
motion-capture benchmark: causal and smoothed walking-direction error per recording, per carriage and field,
per walker) and ``pdr eval pocket-heading --data /work/shared/data`` (simulated pocket walks' mean error, the
direction flips of the real MobiFall and Oxford pocket walks).

Swing-plane axis (:func:`swing_plane_axis`)
    A phone in a swinging hand turns with the arm, and one in a trouser pocket with the thigh, about the
    shoulder's or hip's lateral axis ``r = f x u`` (``f`` walking direction, ``u`` up). Over a stride the
    horizontal part of the navigation-frame angular rate therefore lies along ``+/-r``: the principal axis of
    its 2x2 scatter is ``r``, and the walking line is perpendicular to it. The device's own yaw plays no part,
    so it holds whatever way the phone sits in the hand.

Forward or backward (:func:`turn_evidence`; which rule decides and why)
    The walking line has two directions. Walking at speed ``V`` along ``f`` while turning at the yaw rate
    ``Omega``, the body's mean horizontal acceleration over a stride is the centripetal ``V Omega (u x f)``,
    whatever the gait or the carriage: it is the only horizontal acceleration that does not average out over a
    stride (the gait's fore-aft and lateral oscillations and the limb's swing all do). For a candidate
    direction ``p`` the evidence is ``Omega * (a_mean . (u x p))``: ``V Omega^2 > 0`` for ``p = f`` and the
    opposite for ``p = -f``. It is scaled by ``v_ref * omega_ref^2`` and clipped to [-1, 1], so a straight
    stride (``Omega`` near 0) carries no evidence and a clear turn one full vote. It needs no assumption on the
    arm's or thigh's swing, which is why it decides for the swinging hand, whose swing is nearly symmetric (the
    thigh-swing skewness of :func:`pdr.phone.heading.thigh_swing_evidence` is near chance there). In a trouser
    pocket the skewness decides, with the turn cue as a light second vote (below, "Trouser pocket: continuity"),
    accumulated by :class:`pdr.phone.heading.DirectionVote`: the skewness is reliable in a front pocket but near
    chance in a back pocket and when running (the back of the thigh and a running thigh lack the
    slow-stance/fast-swing asymmetry at the pocket), where the turn cue is the one that is right. The
    correlation of vertical and forward acceleration over the stride changes sign between front and back
    pockets, so it cannot decide without knowing which pocket.

    What limits it: a tilt error ``d`` of the attitude adds ``g d`` (0.17 m/s^2 per degree) to the mean
    horizontal acceleration, against a centripetal term of about 0.5 m/s^2 (1.2 m/s turning 23 deg/s). The
    attitude filter's accelerometer rows take a swinging arm's specific force (along the arm) for gravity, so
    with our attitude the cue is right less often than with the motion-capture one. At full weight in a pocket
    it flips the straight MobiFall pocket walks (their few turns are pivots, not the steady turn the cue
    assumes); hence the gate and the weight below.

Device-frame swing axis of a swinging hand (:class:`DeviceSwingAxis`; item 5 of issue 25)
    A hand's grip holds the phone still relative to the forearm for minutes, and the arm swings about the
    shoulder's lateral axis ``r``: ``r`` is the rotation's axis, so it is the same vector in the navigation frame
    and in the device frame. The device-frame angular rate ``omega_b`` therefore scatters along one fixed device
    axis ``r_b``, the principal axis of its 3x3 scatter accumulated over strides (memory ``1 / (1 - decay)``
    strides, so a new grip is followed). Each stride's walking direction is ``f = u x C_nb r_b`` (horizontal
    part, averaged over the stride). Two things follow that the per-stride swing plane lacks: the line comes
    from tens of strides of gyro data instead of one, and the forward/backward choice is the sign of ``r_b``,
    one bit for the whole grip: the turn evidence (above) of every turning stride is summed on that one sign
    (memory ``1 / (1 - sign_decay)`` strides; as in the pocket, only strides that turn steadily at a walking or
    running speed count, :data:`TURN_SPEED_MPS`) instead of being carried from stride to stride through the
    yaw's continuity, where a misread turn flipped the direction for several strides. When the principal axis
    moves by more than ``regrip_deg`` between strides (the phone changed hands or grip) the sign's evidence
    restarts. The memories were checked on the benchmark's tuning walker only, where the error is flat over a
    wide range of them; the other walker confirms (``pdr eval heading``, swinging-hand lines). In a trouser
    pocket the same tracker reverses many steps: a thigh's rotation is not a fixed-axis swing (the knee's
    flexion, the thigh's axial rotation and the pelvis' tilt add other device-frame axes), so it is used for
    the swinging hand only.

    What limits it: with the motion-capture attitude the per-stride swing plane of the swinging hand is close
    to the walking direction; with the attitude filter's, what is left is the attitude's yaw error, the arm's
    swing plane turned from the walking direction by a constant per walker (median error of the swing axis per
    walk: +17 and +19 deg for the tuning walker, -6 and -2 for the other, with attitude yaw errors of 3.6-17.8 deg),
    and the truth's own arm swing: the benchmark's walking path is the phone's position averaged over 1 s, while
    these walkers' strides last 1.4-1.7 s, so part of the arm's swing stays in the path and its step directions
    zigzag from step to step (median 10-21 deg off the mean of their two neighbours, against 2-6 deg in the pocket
    walks; averaged over each walk's own stride, 6-13 deg, and our error falls by 1-5 deg). The walker's offset is
    not learnt as the pocket's is: the step-frequency axis of the specific force (the pocket's unbiased second
    measurement) carries no fore-aft signal in a swinging hand (per stride its error scatters over the whole half
    circle, 1.48 MAD 51-67 deg; pooled over a walk in the walking frame its ellipse's axis ratio is 1.1-1.4).
    Removing the arm's own motion first does not rescue it: with the motion-capture attitude, the phone's linear
    acceleration less that of a rigid lever ``rho_b`` turning with the gyro's rate (``alpha x rho + omega x (omega x
    rho)``, ``rho_b`` fitted by least squares per walk: 0.25-0.41 m) leaves a step-frequency axis whose per-stride
    error still scatters by 1.48 MAD 32-56 deg, with walk medians of +12, +17, -19 and +7 deg (not unbiased).
    The pooled axis is not always the shoulder's: in three of the benchmark's four swinging walks it is mostly the
    forearm's twist about the vertical (its vertical component in the navigation frame, median per walk: 0.76, 0.66
    and 0.52; 0.11 on the one clean swing), so the walking direction comes from its horizontal remainder, and a small
    change in how the hand twists the phone moves the output by 70-150 deg without moving the axis by
    ``regrip_deg`` (the other walker's disturbed walk at 93-96 s). Tried and not adopted: a stride whose own
    horizontal swing plane is planar (eigenvalue ratio 5 or more) and more than 2.58 sigma from the pooled direction
    takes its own line, with the direction nearer the last stride's turned by the gyro. It changed six strides of
    one walk of the confirmation walker (causal 29.6 -> 25.1 deg) and no scored stride of the tuning walker; the
    smoothed means went 21.2 -> 21.3 deg over the four walks. Restarting the pooled scatter from such a stride, with
    the sign by continuity, was much worse (disturbed walks 19.4 -> 42-48 and 29.6 -> 49-63 deg).
    Nor does the centripetal acceleration give the offset: per turning stride (mean yaw rate above 0.2-0.5 rad/s)
    the direction it implies, ``u x f`` turned back by 90 deg, scatters about the truth by 1.48 MAD 66-103 deg with
    the filter's attitude, and its walk medians (-8, +18, -25, -6 deg) carry the same per-walker offsets as the
    swing axis (an offline study over the four swinging walks, not built).

Trouser pocket: the walking line from stride to stride (:class:`WalkingLineFilter`)
    One stride's swing plane is a noisy measurement of the walking line. The walker's turn between two strides
    is known far better: the change of the stride-mean rotation about the vertical (a whole gait cycle, so the
    thigh's own swing averages out). A Kalman filter on the line (mod 180 deg) therefore predicts with the turn
    and updates with the stride. Its noises are properties of the data, not tuned: on the motion-capture
    benchmark's pocket walks with the pipeline's attitude, one stride's swing-plane line scatters about each
    walk's own median with a robust spread (1.48 MAD) of 12.8 deg (tuning walker) and 12.0 deg (the other), and
    the stride-mean turn differs from the true change of walking direction by 5.3 and 6.0 deg (1.48 MAD, the
    truth's own step-to-step noise included): hence ``line_sigma_deg`` 13 and ``turn_sigma_deg`` 5. It is not
    used for the swinging hand, where :class:`DeviceSwingAxis` already pools the strides.

    A stride whose swing is not planar measures its line worse: the principal axis of a nearly round scatter is
    poorly defined. Each stride's swing-plane row therefore adds the sampling variance of a principal axis
    (:func:`axis_variance`: eigenvalue ratio ``r`` over ``n`` samples, ``r / ((r - 1)^2 n)``) to
    ``line_sigma_deg``, which stays as the floor of a well-defined plane. It has no constant of its own: ``n`` is
    the stride's count of attitude samples, and the measured spreads below match the formula with the samples taken
    as independent within a factor of about two. On the
    benchmark's pocket walks the swing plane's spread about the truth (1.48 MAD, tuning walker) is 32, 27, 21, 13,
    13 and 12 deg for ratios in [1, 1.3), [1.3, 1.6), [1.6, 2), [2, 3), [3, 5) and 5 or more; low ratios are mostly
    running strides, a running thigh's swing being less planar. Causal mean error (``pdr eval heading``), tuning
    walker: running 11.3 -> 8.9 deg, back pocket 7.0/7.4 -> 6.4/7.1, front pocket 7.1/8.4 -> 7.0/8.1 (disturbed /
    clean); the other walker: 9.7 -> 9.7, 10.1/5.3 -> 9.7/5.3, 15.7/9.3 -> 15.7/9.4. Smoothed, the tuning walker's
    running walk went 5.4 -> 6.3 deg (its constant offset -3.4 -> -4.8 deg), the other pocket walks within
    0.4 deg.

    The swing plane is not square to the walking direction: the thigh's sagittal plane is turned by the leg's
    rotation about its own axis (toe-out, hip rotation), by a constant of either sign per walker and pocket (the
    swing plane's median error per walk, motion-capture attitude: -21 and -17 deg front pocket, -8 and -14 back
    pocket for the tuning walker; +4, +9, -14, +5 for the other). The filter learns it as a second state, the
    swing plane's offset, from an unbiased second measurement: :func:`step_frequency_axis`, the axis of the
    horizontal specific force at the step frequency. Walking is an inverted pendulum: the body brakes after each
    heel strike and is pushed on before each toe-off, so at the step frequency it oscillates along the walking
    direction, whatever the thigh does (its swing, and the body's lateral sway, are at the stride frequency).
    Measured per stride on the benchmark's walking pocket walks: median errors of +1 to +9 deg per walk, a robust
    spread of 14.6 deg about them on the tuning walker (``step_sigma_deg`` 15; 17.4 on the other). It is noisier
    than the swing plane but unbiased, so together the line gets the swing plane's precision without its offset.
    The offset's prior (20 deg) covers the offsets above; it may drift by ``bias_walk_deg`` (0.1 deg) a stride as
    the phone settles in the pocket. The offset is the leg's, so it barely moves while the phone stays put: with a
    walk of 1 deg a stride the filter chased the step-frequency axis' noise, and the filtered line scattered more
    than the raw swing plane in every front pocket (1.48 MAD about the walk's median, motion-capture benchmark:
    15.3 -> 20.7, 10.2 -> 15.8, 18.0 -> 16.5, 13.6 -> 16.8 deg). Chosen on the tuning walker among 2, 1, 0.5, 0.25,
    0.1 and 0 deg (pocket walks' causal mean, front / back: 8.2/7.3, 8.0/7.2, 7.8/7.2, 7.8/7.2, 7.8/7.2, 7.8/7.2;
    ``pdr eval heading``), confirmed on the other (13.4/8.7, 13.1/8.3, 12.7/7.8, 12.3/7.4, 12.4/7.4, 12.3/7.4);
    the simulated pocket walks (``pdr eval pocket-heading``) 13.1 -> 12.9 deg, MobiFall and Oxford flips unchanged.

    The simulator's thighs disagree: there the step-frequency axis is off by +13 to +17 deg on the left thigh and
    -13 to -18 on the right (median per walk, five walks each) even with the true attitude, 1.48 MAD 0.9-1.4 deg,
    and the filter duly learns that offset, which is why the simulated pocket walks stay at 12-25 deg (left) and
    5-13 (right). Most of it comes from the simulated pelvis' rotation (its yaw times the thigh's swing has a
    step-frequency part across the walking direction: without it the left walks' axis moved from +20, +12, +27 to
    +8, +1, +14 deg with the filter's attitude). The real walks' +1 to +9 deg above say the simulator exaggerates it;
    which real thigh the phone was on is not recorded, so the side dependence is not checked on real data.

    Running is not an inverted pendulum (the stance leg is a spring, with a flight phase): the step-frequency
    axis was 25 and 17 deg off on the benchmark's running walks, where the swing plane was within 4 and 7 deg.
    A bout whose median stride of the last five is shorter than
    :data:`pdr.phone.heading_stages.WALKING_MIN_STRIDE_S` (a cadence above 2 steps/s; the benchmark's walks step
    at 1.5-1.9 steps/s, its runs at 2.8-2.9) is taken for running: the swing plane is used as it is, and the
    offset, the walking thigh's, is neither applied nor learnt. A stride more than a quarter off that median (a
    step missed or found twice) is not one gait cycle, and its harmonics are not taken either.

    What limits it: the walking line's error grows with the turn rate in a front pocket (below, "front or
    back"). The offline smoother, which carries the heading on the gyro, does not have it.

Trouser pocket: front or back, and the lead in turns (:class:`PocketSide`)
    In a front pocket the walking direction trails the path through turns: its error regressed on the true turn
    rate has slopes of -0.42, -0.49 (tuning walker), -0.52 and -0.21 s (the other), about the half step between
    the stride's centre and the step's; in a back pocket it does not (-0.07, -0.02, +0.09, +0.06 s). Why the
    back pocket's line is already at the step's centre is not explained; the difference is measured
    (``pdr eval heading --steps DIR``, step tables). Which side of the thigh the phone is on is seen in the
    stride's correlation of forward and vertical specific force: the thigh swings about the hip, and a point in
    front of its long axis (offset ``d`` forward) rises as the thigh swings forward (its height carries
    ``d sin(theta)`` while its forward position carries ``L sin(theta)``), so the two covary with the sign of
    ``d``. Median per stride, with the true walking direction: +0.23, +0.23 front and -0.21, -0.35 back for the
    tuning walker; +0.39, +0.02 front and -0.11, -0.03 back for the other (whose disturbed-field pair is
    ambiguous). :class:`PocketSide` sums it over about ten strides along the resolved direction and grades the
    half-step lead of :func:`step_lead` from 0 (behind the thigh, or no evidence) to 1 (mean correlation 0.2),
    in walking strides only (a running thigh's pattern is not a walking one). Front pockets went from 14.1 and
    15.6 to 9.3 and 8.3 deg (tuning walker) and from 15.9 and 15.1 to 13.6 and 15.5 (the other); the back
    pockets and runs did not change by more than 0.2 deg (``pdr eval heading``).

Turns
    A direction measured over a stride is the walking direction at the stride's centre, while a step's
    direction is wanted at the step's centre, half a step later. The benchmark's walkers turn at 23 deg/s on
    average and up to 50 deg/s, which made the swinging hand's heading lag by a step through every turn.
    :func:`step_lead` carries it forward by the stride's mean rate about the vertical. In a trouser pocket the
    same lead helped one walker, not the other, and made the smoothed heading worse: the pocket's swing plane is
    dominated by the fast swing of the pocket's thigh, which falls in one of the stride's two steps, so its time
    is not the stride's centre. It is applied to the swinging hand only.

Trouser pocket: continuity (:class:`DeviceFrameDirection`; item 4 of issue 25)
    The pocket's walking line is re-measured every stride (swing plane or RMPCA), and one of its two
    directions must be picked. That choice used to follow the previous step's heading turned by the device's
    rotation about the vertical between the two steps' mid-points, which in a pocket include opposite phases
    of the thigh's swing: in the benchmark's continuous turns it chose the wrong direction for blocks of steps
    until the vote undid it. What stays fixed while the phone stays in the pocket is the walking direction
    in the device frame averaged over a stride (the thigh swings about its mean attitude): ``d_b``, the
    stride-mean ``C_nb^T p`` of the chosen direction, blended over about five strides. Each stride takes the
    direction nearer ``d_b``; a reversal by the vote reverses ``d_b`` too. The vote then adds to the skewness
    the turn cue, only for strides whose implied speed ``|a_lat / Omega|`` is a walking or running speed
    (0.4-4 m/s: not a pivot on the spot or a tilt error), at weight 0.1.

    Why 0.1 and the gate: the turn cue is right where the skewness is at chance (back pocket, running), but on
    straight walks with pivots, at a walk's start and on the simulator it costs. Weights 1 and 0.25 raised the
    simulated pocket walks' error and the MobiFall and Oxford flips (``pdr eval pocket-heading`` with
    :data:`pdr.phone.heading_stages.POCKET_TURN_WEIGHT` changed); weight 0
    (skewness only) leaves the benchmark's clean back-pocket walks backwards from start to end, the skewness
    there being at chance (``pdr eval heading``, back-pocket lines); 0.1 with the speed and along-track gates
    costs nothing measurable on the first and fixes the second. The reversed steps left are the first few of a
    walk (the vote's first decision).

    Tried and not adopted: the inverted pendulum's phase as a third vote (the body is highest and slowest at
    mid-stance, so at the step frequency the forward acceleration leads the vertical one by a quarter of a step:
    the quadrature pointed forward in 91-100 % of the strides of every walking pocket walk of the benchmark,
    front and back). At full weight it cut the direction flips of the MobiFall pocket walks from 3 to 1 and of
    Oxford's from 11 to 4, but running turns it round (the stance leg is a spring: 9 % forward on one of the
    benchmark's runs) and a runner slowing down to a jog at a walking cadence was turned backwards for 4 s
    (that run 12.7 -> 17.7 deg). A gait cue that tells a jog from a walk would let it in.

Trouser pocket: other lines tried
    Seed 003's RMPCA of the specific force is off the other way from the swing plane on one walker but not on the
    other, so no fixed combination of the two cancels the swing plane's offset; the centripetal acceleration
    (the one other unbiased cue) gives the direction too coarsely per turning stride, with the filter's tilt,
    to learn it. The step-frequency axis above is what does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.phone.heading import pca_axis

FloatArray = NDArray[np.float64]

#: Reference walking speed (m/s) and turn rate (rad/s) of a full vote: 1 m/s turning 17 deg/s.
V_REF_MPS = 1.0
OMEGA_REF_RPS = 0.3
#: Speeds (m/s), walking to running, at which a stride's centripetal acceleration is taken as turn evidence
#: (:func:`turn_evidence`'s ``speed_range_mps``): outside them it is a pivot on the spot, a start or a stop, or a tilt
#: error.
TURN_SPEED_MPS = (0.4, 4.0)


def nav_angular_rate(q_nb: FloatArray, rate_hz: float) -> FloatArray:
    """Navigation-frame angular rate (rad/s, ENU) between consecutive attitudes, (N - 1, 3).

    ``q_{k+1} = dq q_k`` with ``dq = exp(omega_n / rate_hz)``.
    """
    q = np.asarray(q_nb, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 3:
        raise InputError("need (N >= 3, 4) attitude quaternions", source="walking direction")
    return np.asarray(quat.to_rotvec(quat.multiply(q[1:], quat.conjugate(q[:-1]))) * rate_hz)


def swing_plane_axis(q_nb: FloatArray, rate_hz: float) -> tuple[float, float]:
    """Walking line of one stride from the swing plane: (yaw in (-pi/2, pi/2], eigenvalue ratio).

    The line is perpendicular to the principal axis (:func:`pdr.phone.heading.pca_axis`) of the horizontal
    navigation-frame angular rate (module doc); the ratio of the two eigenvalues (>= 1) says how planar the
    swing was.
    """
    axis, ratio = pca_axis(nav_angular_rate(q_nb, rate_hz)[:, :2])
    line = axis + math.pi / 2
    return float(line - math.pi if line > math.pi / 2 else line), ratio


def axis_variance(ratio: float, n: int) -> float:
    """Sampling variance (rad^2) of a principal axis' angle measured from ``n`` samples whose 2x2 scatter has the
    eigenvalue ratio ``ratio`` (>= 1): ``ratio / ((ratio - 1)^2 n)``, the large-sample variance of an eigenvector's
    angle (it underestimates a nearly round scatter of few samples, ``n (ratio - 1)^2 / ratio`` below about 20),
    capped at that of an angle spread evenly over the half circle (pi^2 / 12: no axis at all).
    """
    cap = math.pi ** 2 / 12.0
    if not (ratio > 1.0 and n > 0):
        return cap
    return min(ratio / ((ratio - 1.0) ** 2 * n), cap)


def step_harmonic(f_n: FloatArray) -> NDArray[np.complex128]:
    """(3,) complex amplitudes ``A`` of the specific force ``f_n`` (N, 3; m/s^2, ENU) over exactly one stride at
    twice the stride frequency (the step frequency): ``f ~ Re(A exp(i w t))``.
    """
    f = np.asarray(f_n, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 5:
        raise InputError("need (N >= 5, 3) specific forces over one stride", source="walking direction")
    n = f.shape[0]
    return np.asarray((np.exp(-4j * np.pi * np.arange(n) / n) @ f) * (2.0 / n))


def step_frequency_axis(f_n: FloatArray) -> tuple[float, float]:
    """Walking line of one stride from the body's fore-aft oscillation at the step frequency: (yaw in
    (-pi/2, pi/2], eigenvalue ratio >= 1).

    ``f_n`` (N, 3) is the specific force (m/s^2, ENU) over exactly one stride, so its second harmonic is at the step
    frequency. A walker vaults over the stance leg at every step (the inverted pendulum of walking): braking after
    heel strike, propulsion before toe-off, so the body's horizontal acceleration at the step frequency lies along
    the walking direction; the lateral sway is at the stride frequency. The line is the principal axis of the
    harmonic's horizontal ellipse, ``Re(A A^H)`` with ``A`` its complex amplitude; the thigh's own rotation plays
    no part in it (module doc, "Trouser pocket: the walking line from stride to stride").
    """
    amp = step_harmonic(f_n)[:2]
    scatter = np.real(np.outer(amp, np.conj(amp)))
    vals, vecs = np.linalg.eigh(scatter)
    line = math.atan2(float(vecs[1, 1]), float(vecs[0, 1]))
    ratio = float(vals[1] / vals[0]) if vals[0] > 0.0 else math.inf
    return _line(line), ratio


def turn_evidence(f_n: FloatArray, yaw_rate_rps: float, yaw: float, v_ref_mps: float = V_REF_MPS,
                  omega_ref_rps: float = OMEGA_REF_RPS, speed_range_mps: tuple[float, float] | None = None) -> float:
    """Evidence in [-1, 1] that ``yaw`` (rad) is the walking direction, from the centripetal acceleration.

    With ``speed_range_mps`` (m/s) a stride counts only as a steady turn at a walking speed: the implied speed
    ``|a_lat / Omega|`` within the range and the mean acceleration along ``yaw`` no larger than across it.

    Parameters
    ----------
    f_n
        (N, 3) specific force over one stride (m/s^2, ENU).
    yaw_rate_rps
        Mean rotation rate about the vertical over the stride (rad/s, counter-clockwise positive).
    yaw
        Candidate walking direction (rad).
    """
    f = np.asarray(f_n, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 1:
        raise InputError("need (N >= 1, 3) specific forces", source="walking direction")
    mean_h = f[:, :2].sum(axis=0) / f.shape[0]
    lateral = float(-mean_h[0] * math.sin(yaw) + mean_h[1] * math.cos(yaw))   # a . (u x p)
    if speed_range_mps is not None:
        along = float(mean_h[0] * math.cos(yaw) + mean_h[1] * math.sin(yaw))
        if abs(along) > abs(lateral) or not (
                speed_range_mps[0] * abs(yaw_rate_rps) <= abs(lateral) <= speed_range_mps[1] * abs(yaw_rate_rps)):
            # Not a steady turn at a walking speed: speeding up or slowing down (a walk's start), turning on
            # the spot, or a tilt error.
            return 0.0
    return float(np.clip(yaw_rate_rps * lateral / (v_ref_mps * omega_ref_rps ** 2), -1.0, 1.0))


def step_lead(q_nb: FloatArray, rate_hz: float, step_start: int) -> float:
    """Yaw (rad) the walker turns between the centre of a stride and the centre of its last step.

    ``q_nb`` (N, 4) are the stride's attitudes and ``step_start`` the index of its last step's first sample. A
    direction measured over the stride (its swing plane or swing axis) is the walking direction at the stride's
    centre, half a step before the step's centre: in a turn at the yaw rate ``Omega`` it lags by
    ``Omega * step_start / (2 rate_hz)`` (module doc, "Turns"). ``Omega`` is the stride's mean rotation rate
    about the vertical: the limb's swing is about a horizontal axis, so over a stride the device turns as the
    walker does.
    """
    q = np.asarray(q_nb, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 2 or not 0 <= step_start < q.shape[0]:
        raise InputError("need (N >= 2, 4) attitude quaternions and a step start inside them",
                         source="walking direction")
    return yaw_rate(q, 1.0) * step_start / 2.0


def yaw_rate(q_nb: FloatArray, rate_hz: float) -> float:
    """Mean rotation rate about the vertical (rad/s) over attitudes ``q_nb`` (N >= 2, 4) at ``rate_hz`` (Hz):
    the vertical component of the rotation from the first to the last, over the time between them.
    """
    dyaw = float(quat.to_rotvec(quat.multiply(q_nb[-1], quat.conjugate(q_nb[0])))[2])
    return dyaw * rate_hz / max(q_nb.shape[0] - 1, 1)


def body_angular_rate(q_nb: FloatArray, rate_hz: float) -> FloatArray:
    """Device-frame angular rate (rad/s) between consecutive attitudes, (N - 1, 3): ``q_{k+1} = q_k exp(omega_b /
    rate_hz)``.
    """
    q = np.asarray(q_nb, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] < 3:
        raise InputError("need (N >= 3, 4) attitude quaternions", source="walking direction")
    return np.asarray(quat.to_rotvec(quat.multiply(quat.conjugate(q[:-1]), q[1:])) * rate_hz)


@dataclass
class DeviceSwingAxis:
    """Walking direction of a swinging hand from the swing axis fixed in the device frame (module doc).

    Feed every stride in order with :meth:`update`; it returns the walking yaw (rad, ENU).
    """

    decay: float = 0.95
    sign_decay: float = 0.99
    regrip_deg: float = 45.0
    scatter: list[float] = field(default_factory=lambda: [0.0] * 9)
    axis_b: list[float] | None = None
    score: float = 0.0

    def update(self, q_nb: FloatArray, f_n: FloatArray, rate_hz: float, step_start: int = 0) -> float:
        """Walking yaw (rad) of one stride from its attitudes ``q_nb`` (N, 4) and specific force ``f_n`` (N, 3,
        m/s^2, ENU) at ``rate_hz`` (Hz): at the centre of its last step, which starts at sample ``step_start``
        (:func:`step_lead`; 0: at the stride's centre).
        """
        w = body_angular_rate(q_nb, rate_hz)
        s = self.decay * np.array(self.scatter).reshape(3, 3) + w.T @ w / w.shape[0]
        self.scatter = s.ravel().tolist()
        r = np.linalg.eigh(s)[1][:, -1]
        if self.axis_b is not None:
            prev = np.array(self.axis_b)
            if float(r @ prev) < 0.0:
                r = -r
            if float(r @ prev) < math.cos(math.radians(self.regrip_deg)):
                self.score = 0.0                                     # a new grip: decide the sign again
        r_n = quat.rotate(q_nb, np.tile(r, (q_nb.shape[0], 1))).sum(axis=0)
        yaw = math.atan2(float(r_n[0]), float(-r_n[1]))              # f = u x r_n = (-r_y, r_x)
        self.score = self.sign_decay * self.score + turn_evidence(f_n, yaw_rate(q_nb, rate_hz), yaw,
                                                                  speed_range_mps=TURN_SPEED_MPS)
        if self.score < 0.0:
            r, self.score = -r, -self.score
            yaw = float(math.atan2(math.sin(yaw + math.pi), math.cos(yaw + math.pi)))
        self.axis_b = r.tolist()
        return float(math.remainder(yaw + step_lead(q_nb, rate_hz, step_start), 2 * math.pi))

    def state(self) -> dict[str, Any]:
        return {"decay": self.decay, "sign_decay": self.sign_decay, "regrip_deg": self.regrip_deg,
                "scatter": list(self.scatter), "axis_b": self.axis_b, "score": self.score}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> DeviceSwingAxis:
        return cls(float(d["decay"]), float(d["sign_decay"]), float(d["regrip_deg"]),
                   [float(v) for v in d["scatter"]], None if d["axis_b"] is None else [float(v) for v in d["axis_b"]],
                   float(d["score"]))


@dataclass
class WalkingLineFilter:
    """Kalman filter of a trouser-pocket phone's walking line (yaw mod pi, rad) from stride to stride, with the
    swing plane's offset from it (module doc, "Trouser pocket: the walking line from stride to stride").

    State: the line and the swing plane's offset ``bias`` (rad; the thigh's sagittal plane is not square to the
    walking direction), covariance ``cov`` (2x2, rad^2).
    Prediction: the line turns with the walker, by the change of the stride-mean rotation about the vertical
    between this stride and the last (the attitude's navigation-frame rate integrated over both windows; the mean
    over a whole gait cycle removes the thigh's own swing); its variance grows by ``turn_sigma_deg`` squared, the
    offset's by ``bias_walk_deg`` squared.
    Measurements, innovations mod pi: the stride's swing-plane line (:func:`swing_plane_axis`) = line + bias, with
    standard deviation ``line_sigma_deg`` plus the stride's own axis variance (``line_var`` of :meth:`update`); the
    step-frequency axis (:func:`step_frequency_axis`) = line, with ``step_sigma_deg``, in walking strides only
    (``step_axis`` None otherwise). The line restarts after a pause
    longer than ``max_gap_s`` or when the last stride's attitudes are no longer in the history; the offset is the
    walker's and the pocket's and is kept.
    """

    line_sigma_deg: float = 13.0
    turn_sigma_deg: float = 5.0
    max_gap_s: float = 2.0
    line: float | None = None
    var: float = 0.0
    window: list[int] | None = None      # grid indices [start, end) of the last stride
    step_sigma_deg: float = 15.0
    bias_sigma_deg: float = 20.0
    bias_walk_deg: float = 0.1
    bias: float = 0.0
    cov: list[list[float]] | None = None

    def update(self, measured_line: float, q_nb: FloatArray, first: int, start: int, step_start: int, end: int,
               rate_hz: float, step_axis: float | None = None, walking: bool = True,
               line_var: float = 0.0) -> float:
        """The filtered line (rad, in (-pi/2, pi/2]) after the stride ``[start, end)`` (grid indices; its last
        step starts at ``step_start``) whose swing plane gave ``measured_line`` (rad) and whose step-frequency axis
        gave ``step_axis`` (rad; None when it is not measured). A running stride (``walking`` False) takes its swing
        plane as it is: the offset is the walking thigh's, learnt and applied in walking strides only.
        ``q_nb`` (N, 4) holds the attitudes of grid indices ``first .. first + N - 1`` at ``rate_hz`` (Hz).
        ``line_var`` (rad^2) is added to the swing plane's variance: the stride's own sampling variance of its
        axis (:func:`axis_variance`).
        """
        w = self.window
        turn = None
        if self.line is not None and w is not None and (step_start - w[1]) / rate_hz <= self.max_gap_s \
                and first <= w[0] < start < end <= first + len(q_nb):
            q = np.asarray(q_nb[w[0] - first:end - first], dtype=np.float64)
            if q.shape[0] >= 3 and np.all(np.isfinite(q)):
                yaw = np.concatenate([[0.0], np.cumsum(nav_angular_rate(q, rate_hz)[:, 2]) / rate_hz])
                turn = float(np.mean(yaw[start - w[0]:]) - np.mean(yaw[:w[1] - w[0]]))
        r_swing = math.radians(self.line_sigma_deg) ** 2 + line_var
        swing_row = np.array([1.0, 1.0 if walking else 0.0])
        if not walking:
            step_axis = None
        r_step = math.radians(self.step_sigma_deg) ** 2
        b_var = math.radians(self.bias_sigma_deg) ** 2
        cov = np.array(self.cov) if self.cov is not None else np.diag([0.0, b_var])
        if turn is None or self.line is None:
            # (Re)start: the line from the unbiased step-frequency axis when there is one, else from the swing
            # plane less its offset; the offset keeps what was learnt, uncorrelated with the new line.
            if step_axis is not None:
                x = np.array([step_axis, self.bias])
                cov = np.diag([r_step, cov[1, 1]])
                measurements = [(measured_line, swing_row, r_swing)]
            else:
                x = np.array([measured_line - swing_row[1] * self.bias, self.bias])
                cov = np.diag([r_swing + swing_row[1] * cov[1, 1], cov[1, 1]])
                cov[0, 1] = cov[1, 0] = -swing_row[1] * cov[1, 1]
                measurements = []
        else:
            x = np.array([self.line + turn, self.bias])
            cov = cov + np.diag([math.radians(self.turn_sigma_deg) ** 2, math.radians(self.bias_walk_deg) ** 2])
            measurements = [(measured_line, swing_row, r_swing)]
            if step_axis is not None:
                measurements.append((step_axis, np.array([1.0, 0.0]), r_step))
        for z, hrow, r in measurements:
            innovation = _line(z - float(hrow @ x))
            ph = cov @ hrow
            gain = ph / (float(hrow @ ph) + r)
            x = x + gain * innovation
            cov = cov - np.outer(gain, ph)
        self.line, self.bias = _line(float(x[0])), float(math.remainder(float(x[1]), math.pi))
        self.var = float(cov[0, 0])
        self.cov = (0.5 * (cov + cov.T)).tolist()
        self.window = [start, end]
        return self.line

    def state(self) -> dict[str, Any]:
        return {"line_sigma_deg": self.line_sigma_deg, "turn_sigma_deg": self.turn_sigma_deg,
                "max_gap_s": self.max_gap_s, "line": self.line, "var": self.var, "window": self.window,
                "step_sigma_deg": self.step_sigma_deg, "bias_sigma_deg": self.bias_sigma_deg,
                "bias_walk_deg": self.bias_walk_deg, "bias": self.bias, "cov": self.cov}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> WalkingLineFilter:
        o = cls(float(d["line_sigma_deg"]), float(d["turn_sigma_deg"]), float(d["max_gap_s"]),
                None if d["line"] is None else float(d["line"]), float(d["var"]),
                None if d["window"] is None else [int(v) for v in d["window"]])
        if "cov" in d:                       # absent in states saved before the swing plane's offset
            o.step_sigma_deg, o.bias_sigma_deg = float(d["step_sigma_deg"]), float(d["bias_sigma_deg"])
            o.bias_walk_deg, o.bias = float(d["bias_walk_deg"]), float(d["bias"])
            o.cov = None if d["cov"] is None else [[float(v) for v in row] for row in d["cov"]]
        elif o.line is not None:
            o.cov = [[o.var, 0.0], [0.0, math.radians(o.bias_sigma_deg) ** 2]]
        return o


def _line(yaw: float) -> float:
    """A line's angle (rad) in (-pi/2, pi/2]."""
    a = math.remainder(yaw, math.pi)
    return a + math.pi if a <= -math.pi / 2 else a


@dataclass
class PocketSide:
    """Which side of the thigh a pocket phone is on, and the turn lead it needs (module doc, "Trouser pocket: front
    or back, and the lead in turns").

    Feed every whole walking stride with :meth:`update`; :attr:`score` is the exponentially weighted sum (memory
    ``1 / (1 - decay)`` strides) of the strides' correlation of forward and vertical specific force, and
    :meth:`lead_weight` the share of :func:`step_lead` to apply: 0 behind the thigh (back pocket), 1 in front of it
    once the strides' mean correlation reaches ``full_corr``.
    """

    decay: float = 0.9
    full_corr: float = 0.2
    score: float = 0.0

    def update(self, f_n: FloatArray, yaw: float) -> None:
        """Add one stride's correlation of the specific force ``f_n`` (N, 3, m/s^2, ENU) along ``yaw`` (rad, the
        walking direction) with its vertical component (0 when either is constant).
        """
        f = np.asarray(f_n, dtype=np.float64)
        fwd = f[:, 0] * math.cos(yaw) + f[:, 1] * math.sin(yaw)
        up = f[:, 2]
        c = 0.0
        if f.shape[0] >= 3 and float(np.std(fwd)) > 0.0 and float(np.std(up)) > 0.0:
            c = float(np.corrcoef(fwd, up)[0, 1])
        self.score = self.decay * self.score + c

    def mean_corr(self) -> float:
        """The strides' exponentially weighted mean correlation of forward and vertical specific force: positive in
        front of the thigh, negative behind it (a back pocket), near 0 while undecided.
        """
        return self.score * (1.0 - self.decay)

    def lead_weight(self) -> float:
        """Share in [0, 1] of the half-step turn lead (:func:`step_lead`) for the pocket's walking direction."""
        return min(max(self.mean_corr() / self.full_corr, 0.0), 1.0)

    def state(self) -> dict[str, Any]:
        return {"decay": self.decay, "full_corr": self.full_corr, "score": self.score}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> PocketSide:
        return cls(float(d["decay"]), float(d["full_corr"]), float(d["score"]))


@dataclass
class DeviceFrameDirection:
    """Continuity of a pocket phone's walking direction in the device frame (module doc, "Trouser pocket:
    continuity").

    :meth:`resolve` picks, of the two directions along a stride's walking line, the one whose stride-mean
    device-frame vector ``mean C_nb^T p`` points like the stored ``d_b``; :meth:`update` blends the chosen
    direction into ``d_b`` (weight ``1 - decay``); :meth:`reverse` turns ``d_b`` round when the forward/backward
    vote refutes it.
    """

    decay: float = 0.8
    d_b: list[float] | None = None

    @staticmethod
    def _in_device(yaw: float, q_nb: FloatArray) -> FloatArray:
        p = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        v = quat.rotate(quat.conjugate(np.asarray(q_nb, dtype=np.float64)), np.tile(p, (len(q_nb), 1))).sum(axis=0)
        n = float(np.linalg.norm(v))
        return v / n if n > 0.0 else v

    def resolve(self, line_yaw: float, q_nb: FloatArray) -> float:
        """The direction (rad) along ``line_yaw`` (a line, rad) nearest ``d_b`` over the stride's attitudes
        ``q_nb`` (N, 4); the line's own angle before the first stride.
        """
        a = math.remainder(line_yaw, 2 * math.pi)
        if self.d_b is None or float(self._in_device(a, q_nb) @ np.array(self.d_b)) >= 0.0:
            return a
        return math.remainder(a + math.pi, 2 * math.pi)

    def update(self, yaw: float, q_nb: FloatArray) -> None:
        """Blend the stride's chosen direction ``yaw`` (rad) into ``d_b``."""
        v = self._in_device(yaw, q_nb)
        if self.d_b is not None:
            v = self.decay * np.array(self.d_b) + (1.0 - self.decay) * v
        n = float(np.linalg.norm(v))
        if n > 0.0:
            self.d_b = (v / n).tolist()

    def reverse(self) -> None:
        if self.d_b is not None:
            self.d_b = [-x for x in self.d_b]

    def state(self) -> dict[str, Any]:
        return {"decay": self.decay, "d_b": self.d_b}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> DeviceFrameDirection:
        return cls(float(d["decay"]), None if d["d_b"] is None else [float(v) for v in d["d_b"]])
