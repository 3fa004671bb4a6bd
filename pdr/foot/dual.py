"""Dual-foot fusion: the left and right foot of one person in one state (seed 001 Sec. 4.1-4.2, Algorithm 2).

Each foot runs the step-wise inertial navigation of :func:`pdr.foot.zupt.run_zupt` (Algorithm 1) and hands
over one increment ``(dp_l, dpsi_l)`` with its covariance per step. The two feet share one Gaussian state
``x = [x_left, chi_left, x_right, chi_right]`` (:class:`pdr.fusion.state.GlobalState`): every increment
propagates its foot's block (eqs. 7-8, :func:`pdr.fusion.dead_reckoning.propagate_step`), and after every
increment the separation constraint ``||D_gamma (x_left - x_right)|| <= gamma_xy`` (eq. 13) is imposed by the
state transformation of eq. 14, sigma-point projection (eq. 15) and marginalisation (eq. 12)
(:func:`pdr.fusion.constraints.impose_separation`, the one implementation shared with the cooperative fusion
centre). Increments arrive asynchronously, ordered by time on the common clock of the two logs.

The two feet's navigation frames differ by the unknown initial yaw of each sensor. Before fusing, the right
foot's frame is turned so that its walking direction over the first metres matches the left's
(:func:`initial_heading_offset`); the constraint then corrects what remains through the heading states.

:class:`DualFootFusion` is the online form, and :func:`fuse_feet` drives it: each foot's increments are added
as they come (:meth:`DualFootFusion.add_steps`), and an increment is fused only once both feet have reported up
to its time (every later increment of either foot is newer), so the fused result depends neither on how the
increments are chunked nor on which foot reports first. Online, the relative heading is found from the
increments alone: the fusion holds the first steps back and dead-reckons each foot in its own frame (eq. 7);
at the first left step whose reset lies ``align_distance_m`` or more (straight line) from the left's start,
the offset is the angle between the left's and the right's start-to-current-reset directions (the right at its
latest reset at or before that time; zero if the right has not walked half that distance). Then the held steps
are fused in order. A left foot that has made ``align_max_steps`` steps without getting that far (shuffling
in place), or the end of the data (:meth:`DualFootFusion.finish`), gives offset zero, as in the batch rule.

The per-sample tracks are the feet's step-wise tracks moved rigidly with the corrections of their last
reset: ``p_k = x_l + R(chi_l - chi_l^raw) (p_k^raw - x_l^raw)``, with the state as estimated at ``t_k``
(filtering, not smoothing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.foot.detectors import DetectorConfig
from pdr.foot.navigate import FootImu, navigate
from pdr.foot.stepwise import StepwiseDeadReckoning
from pdr.foot.zupt import Segmentation, ZuptConfig, ZuptTrack
from pdr.frames import wrap_angle
from pdr.fusion.constraints import SeparationConfig, impose_separation
from pdr.fusion.dead_reckoning import check_increment, propagate_step
from pdr.fusion.state import FootKey, GlobalState
from pdr.recording import Recording
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

LEFT = FootKey("person", "left")
RIGHT = FootKey("person", "right")


@dataclass(frozen=True)
class DualFootConfig:
    """Settings of the dual-foot fusion.

    Attributes
    ----------
    separation
        The separation constraint (eq. 13): ``gamma_xy``, ``gamma_z`` (m), sigma-point spread ``eta``, and the
        widening for states far apart in time.
    init_sigma_separation_m
        Standard deviation of the right foot's initial position relative to the left's, m per axis.
    init_sigma_heading_rad
        Standard deviation of the right foot's initial heading relative to the left's after the alignment, rad.
    align_distance_m
        Horizontal distance (m) walked by the left foot over which the right foot's frame is aligned.
    align_max_steps
        Online alignment: left steps after which the fusion stops waiting for ``align_distance_m`` and starts
        with offset zero (:class:`DualFootFusion`).
    """

    separation: SeparationConfig = field(default_factory=lambda: SeparationConfig(gamma_xy=1.0, gamma_z=0.3))
    init_sigma_separation_m: float = 0.3
    init_sigma_heading_rad: float = math.radians(5.0)
    align_distance_m: float = 3.0
    align_max_steps: int = 20

    def __post_init__(self) -> None:
        for name in ("init_sigma_separation_m", "init_sigma_heading_rad", "align_distance_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"must be a positive number, got {v}", field=name)
        if isinstance(self.align_max_steps, bool) or not isinstance(self.align_max_steps, int) \
                or self.align_max_steps < 1:
            raise InputError(f"must be a positive integer, got {self.align_max_steps!r}", field="align_max_steps")


@dataclass(frozen=True)
class FootEstimate:
    """Fused per-sample track of one foot.

    Attributes
    ----------
    t_s
        (N,) sample times on the common clock, s.
    pos_n
        (N, 3) position, m, ENU (left foot's navigation frame, origin at its start).
    yaw
        (N,) yaw of the sensor, rad, counter-clockwise from east.
    zero_velocity
        (N,) detector flags.
    step_t_s
        (L,) times of the resets, s.
    step_pos_n
        (L, 3) fused reset positions ``x_l`` (after the constraint of the step's own update), m.
    step_cov
        (L, 4, 4) their covariance with the heading.
    step_strides
        (L,) whether each reset closes a stride (False: a reset while the foot stands; :attr:`FusedStep.stride`).
    """

    t_s: Array
    pos_n: Array
    yaw: Array
    zero_velocity: NDArray[np.bool_]
    step_t_s: Array
    step_pos_n: Array
    step_cov: Array
    step_strides: NDArray[np.bool_]


@dataclass(frozen=True)
class DualFootTrack:
    """Output of :func:`fuse_feet`.

    Attributes
    ----------
    left, right
        Fused tracks of the two feet.
    heading_offset_rad
        Rotation applied to the right foot's frame by the initial alignment, rad.
    constraint_active
        Number of updates at which the separation constraint changed the state.
    updates
        Number of step updates fused.
    """

    left: FootEstimate
    right: FootEstimate
    heading_offset_rad: float
    constraint_active: int
    updates: int


def _raw_resets(track: ZuptTrack) -> tuple[IntArray, Array, Array]:
    """Sample indices, raw positions ``x_l`` and raw headings ``chi_l`` of a step-wise track's resets."""
    idx = np.array([s.index for s in track.steps], dtype=np.int64)
    chi = np.cumsum([s.dpsi for s in track.steps]) if track.steps else np.zeros(0)
    return idx, track.pos_n[idx] if idx.size else np.zeros((0, 3)), np.asarray(chi, dtype=np.float64)


def initial_heading_offset(left: ZuptTrack, right: ZuptTrack, t_left: Array, t_right: Array,
                           distance_m: float) -> float:
    """Yaw (rad) that turns the right foot's raw frame onto the left's.

    Both feet start at rest near each other and walk together: the direction from the start to where each foot
    is when the left foot has first walked ``distance_m`` (straight-line) is the same walking direction seen in
    the two frames. Zero when the left foot never gets that far.
    """
    d = np.linalg.norm(left.pos_n[:, :2] - left.pos_n[0, :2], axis=1)
    far = np.flatnonzero(d >= distance_m)
    if far.size == 0:
        return 0.0
    t_star = t_left[far[0]]
    k = int(np.clip(np.searchsorted(t_right, t_star), 0, t_right.size - 1))
    return walking_direction_offset(left.pos_n[far[0], :2] - left.pos_n[0, :2],
                                    right.pos_n[k, :2] - right.pos_n[0, :2], distance_m)


def walking_direction_offset(d_left: Array, d_right: Array, distance_m: float) -> float:
    """Yaw (rad) from the right foot's frame to the left's, given the two feet's (2,) horizontal displacements
    (m) from their starts at one instant (the left's at least ``distance_m`` long); zero when the right's is
    shorter than half of ``distance_m`` (it cannot show the walking direction).
    """
    if np.linalg.norm(d_right) < 0.5 * distance_m:
        return 0.0
    return float(wrap_angle(math.atan2(d_left[1], d_left[0]) - math.atan2(d_right[1], d_right[0])))


SIDES = ("left", "right")
KEYS = (LEFT, RIGHT)


@dataclass(frozen=True)
class FusedStep:
    """The two feet after one fused step update (:class:`DualFootFusion`).

    Attributes
    ----------
    t_s
        Time of the step's reset on the common clock, s.
    side
        The foot that stepped: ``"left"`` or ``"right"``.
    pos_n
        (2, 3) fused reset positions ``x`` of the left and right foot after the update (and the constraint),
        m, ENU in the left foot's navigation frame (origin at its start).
    heading
        (2,) fused headings ``chi`` of the left and right foot, rad, counter-clockwise from east.
    cov
        (4, 4) covariance of the stepping foot's ``[x, chi]`` after the update, m and rad.
    midpoint_shift_m
        Horizontal distance the midpoint between the feet moved in this update, m (one step length).
    constraint_active
        Whether the separation constraint changed the state.
    stride
        Whether the step closes a stride of the stepping foot (its increment's
        :attr:`pdr.step_increment.StepIncrement.stride`): False for a reset while that foot stands, fused for its
        increment but no step of the walker.
    """

    t_s: float
    side: str
    pos_n: Array
    heading: Array
    cov: Array
    midpoint_shift_m: float
    constraint_active: bool
    stride: bool

    @property
    def midpoint_n(self) -> Array:
        """(3,) midpoint between the two feet, m, ENU: the walker's position."""
        return np.asarray(0.5 * (self.pos_n[0] + self.pos_n[1]), dtype=np.float64)

    @property
    def body_yaw(self) -> float:
        """Circular mean of the two feet's headings, rad, counter-clockwise from east."""
        return math.atan2(math.sin(self.heading[0]) + math.sin(self.heading[1]),
                          math.cos(self.heading[0]) + math.cos(self.heading[1]))


def _side_index(side: str) -> int:
    if side not in SIDES:
        raise InputError(f"side must be 'left' or 'right', got {side!r}", field="side")
    return SIDES.index(side)


def _increment_to_dict(inc: StepIncrement) -> dict[str, Any]:
    return {"t_s": float(inc.t_s), "index": int(inc.index), "dp": np.asarray(inc.dp, dtype=np.float64).tolist(),
            "dpsi": float(inc.dpsi), "cov": np.asarray(inc.cov, dtype=np.float64).tolist(), "stride": bool(inc.stride)}


def _increment_from_dict(d: dict[str, Any]) -> StepIncrement:
    # "stride" is absent from states saved before the fusion carried it: a stride, as StepIncrement's default.
    return StepIncrement(float(d["t_s"]), int(d["index"]), np.asarray(d["dp"], dtype=np.float64),
                         float(d["dpsi"]), np.asarray(d["cov"], dtype=np.float64), bool(d.get("stride", True)))


class DualFootFusion:
    """Online dual-foot fusion of the step increments of a left and a right foot (seed 001 Algorithm 2).

    Parameters
    ----------
    config
        Fusion settings (separation constraint, initial uncertainty, online alignment).
    heading_offset_rad
        Known yaw (rad) from the right foot's frame to the left's; ``None`` finds it online from the first
        steps (module docstring).
    start_t_s
        Times (s, common clock) at which the two feet's initial states hold, for the time-difference widening
        of the constraint; ``None``: the time of the first fused step, for both.

    Notes
    -----
    Feed each foot's increments in time order with :meth:`add_steps` (increment times on the common clock of
    the two feet); each call returns the updates that became final. :meth:`finish` fuses what is still held
    (the end of both recordings). The state is JSON-serialisable (:meth:`to_dict`); restoring it changes
    nothing.
    """

    def __init__(self, config: DualFootConfig | None = None, heading_offset_rad: float | None = None,
                 start_t_s: tuple[float, float] | None = None) -> None:
        self.config = config or DualFootConfig()
        if heading_offset_rad is not None and not math.isfinite(heading_offset_rad):
            raise InputError(f"must be finite, got {heading_offset_rad}", field="heading_offset_rad")
        if start_t_s is not None and not all(math.isfinite(t) for t in start_t_s):
            raise InputError(f"must be finite times in s, got {start_t_s}", field="start_t_s")
        self.heading_offset_rad = heading_offset_rad
        self.start_t_s = start_t_s
        self.pending: tuple[list[StepIncrement], list[StepIncrement]] = ([], [])  # received, not yet fused
        self.last_t_s: list[float | None] = [None, None]                           # latest step received per foot
        # Before the alignment: the released steps held back and each foot's own dead reckoning (eq. 7).
        self.held: list[tuple[int, StepIncrement]] = []
        self.raw = (StepwiseDeadReckoning(), StepwiseDeadReckoning())
        self.state: GlobalState | None = None
        self.updates = 0
        self.constraint_active = 0

    # -- public API ---------------------------------------------------------------------------------------
    def add_steps(self, side: str, increments: Sequence[StepIncrement]) -> list[FusedStep]:
        """Add steps of one foot (``"left"``/``"right"``, in time order); returns the updates now final.

        Raises
        ------
        InputError
            Unknown side, malformed increment, or a step not after the foot's previous one.
        """
        f = _side_index(side)
        for i, inc in enumerate(increments):
            check_increment(inc, field=f"{side}[{i}]")
            last = self.last_t_s[f]
            if last is not None and not inc.t_s > last:
                raise InputError(f"{side} step at {inc.t_s:.3f} s is not after the previous one ({last:.3f} s)",
                                 field=f"{side}[{i}].t_s")
            self.pending[f].append(inc)
            self.last_t_s[f] = float(inc.t_s)
        left, right = self.last_t_s
        if left is None or right is None:
            return []
        return self._release(min(left, right))

    def finish(self) -> list[FusedStep]:
        """Fuse every step still held (neither foot will report older steps); starts unaligned feet."""
        out = self._release(math.inf)
        if self.state is None and self.held:
            out += self._start(0.0 if self.heading_offset_rad is None else self.heading_offset_rad)
        return out

    @property
    def aligned(self) -> bool:
        """Whether the fusion has started (the right foot's frame is turned onto the left's)."""
        return self.state is not None

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state (floats round-trip exactly through JSON)."""
        return {
            "config": asdict(self.config), "heading_offset_rad": self.heading_offset_rad,
            "start_t_s": None if self.start_t_s is None else list(self.start_t_s),
            "pending": [[_increment_to_dict(s) for s in p] for p in self.pending],
            "last_t_s": list(self.last_t_s),
            "held": [[f, _increment_to_dict(s)] for f, s in self.held],
            "raw": [{"pos_n": r.pos_n.tolist(), "heading": r.heading, "cov": r.cov.tolist()} for r in self.raw],
            "state": None if self.state is None else self.state.to_dict(),
            "updates": self.updates, "constraint_active": self.constraint_active,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> DualFootFusion:
        """Restore a fusion saved by :meth:`to_dict` (InputError when malformed)."""
        try:
            cfg = dict(d["config"])
            cfg["separation"] = SeparationConfig(**cfg["separation"])
            start = d["start_t_s"]
            out = cls(DualFootConfig(**cfg), d["heading_offset_rad"],
                      None if start is None else (float(start[0]), float(start[1])))
            out.pending = ([_increment_from_dict(s) for s in d["pending"][0]],
                           [_increment_from_dict(s) for s in d["pending"][1]])
            out.last_t_s = [None if t is None else float(t) for t in d["last_t_s"]]
            out.held = [(int(f), _increment_from_dict(s)) for f, s in d["held"]]
            out.raw = tuple(StepwiseDeadReckoning(np.asarray(r["pos_n"], dtype=np.float64), float(r["heading"]),
                                                  np.asarray(r["cov"], dtype=np.float64))
                            for r in d["raw"])  # type: ignore[assignment]
            out.state = None if d["state"] is None else GlobalState.from_dict(d["state"])
            out.updates, out.constraint_active = int(d["updates"]), int(d["constraint_active"])
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise InputError(f"malformed dual-foot fusion state: {exc}", field="state") from None
        return out

    # -- processing -----------------------------------------------------------------------------------------
    def _release(self, until_s: float) -> list[FusedStep]:
        """Consume the received steps at or before ``until_s`` in time order (left first at equal times)."""
        ready = []
        for f in (0, 1):
            n = 0
            while n < len(self.pending[f]) and self.pending[f][n].t_s <= until_s:
                n += 1
            ready += [(float(s.t_s), f, s) for s in self.pending[f][:n]]
            del self.pending[f][:n]
        ready.sort(key=lambda e: (e[0], e[1]))
        out: list[FusedStep] = []
        for _, f, inc in ready:
            if self.state is not None:
                out.append(self._fuse(f, inc))
                continue
            self.held.append((f, inc))
            if self.heading_offset_rad is not None:
                out += self._start(self.heading_offset_rad)
                continue
            self.raw[f].update(inc)                                          # eq. 7 in the foot's own frame
            if f == 0:
                d_left = self.raw[0].pos_n[:2]
                if np.linalg.norm(d_left) >= self.config.align_distance_m:
                    out += self._start(walking_direction_offset(d_left, self.raw[1].pos_n[:2],
                                                                self.config.align_distance_m))
                elif sum(1 for g, _ in self.held if g == 0) >= self.config.align_max_steps:
                    out += self._start(0.0)
        return out

    def _start(self, offset: float) -> list[FusedStep]:
        """Set up the joint state with the right foot's frame turned by ``offset`` and fuse the held steps."""
        cfg = self.config
        self.heading_offset_rad = float(offset)
        t0 = self.start_t_s or (float(self.held[0][1].t_s),) * 2
        state = GlobalState()
        # The left foot's start defines the navigation frame (position and heading known exactly); what is
        # uncertain is the right foot relative to it.
        s2 = cfg.init_sigma_separation_m**2
        state.add_foot(LEFT, np.zeros(3), 0.0, np.zeros((4, 4)), float(t0[0]))
        state.add_foot(RIGHT, np.zeros(3), float(offset), np.diag([s2, s2, s2, cfg.init_sigma_heading_rad**2]),
                       float(t0[1]))
        self.state = state
        held, self.held = self.held, []
        self.raw = (StepwiseDeadReckoning(), StepwiseDeadReckoning())
        return [self._fuse(f, inc) for f, inc in held]

    def _fuse(self, f: int, inc: StepIncrement) -> FusedStep:
        """One step update of foot ``f`` (eqs. 7-8) followed by the separation constraint (Algorithm 2)."""
        state = self.state
        assert state is not None
        before = 0.5 * (state.position(LEFT) + state.position(RIGHT))
        propagate_step(state, KEYS[f], inc)                                          # eqs. 7-8
        active = impose_separation(state, LEFT, RIGHT, self.config.separation)       # eqs. 13-15, Algorithm 2
        self.updates += 1
        self.constraint_active += int(active)
        pos = np.stack([state.position(LEFT), state.position(RIGHT)])
        blk = state.block(KEYS[f])
        shift = float(np.hypot(*(0.5 * (pos[0, :2] + pos[1, :2]) - before[:2])))
        return FusedStep(float(inc.t_s), SIDES[f], pos, np.array([state.heading(LEFT), state.heading(RIGHT)]),
                         state.cov[np.ix_(blk, blk)].copy(), shift, bool(active), bool(inc.stride))


def _rigid(track: ZuptTrack, t: Array, ev_t: Array, ev_pos: Array, ev_chi: Array, raw_idx: IntArray,
           raw_pos: Array, raw_chi: Array) -> tuple[Array, Array]:
    """Move each sample with the correction of its foot's last reset, as estimated at the sample's time."""
    n = t.size
    last_reset = np.searchsorted(raw_idx, np.arange(n), side="right") - 1          # -1 before the first reset
    x_raw = np.where(last_reset[:, None] >= 0, raw_pos[np.maximum(last_reset, 0)], 0.0)
    chi_raw = np.where(last_reset >= 0, raw_chi[np.maximum(last_reset, 0)], 0.0)
    ev = np.clip(np.searchsorted(ev_t, t, side="right") - 1, 0, None)               # row 0: initial state
    dchi = ev_chi[ev] - chi_raw
    c, s = np.cos(dchi), np.sin(dchi)
    d = track.pos_n - x_raw
    pos = np.empty_like(d)
    pos[:, 0] = ev_pos[ev, 0] + c * d[:, 0] - s * d[:, 1]
    pos[:, 1] = ev_pos[ev, 1] + s * d[:, 0] + c * d[:, 1]
    pos[:, 2] = ev_pos[ev, 2] + d[:, 2]
    yaw = wrap_angle(quat.to_euler(track.q_nb)[2] + dchi)
    return pos, np.asarray(yaw, dtype=np.float64)


def fuse_feet(left: ZuptTrack, right: ZuptTrack, left_offset_s: float = 0.0, right_offset_s: float = 0.0,
              config: DualFootConfig | None = None) -> DualFootTrack:
    """Fuse the step-wise navigation of the left and right foot of one person (seed 001 Algorithm 2).

    Parameters
    ----------
    left, right
        Step-wise tracks (:func:`pdr.foot.zupt.run_zupt` with a segmentation) of the two feet.
    left_offset_s, right_offset_s
        Added to each track's ``t_s`` to put both on one clock, s.
    config
        Fusion settings.

    Returns
    -------
    The fused tracks of both feet, in the left foot's navigation frame.
    """
    cfg = config or DualFootConfig()
    for name, tr in (("left", left), ("right", right)):
        if not tr.steps:
            raise InputError("no steps: run the foot navigation with step segmentation (method 'stepwise') on a "
                             "walking recording", field=name)
    t_l = left.t_s + left_offset_s
    t_r = right.t_s + right_offset_s
    if t_l[-1] < t_r[0] or t_r[-1] < t_l[0]:
        raise InputError(f"the two logs do not overlap in time (left {t_l[0]:.1f}-{t_l[-1]:.1f} s, right "
                         f"{t_r[0]:.1f}-{t_r[-1]:.1f} s on their clocks)", field="right")
    offset = initial_heading_offset(left, right, t_l, t_r, cfg.align_distance_m)

    fusion = DualFootFusion(cfg, offset, (float(t_l[left.start_index]), float(t_r[right.start_index])))
    # Per-foot history of its block after every update (row 0: the initial state).
    hist_t: list[list[float]] = [[-math.inf], [-math.inf]]
    hist_x = [[np.zeros(3)], [np.zeros(3)]]
    hist_chi = [[0.0], [offset]]
    step_pos: list[list[Array]] = [[], []]
    step_cov: list[list[Array]] = [[], []]
    step_strides: list[list[bool]] = [[], []]
    updates: list[FusedStep] = []
    for side, tr, t in (("left", left, t_l), ("right", right, t_r)):
        # Increments on the common clock (their reset sample's time).
        updates += fusion.add_steps(side, [replace(s, t_s=float(t[s.index])) for s in tr.steps])
    updates += fusion.finish()
    for u in updates:
        f = SIDES.index(u.side)
        for g in (0, 1):
            hist_t[g].append(u.t_s)
            hist_x[g].append(u.pos_n[g])
            hist_chi[g].append(float(u.heading[g]))
        step_pos[f].append(u.pos_n[f])
        step_cov[f].append(u.cov)
        step_strides[f].append(u.stride)

    feet = []
    for f, (tr, t) in enumerate(((left, t_l), (right, t_r))):
        raw_idx, raw_pos, raw_chi = _raw_resets(tr)
        ev_t = np.asarray(hist_t[f])
        # The right foot's alignment offset is part of its heading state, so it turns its raw frame too.
        pos, yaw = _rigid(tr, t, ev_t, np.asarray(hist_x[f]), np.asarray(hist_chi[f]), raw_idx, raw_pos, raw_chi)
        feet.append(FootEstimate(t, pos, yaw, tr.zero_velocity, t[raw_idx], np.asarray(step_pos[f]),
                                 np.asarray(step_cov[f]), np.asarray(step_strides[f], dtype=bool)))
    return DualFootTrack(feet[0], feet[1], offset, fusion.constraint_active, fusion.updates)


def navigate_feet(left: Recording, right: Recording, detector: DetectorConfig | None = None,
                  zupt: ZuptConfig | None = None, segmentation: Segmentation | None = None,
                  config: DualFootConfig | None = None) -> tuple[FootImu, FootImu, DualFootTrack]:
    """Dual-foot navigation of two foot IMU recordings of one person (``pdr foot --left L --right R``).

    Each recording goes through :func:`pdr.foot.navigate.navigate` with the step-wise method; the two are put
    on one clock by their origins (``t0_ns``) and fused by :func:`fuse_feet`.
    """
    imu_l, tr_l = navigate(left, "stepwise", detector, zupt, segmentation)
    imu_r, tr_r = navigate(right, "stepwise", detector, zupt, segmentation)
    return imu_l, imu_r, fuse_feet(tr_l, tr_r, imu_l.clock_offset_s, imu_r.clock_offset_s, config)
