"""The online phone PDR pipeline: ``update(batch) -> events`` with serialisable state.

Stages per batch (each keeps its own state, so a session can be fed batch by batch, saved with
:meth:`PdrPipeline.to_dict`, resumed with :meth:`PdrPipeline.from_dict`, and gives the same track as one
big batch):

1. :class:`pdr.phone.grid.OnlineGrid`: acc, gyro, mag, baro on one uniform grid (``rate_hz``);
   the magnetometer's hard-iron offset is learnt online from the gyro (:mod:`pdr.phone.magcal`) and removed once
   significant; a site's ``declination_deg`` replaces the configured declination;
2. :class:`pdr.phone.steps.StepDetector` (seed 004 Sec. 3.2) on the accelerometer;
3. :class:`pdr.phone.attitude.AttitudeFilter` (seed 003 UKF, or the EKF baseline), run in segments that end
   where steps become known, so a landmark can update the attitude (eqs. 14-32) at a deterministic sample;
4. per step: patterns and length (seed 004 eqs. 13-19), heading (:mod:`pdr.phone.heading`: device heading +
   offset for hand-held/torso, improved RMPCA + second UKF for the trouser pocket; hand-held/torso headings
   then pass the heuristic drift elimination :class:`pdr.phone.heading.StepDriftElimination`), landmark label
   (:mod:`pdr.phone.landmarks`, with the neighbour-step correction, which delays each step by one step),
   site landmarks (a flight of stairs: position fix at its first step, heading rows of both UKFs at every
   step of it), floor (:mod:`pdr.phone.floors`), and the PDR position (:mod:`pdr.phone.track`, eqs. 20-22);
5. elevator rides from the vertical specific force (:class:`pdr.phone.landmarks.ElevatorDetector`).

Events are plain dicts: ``{"type": "step", "t_s", "east_m", "north_m", "up_m", "floor", "heading_deg",
"step_length_m", "turn_deg", "mode", ...}`` (``turn_deg``: the change of the step heading since the previous step
of the walk, which shortens a turning step, :func:`pdr.phone.step_length.turn_factor`; ``heading_raw_deg``, the heading
before the drift elimination, ``gyro_heading_deg``, the gyro's rotation about the vertical since the start with an
arbitrary origin (:mod:`pdr.phone.gyro_yaw`: no magnetometer, no landmark, no geometric phase of a swinging phone),
``up_time_s``, the device-frame up direction integrated over the same time (s, so that ``up_time_s . b`` is what a
constant gyro bias ``b`` added to it), ``gyro_bias_dps``, the attitude filter's stationary
gyro bias estimate (deg/s, device frame; None before the first stationary period), ``position_fix`` and
``landmark_heading``: the inputs of the offline
:mod:`pdr.phone.heading_smoother`), ``{"type": "elevator", ...}``,
``{"type": "floor_change", ...}`` and ``{"type": "notice", "message"}`` (degraded inputs). ``t_s`` is on the
log's own clock (seconds).

Placement (``pocket``, ``hand``, ``torso``, ``swinging``) comes from the configuration, else from an injected
``placement_provider(recording) -> str | None`` (e.g. the placement classifier; pdr/ never imports it),
else from the recording's :class:`~pdr.recording.DeviceInfo`, else it is detected online from the physics of
the carriage, stride by stride (:mod:`pdr.phone.placement_detect`: a steady device is held, a pendulum's specific
force stays along the arm, a pocket phone's turns with the thigh), and revised when the phone changes place.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters import iir
from pdr.filters.ukf import SigmaPoints
from pdr.frames import GRAVITY_MPS2, heading_deg_to_yaw, wrap_angle, yaw_to_heading_deg
from pdr.phone.attitude import AttitudeConfig, AttitudeFilter, AttitudeState
from pdr.phone.floors import FloorConfig, FloorTracker
from pdr.phone.grid import OnlineGrid
from pdr.phone.gyro_yaw import GyroYaw
from pdr.phone.heading import (
    DirectionVote,
    DriftEliminationConfig,
    HeadingEstimate,
    OffsetEstimator,
    StepDriftElimination,
    fuse_landmark,
    improved_rmpca_ut,
    landmark_attitude_update,
    mean_yaw,
    pca_axis,
    scatter_in_frame,
    scatter_of,
    thigh_swing_evidence,
    yaw_variance,
)
from pdr.phone.landmarks import ElevatorDetector, LandmarkConfig, Site, classify_step, neighbour_correction
from pdr.phone.magcal import HardIronEstimator, MagCalConfig
from pdr.phone.placement_detect import PlacementDetectConfig, PlacementDetector, stride_cues
from pdr.phone.step_length import StepLengthModel, step_patterns
from pdr.phone.steps import StepConfig, StepDetector
from pdr.phone.track import TrackState
from pdr.phone.walking_direction import (
    DeviceFrameDirection,
    DeviceSwingAxis,
    swing_plane_axis,
    turn_evidence,
    yaw_rate,
)
from pdr.recording import Recording

FloatArray = NDArray[np.float64]
Event = dict[str, Any]
PlacementProvider = Callable[[Recording], "str | None"]

PLACEMENT_GROUPS = {"trouser_pocket_front": "pocket", "trouser_pocket_back": "pocket", "trouser_pocket": "pocket",
                    "hand": "hand", "torso": "torso", "neck": "torso", "bag": "torso", "armband": "hand"}
#: Placements the pipeline has a heading method for.
PIPELINE_PLACEMENTS = ("pocket", "hand", "torso", "swinging")


@dataclass(frozen=True)
class PipelineConfig:
    """Configuration of the phone pipeline (see the stage modules for each part).

    Attributes
    ----------
    rate_hz
        Grid rate (Hz).
    placement
        ``auto``, ``pocket``, ``hand``, ``torso`` or ``swinging`` (a phone in a hand swinging with the arm).
    attitude_method
        ``ukf`` (seed 003) or ``ekf`` (RMPCA baseline).
    heading_offset
        Hand/torso: ``zero`` (device forward axis is the walking direction) or ``pca`` (estimated).
    initial_floor
        Floor number at the start.
    pocket_swing_deg
        Unused since the placement is detected by :mod:`pdr.phone.placement_detect` (``placement_detect``); kept so
        that saved session states load.
    heading_process_var
        Process noise ``w`` of eq. 41 (rad^2).
    step_length_rel_sigma
        Relative standard deviation of a step length, for the position covariance.
    history_s
        Length of the sample history kept for steps not yet processed (s).
    device_heading_sigma_gyro
        Gyro noise of eq. 9 (rad/s) used instead of ``attitude.sigma_gyro`` once the placement is hand or
        torso (the walking direction is the device heading, so the yaw matters, not the tilt during a thigh
        swing): the larger process noise makes the magnetometer rows act over a shorter stretch of the walk.
        None keeps ``attitude.sigma_gyro``.
    pocket_axis
        Trouser pocket: the walking line from the thigh's swing plane (``swing``, :mod:`pdr.phone.walking_direction`),
        from seed 003's improved RMPCA of the specific force through the second UKF (``rmpca``), or ``auto``:
        ``rmpca`` when the site has landmarks, ``swing`` otherwise. Seed 003's landmark row corrects the attitude
        through the RMPCA measurement ``f(q)`` (eqs. 32, 41), so with landmarks the heading is the one that row is
        written for; without them the swing plane is the better line on real thighs (the RMPCA axis of a front
        pocket is turned by the thigh's own accelerations).
    drift_elimination
        Hand/torso: heuristic drift elimination of the step heading towards dominant directions learnt
        from the walk (:class:`pdr.phone.heading.StepDriftElimination`, parameters ``hde``).
    """

    rate_hz: float = 50.0
    placement: str = "auto"
    attitude_method: str = "ukf"
    heading_offset: str = "zero"
    initial_floor: float = 0.0
    pocket_swing_deg: float = 25.0
    heading_process_var: float = math.radians(5.0) ** 2
    step_length_rel_sigma: float = 0.08
    history_s: float = 30.0
    device_heading_sigma_gyro: float | None = 0.02
    drift_elimination: bool = True
    pocket_axis: str = "auto"
    step: StepConfig = field(default_factory=StepConfig)
    attitude: AttitudeConfig = field(default_factory=AttitudeConfig)
    step_length: StepLengthModel = field(default_factory=StepLengthModel)
    floors: FloorConfig = field(default_factory=FloorConfig)
    landmarks: LandmarkConfig = field(default_factory=LandmarkConfig)
    magcal: MagCalConfig = field(default_factory=MagCalConfig)
    hde: DriftEliminationConfig = field(default_factory=DriftEliminationConfig)
    placement_detect: PlacementDetectConfig = field(default_factory=PlacementDetectConfig)

    def __post_init__(self) -> None:
        if self.placement not in ("auto", *PIPELINE_PLACEMENTS):
            raise InputError("placement must be auto, pocket, hand, torso or swinging", field="placement",
                             source="config")
        if self.attitude_method not in ("ukf", "ekf"):
            raise InputError("attitude_method must be ukf or ekf", field="attitude_method", source="config")
        if self.pocket_axis not in ("auto", "swing", "rmpca"):
            raise InputError("pocket_axis must be auto, swing or rmpca", field="pocket_axis", source="config")
        if self.heading_offset not in ("zero", "pca"):
            raise InputError("heading_offset must be zero or pca", field="heading_offset", source="config")
        if not self.rate_hz >= 10:
            raise InputError("grid rate must be at least 10 Hz", field="rate_hz", source="config")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PipelineConfig:
        try:
            sub = {"step": StepConfig, "attitude": AttitudeConfig, "step_length": StepLengthModel,
                   "floors": FloorConfig, "landmarks": LandmarkConfig, "magcal": MagCalConfig,
                   "hde": DriftEliminationConfig, "placement_detect": PlacementDetectConfig}
            kw = {k: (sub[k](**v) if k in sub else v) for k, v in d.items()}
            return cls(**kw)
        except TypeError as exc:
            raise InputError(f"bad pipeline configuration ({exc})", source="config") from None


_FIELD_WIDTHS = (("t", 0), ("acc", 3), ("q", 4), ("f_n", 3), ("yaw_y", 0), ("yaw_z", 0), ("y_up", 0), ("an", 0),
                 ("mag_n", 0), ("up", 0), ("floor", 0), ("gyro_yaw", 0), ("up_time", 3))
_FIELDS = tuple(n for n, _ in _FIELD_WIDTHS)


def _derived(q: FloatArray, acc: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per sample from ``C_nb(q)``: specific force in ENU, yaw of the device y and z axes and up-part of y."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    c00, c01, c02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    c10, c11, c12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    c20, c21, c22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    ax, ay, az = acc[:, 0], acc[:, 1], acc[:, 2]
    f_n = np.column_stack([c00 * ax + c01 * ay + c02 * az, c10 * ax + c11 * ay + c12 * az,
                           c20 * ax + c21 * ay + c22 * az])
    return f_n, np.arctan2(c11, c01), np.arctan2(c12, c02), c21


class _History:
    """Grid samples of the last ``size`` indices: t, acc_b, q_nb, f_n (specific force in ENU), yaw of the
    device y and z axes, up-component of the device y axis, a_n, |m|, up (m), floor, the gyro yaw (rad: the
    angular rate about the vertical integrated since the start, no magnetometer, no bias removed) and the
    device-frame up direction integrated since the start (s).
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.start = 0
        self.t = np.zeros(0)
        self.acc = np.zeros((0, 3))
        self.q = np.zeros((0, 4))
        self.f_n = np.zeros((0, 3))
        self.yaw_y = np.zeros(0)
        self.yaw_z = np.zeros(0)
        self.y_up = np.zeros(0)
        self.an = np.zeros(0)
        self.mag_n = np.zeros(0)
        self.up = np.zeros(0)
        self.floor = np.zeros(0)
        self.gyro_yaw = np.zeros(0)
        self.up_time = np.zeros((0, 3))

    def append(self, start: int, t: FloatArray, acc: FloatArray, an: FloatArray, mag_n: FloatArray,
               up: FloatArray, floor: FloatArray) -> None:
        if self.t.size == 0:
            self.start = start
        self.t = np.concatenate([self.t, t])
        self.acc = np.concatenate([self.acc, acc])
        self.q = np.concatenate([self.q, np.full((t.size, 4), np.nan)])
        self.f_n = np.concatenate([self.f_n, np.full((t.size, 3), np.nan)])
        self.yaw_y = np.concatenate([self.yaw_y, np.full(t.size, np.nan)])
        self.yaw_z = np.concatenate([self.yaw_z, np.full(t.size, np.nan)])
        self.y_up = np.concatenate([self.y_up, np.full(t.size, np.nan)])
        self.an = np.concatenate([self.an, an])
        self.mag_n = np.concatenate([self.mag_n, mag_n])
        self.up = np.concatenate([self.up, up])
        self.floor = np.concatenate([self.floor, floor])
        self.gyro_yaw = np.concatenate([self.gyro_yaw, np.full(t.size, np.nan)])
        self.up_time = np.concatenate([self.up_time, np.full((t.size, 3), np.nan)])

    def trim(self) -> None:
        extra = self.t.size - self.size
        if extra > 0:
            self.start += extra
            for name in _FIELDS:
                setattr(self, name, getattr(self, name)[extra:])

    def sl(self, a: int, b: int) -> slice:
        return slice(max(a - self.start, 0), max(b - self.start, 0))

    def to_dict(self) -> dict[str, Any]:
        return {"size": self.size, "start": self.start,
                **{n: getattr(self, n).copy() for n in _FIELDS}}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> _History:
        h = cls(int(d["size"]))
        h.start = int(d["start"])
        for n, w in _FIELD_WIDTHS:
            # The gyro yaw and up time are absent in states saved before the heading smoother.
            a = np.array(d[n] if n in d else np.full((len(d["t"]), w) if w else len(d["t"]), np.nan),
                         dtype=np.float64)
            setattr(h, n, a.reshape(-1, w) if w else a.reshape(-1))
        return h


class PdrPipeline:
    """Online phone PDR: feed :class:`~pdr.recording.Recording` batches, get events.

    Parameters
    ----------
    config
        Pipeline configuration.
    site
        Optional site description (landmarks that correct heading and position).
    placement_provider
        Optional callable giving the placement of a batch (``pocket``/``hand``/``torso``, a
        :data:`pdr.recording.PLACEMENTS` name, or None), e.g. a classifier; never imported by pdr/.
    start_en_m
        Start position (east, north) in metres of the site frame.
    """

    def __init__(self, config: PipelineConfig | None = None, site: Site | None = None,
                 placement_provider: PlacementProvider | None = None,
                 start_en_m: tuple[float, float] = (0.0, 0.0)) -> None:
        self.config = config or PipelineConfig()
        self.site = site
        self.placement_provider = placement_provider
        c = self.config
        self.grid: OnlineGrid | None = None
        self.steps = StepDetector(c.rate_hz, c.step)
        # A site that knows its magnetic declination overrides the configured one.
        att = c.attitude if site is None or site.declination_deg is None else replace(
            c.attitude, mag_declination_deg=site.declination_deg)
        self.attitude = AttitudeFilter(c.rate_hz, att, c.attitude_method)
        self.magcal = HardIronEstimator(c.rate_hz, c.magcal)
        self.floors = FloorTracker(c.rate_hz, c.floors if site is None else replace(
            c.floors, floor_height_m=site.floor_height_m), c.initial_floor)
        self.elevator = ElevatorDetector(c.rate_hz, c.landmarks)
        self.track = TrackState(float(start_en_m[0]), float(start_en_m[1]))
        self.offset = OffsetEstimator()
        self.hde = StepDriftElimination(c.hde, self._grid_yaw())
        self.history = _History(int(c.history_s * c.rate_hz))
        self.placement: str | None = None if c.placement == "auto" else c.placement
        # Detected online (pdr.phone.placement_detect) unless the configuration, a provider or the device names it.
        self.auto_placement = c.placement == "auto"
        self.placement_detector = PlacementDetector(c.placement_detect)
        self.t0_ns = 0
        self.prev_yaw: float | None = None
        self.prev_q: list[float] | None = None
        self.prev_step_start: int | None = None
        self.direction_vote = _direction_vote(self.placement)
        self.swing_axis = DeviceSwingAxis()      # swinging hand's walking direction (pdr.phone.walking_direction)
        self.pocket_direction = DeviceFrameDirection()   # pocket's forward/backward continuity (same module)
        self.prev_mode = ""
        self.last_step: tuple[float, float] | None = None   # (raw yaw rad, end time s) of the last emitted step
        self.stairs_landmark: str | None = None
        self.landmark_updates = 0
        self.landmark_attitude_updates = 0
        self.pending: dict[str, Any] | None = None
        self.pitch_baseline: list[float] | None = None
        self.last_floor = float(c.initial_floor)
        self.notices: list[str] = []
        self._av_zi: FloatArray | None = None
        b, a = iir.butter_lowpass(1, 0.5 / (0.5 * c.rate_hz))
        self._av_ba = (b, a)
        self.n_input_samples = 0
        self.gyro_yaw = GyroYaw(c.rate_hz)      # the gyro's rotation about the vertical since the start

    # -- public API --------------------------------------------------------------------------------
    def update(self, batch: Recording) -> list[Event]:
        """Process the next batch of the session; returns the events it produced.

        A batch from a shoe IMU (:attr:`~pdr.recording.DeviceInfo.is_foot`) is refused with an :class:`InputError`
        and leaves the state as it was: phone PDR would count its strides as steps of a phone.
        """
        if batch.device.is_foot:
            d = batch.device
            raise InputError(f"this is a foot-mounted IMU recording (device role '{d.role}', placement "
                             f"'{d.placement}'); phone PDR needs a phone: use 'pdr foot' for shoe IMU logs",
                             source=batch.source or None, field="device")
        events: list[Event] = []
        if self.grid is None:
            events += self._start(batch)
            if self.grid is None:
                return events
        self.n_input_samples += max((len(s) for s in batch.streams.values()), default=0)
        self.grid.push(batch)
        t, vals = self.grid.pull()
        if t.size:
            events += self._process(t, vals)
        return events

    def finish(self) -> list[Event]:
        """End the session: process what is buffered, close the last walking bout, emit the last step."""
        events: list[Event] = []
        if self.grid is None:
            return [{"type": "notice", "message": "no accelerometer data: empty track"}]
        t, vals = self.grid.pull()
        if t.size:
            events += self._process(t, vals)
        t, vals = self.grid.flush()
        events += self._process(t, vals, final=True)
        if self.pending is not None:
            events += self._emit_step(self.pending, None)
            self.pending = None
        if self.track.n_steps == 0:
            events.append({"type": "notice", "message": "no walking detected: empty track"})
        return events

    def run(self, recording: Recording) -> list[Event]:
        """Whole recording as one batch, then :meth:`finish`."""
        return self.update(recording) + self.finish()

    # -- state -------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state (configuration and site included)."""
        return {
            "config": self.config.to_dict(), "site": None if self.site is None else self.site.to_dict(),
            "grid": None if self.grid is None else self.grid.to_dict(), "steps": self.steps.state_dict(),
            "attitude": self.attitude.state.to_dict(), "magcal": self.magcal.to_dict(), "floors": self.floors.to_dict(),
            "elevator": self.elevator.to_dict(), "track": self.track.to_dict(), "offset": self.offset.to_dict(),
            "hde": self.hde.to_dict(), "history": self.history.to_dict(), "placement": self.placement,
            "auto_placement": self.auto_placement, "placement_detector": self.placement_detector.to_dict(),
            "t0_ns": self.t0_ns,
            "prev_yaw": self.prev_yaw, "prev_q": self.prev_q, "prev_mode": self.prev_mode,
            "last_step": None if self.last_step is None else list(self.last_step),
            "stairs_landmark": self.stairs_landmark, "landmark_updates": self.landmark_updates,
            "landmark_attitude_updates": self.landmark_attitude_updates,
            "prev_step_start": self.prev_step_start, "direction_score": self.direction_vote.score,
            "direction_votes": self.direction_vote.n, "swing_axis": self.swing_axis.to_dict(),
            "pocket_direction": self.pocket_direction.to_dict(),
            "pending": _jsonable(self.pending),
            "pitch_baseline": self.pitch_baseline, "last_floor": self.last_floor, "notices": self.notices,
            "av_zi": None if self._av_zi is None else self._av_zi.tolist(), "n_input_samples": self.n_input_samples,
            "gyro_yaw": self.gyro_yaw.state_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], placement_provider: PlacementProvider | None = None) -> PdrPipeline:
        try:
            site = None if d["site"] is None else Site.from_dict(d["site"])
            p = cls(PipelineConfig.from_dict(d["config"]), site, placement_provider)
            p.grid = None if d["grid"] is None else OnlineGrid.from_dict(d["grid"])
            p.steps = StepDetector.from_state_dict(d["steps"])
            p.attitude.state = AttitudeState.from_dict(d["attitude"])
            if d.get("magcal") is not None:
                p.magcal = HardIronEstimator.from_dict(d["magcal"], p.config.rate_hz, p.config.magcal)
            p.floors = FloorTracker.from_dict(d["floors"])
            p.elevator = ElevatorDetector.from_dict(d["elevator"], p.config.landmarks)
            p.track = TrackState.from_dict(d["track"])
            p.offset = OffsetEstimator.from_dict(d["offset"])
            if d.get("hde") is not None:      # absent in states saved before the drift elimination
                p.hde = StepDriftElimination.from_dict(d["hde"], p.config.hde, p._grid_yaw())
            p.history = _History.from_dict(d["history"])
            p.placement, p.t0_ns = d["placement"], int(d["t0_ns"])
            # Absent in states saved before the online placement detector: their placement stays as it was.
            p.auto_placement = bool(d.get("auto_placement", False))
            if d.get("placement_detector") is not None:
                p.placement_detector = PlacementDetector.from_dict(d["placement_detector"], p.config.placement_detect)
            p.prev_yaw, p.prev_q, p.prev_mode = d["prev_yaw"], d["prev_q"], str(d["prev_mode"])
            last = d.get("last_step")             # absent in states saved before the turn factor
            p.last_step = None if last is None else (float(last[0]), float(last[1]))
            # Absent in states saved before per-step stairs landmarks.
            p.stairs_landmark = d.get("stairs_landmark")
            p.landmark_updates = int(d.get("landmark_updates", 0))
            p.landmark_attitude_updates = int(d.get("landmark_attitude_updates", 0))
            p.prev_step_start = None if d["prev_step_start"] is None else int(d["prev_step_start"])
            if d.get("swing_axis") is not None:     # absent in states saved before the device-frame swing axis
                p.swing_axis = DeviceSwingAxis.from_dict(d["swing_axis"])
            if d.get("pocket_direction") is not None:   # absent in states saved before the device-frame continuity
                p.pocket_direction = DeviceFrameDirection.from_dict(d["pocket_direction"])
            p.direction_vote = _direction_vote(p.placement)
            p.direction_vote.score = float(d["direction_score"])
            p.direction_vote.n = int(d["direction_votes"])
            p.pending = _from_jsonable(d["pending"])
            p.pitch_baseline, p.last_floor = d["pitch_baseline"], float(d["last_floor"])
            p.notices = list(d["notices"])
            p._av_zi = None if d["av_zi"] is None else np.array(d["av_zi"], dtype=np.float64)
            p.n_input_samples = int(d["n_input_samples"])
            if isinstance(d.get("gyro_yaw"), dict):      # older states kept a plain integral (restarted here)
                p.gyro_yaw = GyroYaw.from_state_dict(d["gyro_yaw"], p.config.rate_hz)
            if p.pending is not None or p.track.n_steps:      # a step was processed (see _placement_known)
                p._placement_known()
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad pipeline state ({exc})", source="pipeline state") from None
        return p

    # -- internals ---------------------------------------------------------------------------------
    def _start(self, batch: Recording) -> list[Event]:
        events: list[Event] = []
        if not batch.has("acc"):
            return [{"type": "notice", "message": "batch without accelerometer samples skipped"}]
        kinds = ["acc"]
        for k, msg in (("gyro", "no gyroscope: attitude from accelerometer and magnetometer only, heading noisy"),
                       ("mag", "no magnetometer: heading is relative to the initial device heading"),
                       ("baro", "no barometer: floors are not tracked")):
            if batch.has(k):
                kinds.append(k)
            else:
                self.notices.append(msg)
                events.append({"type": "notice", "message": msg})
        self.grid = OnlineGrid(self.config.rate_hz, tuple(kinds))
        self.t0_ns = 0
        if self.placement is None:
            if self.placement_provider is not None:
                self.placement = _placement_group(self.placement_provider(batch))
            if self.placement is None:
                self.placement = _placement_group(batch.device.placement)
            self.auto_placement = self.placement is None
        return events

    def _process(self, t: FloatArray, vals: dict[str, FloatArray], final: bool = False) -> list[Event]:
        assert self.grid is not None and self.grid.first_k is not None
        events: list[Event] = []
        n = t.size
        acc = vals["acc"] if n else np.zeros((0, 3))
        g0 = self.steps._n_seen
        steps, an = self.steps.update(acc, final=final)
        kinds = self.grid.kinds
        gyro = vals["gyro"] if "gyro" in kinds and n else None
        mag = vals["mag"] if "mag" in kinds and n else None
        if mag is not None and gyro is not None:
            # Hard-iron offset learnt online from the rotation (pdr.phone.magcal); applied only once significant.
            mag = self.magcal.update(mag, gyro, self.attitude.state.bias)
        mag_n = np.linalg.norm(mag, axis=1) if mag is not None else np.full(n, np.nan)
        if "baro" in kinds and n:
            up, floor = self.floors.update(vals["baro"][:, 0], np.ones(n, dtype=bool))
            changes = np.flatnonzero(np.diff(np.concatenate([[self.last_floor], floor])) != 0)
            for i in changes:
                events.append({"type": "floor_change", "t_s": float(t[i]), "floor": float(floor[i]),
                               "from_floor": float(self.last_floor if i == 0 else floor[i - 1])})
            if floor.size:
                self.last_floor = float(floor[-1])
        else:
            up, floor = np.zeros(n), np.full(n, self.last_floor)
        self.history.append(g0, t, acc, an, mag_n, up, floor)
        # Attitude in segments ending where steps become known (landmark updates at fixed samples).
        by_confirm: dict[int, list[int]] = {}
        for j in np.lexsort((steps.start_idx, steps.confirm_idx)).tolist():
            by_confirm.setdefault(int(steps.confirm_idx[j]), []).append(j)
        cuts = sorted({int(c) for c in steps.confirm_idx} | {g0 + n - 1}) if n else sorted(
            {int(c) for c in steps.confirm_idx})
        pos = g0
        for cut in cuts:
            if n and cut >= pos:
                a, b = pos - g0, cut - g0 + 1
                qs, _ = self.attitude.run(acc[a:b], None if gyro is None else gyro[a:b],
                                          None if mag is None else mag[a:b])
                hs = self.history.sl(pos, cut + 1)
                self.history.q[hs] = qs
                f_n, yy, yz, yu = _derived(qs, acc[a:b])
                self.history.f_n[hs], self.history.yaw_y[hs], self.history.yaw_z[hs] = f_n, yy, yz
                self.history.y_up[hs] = yu
                if gyro is not None:
                    self.history.gyro_yaw[hs], self.history.up_time[hs] = self.gyro_yaw.update(qs, gyro[a:b])
                pos = cut + 1
            for j in by_confirm.get(cut, []):
                    events += self._step(int(steps.start_idx[j]), int(steps.end_idx[j]), float(steps.peak[j]))
        if n:
            events += self._elevator(t, g0)
        self.history.trim()
        return events

    def _elevator(self, t: FloatArray, g0: int) -> list[Event]:
        av = self.history.f_n[self.history.sl(g0, g0 + t.size), 2] - GRAVITY_MPS2
        b, a = self._av_ba
        if self._av_zi is None:
            self._av_zi = iir.lfilter_zi(b, a) * av[0]
        dv, self._av_zi = iir.lfilter(b, a, av, self._av_zi)
        out: list[Event] = []
        for s, e, direction in self.elevator.update(dv, np.zeros(dv.size, dtype=bool)):
            sl = self.history.sl(s, e + 1)
            dh = float(self.history.up[sl][-1] - self.history.up[sl][0]) if self.history.up[sl].size else 0.0
            has_baro = self.grid is not None and "baro" in self.grid.kinds
            if has_baro and abs(dh) < 0.5 * self.floors.config.floor_height_m:
                continue
            mags = self.history.mag_n[sl]
            ev: Event = {"type": "elevator", "t_start_s": float(self.history.t[sl][0]) if mags.size else float(t[0]),
                         "t_end_s": float(self.history.t[sl][-1]) if mags.size else float(t[-1]),
                         "direction": "up" if direction > 0 else "down", "altitude_change_m": dh,
                         "mag_change_uT": float(np.nanmax(mags) - np.nanmin(mags)) if np.isfinite(mags).any() else None}
            if self.site is not None:
                lm = self.site.match("elevator", self.track.east_m, self.track.north_m, math.nan)
                if lm is not None:
                    self.track.fix(lm.east_m, lm.north_m, 1.0)
                    ev["site_landmark"] = lm.id
            out.append(ev)
        return out

    def _placement_known(self) -> None:
        """Attitude parameters of the placement: ``device_heading_sigma_gyro`` for hand and torso, from the first
        step on (the same sample whether the placement came from the configuration, a provider or the detector),
        and the configured ``sigma_gyro`` again when a detected placement changes to another carriage.
        """
        sg = self.config.device_heading_sigma_gyro
        if sg is None:
            return
        want = float(sg) if self.placement in ("hand", "torso") else self.config.attitude.sigma_gyro
        if self.attitude.config.sigma_gyro != want:
            self.attitude.set_config(replace(self.attitude.config, sigma_gyro=want))

    def _detect_placement(self, s: int, e: int) -> None:
        """Online placement from the stride ending with this step (:mod:`pdr.phone.placement_detect`); a change
        restarts the carriage-specific heading state (the pocket's walking-direction continuity and vote).
        """
        if self.grid is not None and "gyro" not in self.grid.kinds:
            # Without a gyroscope the attitude follows the specific force: the thigh's or arm's turn is not seen.
            self.placement, self.auto_placement = "hand", False
            self.notices.append("no gyroscope: placement not detected, the phone is taken as hand-held "
                                "(give the placement if it is in a pocket)")
            return
        h = self.history
        stride = h.sl(s - (e - s), e)
        q, acc = h.q[stride], h.acc[stride]
        if q.shape[0] < 3 or not np.all(np.isfinite(q)):
            return
        new = self.placement_detector.update(stride_cues(q, acc, self.config.rate_hz,
                                                         self.config.placement_detect.smooth_s))
        if new == self.placement:
            return
        if self.placement is not None:
            self.notices.append(f"placement changed from {self.placement} to {new} at t={float(h.t[stride][-1]):.2f} s")
        else:
            self.notices.append(f"placement detected: {new}")
        self.placement = new
        self.prev_yaw = self.prev_q = self.prev_step_start = None
        self.direction_vote = _direction_vote(new)
        self.swing_axis = DeviceSwingAxis()
        self.pocket_direction = DeviceFrameDirection()

    def _step(self, s: int, e: int, peak: float) -> list[Event]:
        h = self.history
        sl = h.sl(s, e)
        q = h.q[sl]
        if q.shape[0] < 3 or not np.all(np.isfinite(q)):
            return []
        c = self.config
        if self.auto_placement:
            self._detect_placement(s, e)
        if self.placement is None:
            return []
        # From the first step on, whenever the placement became known (configuration, provider or rule).
        self._placement_known()
        f_n = h.f_n[sl]
        a_v = f_n[:, 2]
        pats = step_patterns(h.an[sl], a_v, c.rate_hz)
        # Heading.
        axis, _ratio = pca_axis(f_n[:, :2])                     # RMPCA
        st = self.attitude.state
        if self.placement in ("pocket", "swinging"):
            # A pocket phone moves with one thigh, whose stance and swing halves of the gait cycle differ: the
            # walking axis (RMPCA) and the 180-degree rule use the stride made of this step and the one before
            # it (a step's length before it after a pause).
            ps = self.prev_step_start
            s0 = ps if ps is not None and 0 < s - ps <= 2 * (e - s) else s - (e - s)
            self.prev_step_start = s
            stride = h.sl(s0, e)
            q_str, f_str = h.q[stride], h.f_n[stride]
            if not (np.all(np.isfinite(q_str)) and np.all(np.isfinite(f_str))):
                q_str, f_str = q, f_n
            swing_axis = c.pocket_axis == "swing" or (
                c.pocket_axis == "auto" and (self.site is None or not self.site.landmarks))
            if self.placement == "swinging":
                # The arm's swing axis, fixed in the device frame while the grip holds, with its sign decided
                # by the turns (pdr.phone.walking_direction.DeviceSwingAxis): no per-stride continuity or vote.
                axis = self.swing_axis.update(q_str, f_str, c.rate_hz, q_str.shape[0] - q.shape[0])
            elif swing_axis:
                # The swing plane's axis of the thigh (pdr.phone.walking_direction), not the device yaw.
                axis, _ratio = swing_plane_axis(q_str, c.rate_hz)
            else:
                axis, _ratio = pca_axis(f_str[:, :2])             # RMPCA over the stride
            if self.placement == "swinging":
                psi0 = axis
            else:
                # Continuity in the device frame, and the 180-degree rule from the thigh's fast swing
                # (pdr.phone.heading module doc) and the centripetal acceleration in turns
                # (pdr.phone.walking_direction module doc, "Trouser pocket: continuity").
                psi0 = self.pocket_direction.resolve(axis, q_str)
                turn = turn_evidence(f_str, yaw_rate(q_str, c.rate_hz), psi0, speed_range_mps=POCKET_TURN_SPEED_MPS)
                if self.direction_vote.update(thigh_swing_evidence(q_str, c.rate_hz, psi0) + POCKET_TURN_WEIGHT * turn):
                    psi0 = float(wrap_angle(psi0 + math.pi))
                    self.pocket_direction.reverse()
                    if self.pending is not None:
                        # The step waiting for output was resolved by the refuted direction: reverse it too.
                        self.pending["yaw"] = float(wrap_angle(self.pending["yaw"] + math.pi))
                        self.pending["psi0"] = float(wrap_angle(self.pending["psi0"] + math.pi))
            m1 = scatter_of(f_str, st.q)
            if swing_axis or self.placement == "swinging":
                est = HeadingEstimate(psi0, yaw_variance(st.q, st.P) + c.heading_process_var)
            else:
                est = improved_rmpca_ut(st.q, st.P, m1, psi0, c.heading_process_var, self._ut_points())
            if self.placement == "pocket":
                self.pocket_direction.update(est.yaw, q_str)
            self.prev_yaw = est.yaw
        else:
            dev = mean_yaw(h.yaw_z[sl] if self.placement == "torso" else h.yaw_y[sl])   # seed 004 eq. 21
            if c.heading_offset == "pca":
                off = self.offset.update(axis, dev)
            else:
                off = 0.0
            psi0 = float(wrap_angle(dev + off))
            m1 = scatter_of(f_n, st.q) if self.site is not None else np.zeros((3, 3))
            var = yaw_variance(st.q, st.P) + c.heading_process_var
            est = HeadingEstimate(psi0, var)
        # Landmark label (third level of the tree).
        rate = None
        if self.grid is not None and "baro" in self.grid.kinds:
            back = h.sl(s - int(2.0 * c.rate_hz), e)
            tt, uu = h.t[back], h.up[back]
            if tt.size > 2 and tt[-1] > tt[0]:
                rate = float((uu[-1] - uu[0]) / (tt[-1] - tt[0]))
        pmax = pmin = None
        if self.placement == "pocket":
            pitch = np.degrees(np.arcsin(np.clip(h.y_up[sl], -1, 1)))
            pmax, pmin = float(pitch.max()), float(pitch.min())
        base = tuple(self.pitch_baseline) if self.pitch_baseline else None
        mode = classify_step(rate, pmax, pmin, base, c.landmarks)  # type: ignore[arg-type]
        if mode == "walking" and pmax is not None and pmin is not None:
            nb = [pmax - pmin, pmax, pmin]
            self.pitch_baseline = nb if self.pitch_baseline is None else [
                0.9 * a + 0.1 * b for a, b in zip(self.pitch_baseline, nb, strict=True)]
        rec = {"s": s, "e": e, "t_start": float(h.t[sl][0]), "t_end": float(h.t[sl][-1]) + 1.0 / c.rate_hz,
               "pats": pats.tolist(), "yaw": est.yaw, "var": est.var, "psi0": psi0, "axis": axis,
               "mode": mode, "up": float(h.up[sl][-1]), "floor": float(h.floor[sl][-1]), "m1": m1.tolist(),
               "q1": st.q.tolist(), "peak": peak, "gyro_yaw": _mean_finite(h.gyro_yaw[sl]),
               "up_time": _mean_finite(h.up_time[sl]),
               "gyro_bias": st.bias.tolist() if self.attitude.bias_known else None}
        events: list[Event] = []
        if self.pending is not None:
            events += self._emit_step(self.pending, rec)
        self.pending = rec
        return events

    def _emit_step(self, rec: dict[str, Any], nxt: dict[str, Any] | None) -> list[Event]:
        c = self.config
        mode = rec["mode"]
        max_gap = c.step.max_step_s + 1e-9
        if nxt is not None and self.prev_mode and nxt["t_start"] - rec["t_end"] < max_gap:
            mode = neighbour_correction(self.prev_mode, mode, nxt["mode"])
        on_stairs = mode in ("stairs_up", "stairs_down")
        # The walking direction's change since the previous step of the same walk (pdr.phone.step_length turn factor).
        # Hand and torso only: there the step heading follows the device's smooth yaw; a pocket phone's per-step
        # heading jitters with the thigh (MobiFall walks: 90th percentile 9-66 deg per step), which is no turn.
        last = self.last_step
        turn = (abs(float(wrap_angle(rec["yaw"] - last[0])))
                if last is not None and rec["t_start"] - last[1] < max_gap and not on_stairs
                and self.placement in ("hand", "torso") else 0.0)
        self.last_step = (float(rec["yaw"]), float(rec["t_end"]))
        length = float(self.config.step_length.length(np.array(rec["pats"]), on_stairs, turn))
        est = HeadingEstimate(rec["yaw"], rec["var"])
        events: list[Event] = []
        fixed = landmark_heading = False
        if self.site is not None and on_stairs:
            # Every step of a flight of stairs observes the landmark (seed 003 Sec. 5: a landmark is available
            # while the decision tree labels the steps stairs). The flight is matched at its first step, which
            # also fixes the position; the following steps of the flight keep that landmark.
            entering = self.prev_mode not in ("stairs_up", "stairs_down")
            if entering:
                lm = self.site.match(mode, self.track.east_m, self.track.north_m, rec["floor"])
                self.stairs_landmark = None if lm is None else lm.id
            else:
                lm = self.site.by_id(self.stairs_landmark) if self.stairs_landmark is not None else None
            if lm is not None:
                yaw_lm, var_lm = lm.yaw_and_var()
                st = self.attitude.state
                d_uh = float(wrap_angle(yaw_lm - rec["psi0"]))
                attitude_updated = False
                if abs(d_uh) < math.pi / 4 and self.placement == "pocket":
                    # First UKF landmark row (eqs. 20, 32) on the current attitude. The step's scatter matrix
                    # was expressed in the device frame of the attitude q1 the filter had when the step was
                    # processed; the filter has moved on by one step since (output delay), so the samples are
                    # carried into the current device frame (eqs. 14-16 with t1 = now) before f(q) is evaluated.
                    m_now = scatter_in_frame(np.array(rec["m1"]), np.array(rec["q1"]), st.q)
                    st.q[:], st.P[:, :] = landmark_attitude_update(st.q, st.P, m_now, rec["psi0"], d_uh, var_lm,
                                                                   self._ut_points())
                    attitude_updated = True
                est = fuse_landmark(est, yaw_lm, var_lm)                 # second UKF (eq. 42)
                landmark_heading = True
                if entering:
                    self.track.fix(lm.east_m, lm.north_m, 1.0)
                    fixed = True
                    events.append({"type": "landmark", "t_s": self._clock(rec["t_start"]), "landmark": lm.id,
                                   "mode": mode})
                self.landmark_updates += 1
                self.landmark_attitude_updates += int(attitude_updated)
        else:
            self.stairs_landmark = None
        if self.placement in ("pocket", "swinging") and self.prev_yaw is not None:
            # The step after this one is already resolved (one-step output delay): it keeps its own heading,
            # moved by the correction a landmark made here (replacing it by this step's would make every
            # other step resolve against a heading two steps old).
            self.prev_yaw = float(wrap_angle(self.prev_yaw + (est.yaw - rec["yaw"])))
        raw_yaw = est.yaw
        if c.drift_elimination and self.placement in ("hand", "torso"):
            # Heuristic drift elimination towards the walk's dominant directions (pdr.phone.heading module doc).
            est = HeadingEstimate(self.hde.step(est.yaw, length, rec["t_end"]), est.var)
        self.track.step(length, est.yaw, (c.step_length_rel_sigma * length) ** 2, est.var)
        self.prev_mode = mode
        events.append({
            "type": "step", "t_s": self._clock(rec["t_end"]), "t_start_s": self._clock(rec["t_start"]),
            "east_m": self.track.east_m, "north_m": self.track.north_m, "up_m": rec["up"], "floor": rec["floor"],
            "heading_deg": float(yaw_to_heading_deg(est.yaw)), "step_length_m": length,
            "turn_deg": math.degrees(turn), "mode": mode,
            "placement": self.placement, "heading_sigma_deg": math.degrees(math.sqrt(est.var)),
            "pos_sigma_m": math.sqrt(max(float(np.trace(self.track.P)), 0.0)),
            "patterns": rec["pats"],
            # Inputs of the offline heading smoother (pdr.phone.heading_smoother).
            "heading_raw_deg": float(yaw_to_heading_deg(raw_yaw)),
            "gyro_heading_deg": None if rec.get("gyro_yaw") is None else float(yaw_to_heading_deg(rec["gyro_yaw"])),
            "up_time_s": rec.get("up_time"),
            "gyro_bias_dps": None if rec.get("gyro_bias") is None else np.degrees(rec["gyro_bias"]).tolist(),
            "position_fix": fixed, "landmark_heading": landmark_heading,
        })
        return events

    def _grid_yaw(self) -> float | None:
        """Yaw (rad, ENU) of the site's building grid for the drift elimination, or None."""
        if self.site is None or self.site.grid_deg is None:
            return None
        return float(heading_deg_to_yaw(self.site.grid_deg))

    def _ut_points(self) -> SigmaPoints:
        """Sigma points of the unscented transforms on ``q(t1)`` (eqs. 35-37), with the attitude UKF's parameters."""
        a = self.config.attitude
        return SigmaPoints(4, alpha=a.alpha, beta=a.beta, kappa=a.kappa)

    def _clock(self, t_s: float) -> float:
        return t_s


def _direction_vote(placement: str | None) -> DirectionVote:
    """The trouser pocket's forward/backward vote (the swinging hand decides its sign in
    :class:`pdr.phone.walking_direction.DeviceSwingAxis`).
    """
    return DirectionVote()


def _mean_finite(x: FloatArray) -> Any:
    """Mean over the first axis of ``x`` ((N,): a float; (N, k): a list of k floats), or None where any value
    is missing (no gyro).
    """
    # x.sum / n is what np.mean computes (the same pairwise sum and division), without its dispatch per step.
    return (x.sum(axis=0) / x.shape[0]).tolist() if x.size and np.isfinite(x).all() else None


def _placement_group(name: str | None) -> str | None:
    if name is None:
        return None
    if name in ("pocket", "hand", "torso"):
        return name
    return PLACEMENT_GROUPS.get(name)


def _jsonable(d: dict[str, Any] | None) -> dict[str, Any] | None:
    return None if d is None else dict(d)


def _from_jsonable(d: dict[str, Any] | None) -> dict[str, Any] | None:
    return None if d is None else dict(d)


def track_rows(events: list[Event]) -> list[Event]:
    """The step events of an event list, in order."""
    return [e for e in events if e.get("type") == "step"]


#: Walking speeds (m/s) whose centripetal acceleration is taken as turn evidence in a pocket (walking to running),
#: and the weight of that evidence in the pocket's vote beside the thigh-swing skewness
#: (pdr.phone.walking_direction module doc, "Trouser pocket: continuity").
POCKET_TURN_SPEED_MPS = (0.4, 4.0)
POCKET_TURN_WEIGHT = 0.1
