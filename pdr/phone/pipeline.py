"""The online phone PDR pipeline: ``update(batch) -> events`` with serialisable state.

Stages per batch (each keeps its own state, so a session can be fed batch by batch, saved with
:meth:`PdrPipeline.state`, resumed with :meth:`PdrPipeline.from_state`, and gives the same track as one
big batch):

1. :class:`pdr.phone.grid.OnlineGrid`: acc, gyro, mag, baro on one uniform grid (``rate_hz``);
   the magnetometer's hard-iron offset is learnt online from the gyro (:mod:`pdr.phone.magcal`) and removed once
   significant, unless the log shows the OS's own calibration; a site's ``declination_deg`` replaces the configured
   declination;
2. :class:`pdr.phone.steps.StepDetector` (seed 004 Sec. 3.2) on the accelerometer;
3. :class:`pdr.phone.attitude.AttitudeFilter` (seed 003 UKF, or the EKF baseline), run in segments that end
   where steps become known, so a landmark can update the attitude (eqs. 14-32) at a deterministic sample;
4. per step: patterns and length (seed 004 eqs. 13-19), heading (:mod:`pdr.phone.heading_stages` on
   :mod:`pdr.phone.heading`: device heading +
   offset for hand-held/torso, improved RMPCA + second UKF for the trouser pocket; hand-held/torso headings
   then pass the heuristic drift elimination :class:`pdr.phone.heading.StepDriftElimination`), landmark label
   (:mod:`pdr.phone.landmarks`, with the neighbour-step correction, which delays each step by one step),
   site landmarks (a flight of stairs: position fix at its first step, heading rows of both UKFs at every
   step of it), floor (:mod:`pdr.phone.floors`), and the PDR position (:mod:`pdr.phone.track`, eqs. 20-22);
5. elevator rides: with a barometer, a climb stood through and walked out of (:mod:`pdr.phone.baro_rides`),
   else the vertical specific force's impulses (:class:`pdr.phone.landmarks.ElevatorDetector`);
6. stair flights from the steps' modes and altitudes (:class:`pdr.phone.floors.StairFlights`), each with its floor
   count, emitted with the first step after the flight.

Events are frozen dataclasses (:mod:`pdr.phone.events`: a step, a floor change, a landmark, an elevator ride, a
stair flight, a notice of degraded input); :meth:`PdrPipeline.update` returns their rows (``{"type": "step", "t_s",
"east_m", ...}``), :meth:`PdrPipeline.update_events` the dataclasses. ``t_s`` is on the log's own clock (seconds).
The per-step stages and how to plug in another are described in :mod:`pdr.phone.stage` and ``docs/architecture.md``.

Placement (``pocket``, ``hand``, ``torso``, ``swinging``) comes from the configuration, else from an injected
``placement_provider(recording) -> str | None`` (e.g. the placement classifier; pdr/ never imports it),
else from the recording's :class:`~pdr.recording.DeviceInfo`, else it is detected online from the physics of
the carriage, stride by stride (:mod:`pdr.phone.placement_detect`: a steady device is held, a pendulum's specific
force stays along the arm, a pocket phone's turns with the thigh), and revised when the phone changes place.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters import iir
from pdr.filters.numpy_reductions import all_finite, column_sums, pairwise_sum
from pdr.frames import GRAVITY_MPS2, heading_deg_to_yaw, yaw_to_heading_deg_float
from pdr.geomagnetic import field_at_fix
from pdr.phone.attitude import AttitudeConfig, AttitudeFilter, AttitudeState, gyro_compensated
from pdr.phone.attitude_derived import attitude_derived
from pdr.phone.baro_rides import BaroRide, BaroRides
from pdr.phone.events import (
    ElevatorEvent,
    EventRow,
    FloorChangeEvent,
    NoticeEvent,
    PipelineEvent,
    StairFlightEvent,
    StepEvent,
    to_rows,
)
from pdr.phone.floors import FloorConfig, FloorTracker, StairFlights
from pdr.phone.grid import OnlineGrid
from pdr.phone.gyro_yaw import GyroYaw
from pdr.phone.heading import DriftEliminationConfig, HeadingEstimate, StepDriftElimination, pca_axis
from pdr.phone.heading_stages import (
    DEVICE_HEADING_PLACEMENTS,
    STRIDE_HEADING_PLACEMENTS,
    DeviceHeading,
    DriftElimination,
    PocketHeading,
    StairsLandmarkHeading,
    StepTurn,
)
from pdr.phone.history import SampleHistory
from pdr.phone.landmarks import ElevatorDetector, LandmarkConfig, Site, StepModeLabeller
from pdr.phone.magcal import HardIronEstimator, MagCalConfig, mag_os_calibrated
from pdr.phone.phone_orientation import grid_attitudes, phone_yaw_update
from pdr.phone.placement_detect import PlacementDetectConfig, PlacementDetector, stride_cues
from pdr.phone.stage import PendingStep, StepObserver, StepStage, StepWindow
from pdr.phone.step_length import StepLengthModel, step_patterns
from pdr.phone.steps import StepConfig, StepDetector
from pdr.phone.track import TrackState
from pdr.recording import LOCATION_META, Recording

FloatArray = NDArray[np.float64]
#: The row form of an event (:meth:`pdr.phone.events.StepEvent.to_row` and the others).
Event = EventRow
PlacementProvider = Callable[[Recording], "str | None"]

PLACEMENT_GROUPS = {"trouser_pocket_front": "pocket", "trouser_pocket_back": "pocket", "trouser_pocket": "pocket",
                    "hand": "hand", "torso": "torso", "neck": "torso", "bag": "torso", "armband": "hand"}
#: Layout of :meth:`PdrPipeline.state`: 1 (no ``format`` key) before the stage classes, 2 since (the same keys plus
#: ``format`` and the plugged-in stages' ``stages``). :meth:`PdrPipeline.from_state` reads both.
STATE_FORMAT = 2
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
        ``auto``, ``detect``, ``pocket``, ``hand``, ``torso`` or ``swinging`` (a phone in a hand swinging with the
        arm). ``auto``: the placement a provider or the log's device gives, else detected online
        (:mod:`pdr.phone.placement_detect`); ``detect``: detected online whatever they give.
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
    limb_sigma_a_moving
        ``attitude.sigma_a_moving`` (m/s^2) once the placement is a trouser pocket or a swinging hand: gravity rows
        while the phone moves with a limb (:class:`pdr.phone.attitude.AttitudeConfig`, ``sigma_a_moving``). None
        keeps ``attitude.sigma_a_moving`` for every placement. Chosen on the motion-capture benchmark's tuning
        walker among 0.75, 1.5 and 3 (walking direction 14.1, 13.9, 14.2 deg causal; ``pdr eval heading``), and
        confirmed on the other (15.6, 14.3, 14.4; 15.2 without).
    limb_mag_bias_gain
        ``attitude.mag_bias_gain`` (1/s^2) once the placement is a trouser pocket or a swinging hand (None keeps
        ``attitude.mag_bias_gain`` for every placement). Not for a hand-held phone: in the IPIN steel building the
        field's deflection changes slowly along the corridors, and the integral took it for a bias (the hand-held
        IPIN walks' smoothed p75 rose from 3.02 to 3.74 m with it, ``pdr eval ipin``).
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
    attitude_source
        ``filter``: the attitude ``q_nb`` of every stage is our attitude filter's (``attitude_method``);
        ``phone``: the phone's own fused attitude, the log's ``orientation`` stream on the grid (nlerp,
        :mod:`pdr.phone.phone_orientation`), everything else unchanged (our filter still runs for the gyro bias, the
        hard-iron calibration and the attitude covariance): the phone's heading as a reference in the evaluations.
        A recording without an ``orientation`` stream is refused.
    use_phone_orientation
        Use the ``orientation`` stream's yaw as a measurement of our attitude filter at every confirmed step
        (:func:`pdr.phone.phone_orientation.phone_yaw_update`, variance ``phone_yaw_sigma_deg``^2, gated at
        ``phone_yaw_gate_sigma`` standard deviations of the predicted innovation). Ignored (with a notice) when the
        log has no such stream.
    phone_yaw_sigma_deg, phone_yaw_gate_sigma
        Standard deviation (deg) of the phone's yaw and the gate of its row. 10 deg: the rotation vector's yaw error
        against motion capture is about 4 deg on clean walks and 11-29 deg in a disturbed field
        (``../shared/data/attitude_smartphones``, issue 25); the gate keeps the disturbed stretches out once ours
        is confident.
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
    limb_sigma_a_moving: float | None = 1.5
    limb_mag_bias_gain: float | None = 0.0025
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
    attitude_source: str = "filter"
    use_phone_orientation: bool = False
    phone_yaw_sigma_deg: float = 10.0
    phone_yaw_gate_sigma: float = 3.0

    def __post_init__(self) -> None:
        if self.placement not in ("auto", "detect", *PIPELINE_PLACEMENTS):
            raise InputError("placement must be auto, detect, pocket, hand, torso or swinging", field="placement",
                             source="config")
        if self.attitude_method not in ("ukf", "ekf"):
            raise InputError("attitude_method must be ukf or ekf", field="attitude_method", source="config")
        if self.pocket_axis not in ("auto", "swing", "rmpca"):
            raise InputError("pocket_axis must be auto, swing or rmpca", field="pocket_axis", source="config")
        if self.attitude_source not in ("filter", "phone"):
            raise InputError("attitude_source must be filter or phone", field="attitude_source", source="config")
        if not (self.phone_yaw_sigma_deg > 0 and self.phone_yaw_gate_sigma > 0):
            raise InputError("phone_yaw_sigma_deg and phone_yaw_gate_sigma must be positive",
                             field="phone_yaw_sigma_deg", source="config")
        if self.heading_offset not in ("zero", "pca"):
            raise InputError("heading_offset must be zero or pca", field="heading_offset", source="config")
        if not self.rate_hz >= 10:
            raise InputError("grid rate must be at least 10 Hz", field="rate_hz", source="config")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PipelineConfig:
        """The configuration of :meth:`to_dict` (a saved state's); parameters of older versions that no longer
        exist (:data:`_OBSOLETE`) are dropped.
        """
        try:
            sub = {"step": StepConfig, "attitude": AttitudeConfig, "step_length": StepLengthModel,
                   "floors": FloorConfig, "landmarks": LandmarkConfig, "magcal": MagCalConfig,
                   "hde": DriftEliminationConfig, "placement_detect": PlacementDetectConfig}
            kw = {k: (sub[k](**{n: x for n, x in v.items() if n not in _OBSOLETE.get(k, ())}) if k in sub else v)
                  for k, v in d.items()}
            return cls(**kw)
        except TypeError as exc:
            raise InputError(f"bad pipeline configuration ({exc})", source="config") from None


#: Parameters of older versions' configurations, unused and removed since, per section: dropped from saved states.
_OBSOLETE: dict[str, tuple[str, ...]] = {"landmarks": ("escalator_mag_var",)}


class PdrPipeline:
    """Online phone PDR: feed :class:`~pdr.recording.Recording` batches, get events.

    The pipeline composes its stages (module doc; :mod:`pdr.phone.stage` for the protocol): per batch the grid, the
    hard-iron calibration, the step detector, the floors, the attitude and the gyro yaw; per step the landmark
    label (:class:`pdr.phone.landmarks.StepModeLabeller`), the heading stages (:mod:`pdr.phone.heading_stages`), the
    step length and the track, then the plugged-in ``stages`` (:class:`pdr.phone.stage.StepStage`).

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
    stages
        Further per-step stages run on every step event after the PDR position update, in order (e.g. a map
        matcher).
    observers
        Watchers of each confirmed step's samples (:class:`pdr.phone.stage.StepObserver`), called before the step is
        processed; not saved in the state.
    """

    def __init__(self, config: PipelineConfig | None = None, site: Site | None = None,
                 placement_provider: PlacementProvider | None = None,
                 start_en_m: tuple[float, float] = (0.0, 0.0), stages: Sequence[StepStage] = (),
                 observers: Sequence[StepObserver] = ()) -> None:
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
            c.floors, floor_height_m=site.floor_height_m, altitudes_m=site.floor_altitudes_m), c.initial_floor)
        self.elevator = ElevatorDetector(c.rate_hz, c.landmarks)
        self.baro_rides = BaroRides(c.rate_hz, c.landmarks.elevator_max_ride_s)
        self.flights = StairFlights()
        self.track = TrackState(float(start_en_m[0]), float(start_en_m[1]))
        self.history = SampleHistory(int(c.history_s * c.rate_hz))
        self.placement: str | None = None if c.placement in ("auto", "detect") else c.placement
        # Detected online (pdr.phone.placement_detect) unless the configuration, a provider or the device names it
        # (with "detect", whatever they say).
        self.auto_placement = c.placement in ("auto", "detect")
        self.placement_detector = PlacementDetector(c.placement_detect)
        self.t0_ns = 0
        # The per-step stages.
        self.modes = StepModeLabeller(c.landmarks, c.rate_hz)
        self.device_heading = DeviceHeading(c.heading_offset, c.heading_process_var)
        self.pocket_heading = PocketHeading(c.rate_hz, c.pocket_axis, c.heading_process_var, c.attitude,
                                            self._site_has_landmarks(), self.placement)
        self.stairs = StairsLandmarkHeading(site, c.attitude)
        self.turns = StepTurn(self._max_gap_s())
        self.drift = DriftElimination(c.drift_elimination, StepDriftElimination(c.hde, self._grid_yaw()))
        self.stages: list[StepStage] = list(stages)
        self.observers: list[StepObserver] = list(observers)
        self.pending: PendingStep | None = None
        self.last_floor = float(c.initial_floor)
        self.notices: list[str] = []
        #: (placement, attitude configuration, pipeline configuration) for which :meth:`_placement_known` last set
        #: the attitude parameters: the same objects again need nothing (it runs once per step).
        self._placement_config_for: tuple[str | None, AttitudeConfig, PipelineConfig] | None = None
        self._av_zi: FloatArray | None = None
        b, a = iir.butter_lowpass(1, 0.5 / (0.5 * c.rate_hz))
        self._av_ba = (b, a)
        self.n_input_samples = 0
        self.gyro_yaw = GyroYaw(c.rate_hz)      # the gyro's rotation about the vertical since the start
        self.att_q_now: FloatArray | None = None    # attitude at the last sample (the phone's when it is the source)
        #: Whether the gyro stream is the OS's bias-compensated one (:func:`pdr.phone.attitude.gyro_compensated`).
        self.gyro_compensated = False
        #: Whether the magnetometer stream is the OS's hard-iron calibrated one
        #: (:func:`pdr.phone.magcal.mag_os_calibrated`): the online hard-iron estimator is then not run.
        self.mag_os_calibrated = False
        self.phone_yaw_updates = 0                  # phone yaw rows used by the attitude filter

    # -- public API --------------------------------------------------------------------------------
    def update(self, batch: Recording) -> list[Event]:
        """Process the next batch of the session; returns the events it produced, as rows (:meth:`update_events`)."""
        return to_rows(self.update_events(batch))

    def finish(self) -> list[Event]:
        """End the session (:meth:`finish_events`); the events as rows."""
        return to_rows(self.finish_events())

    def run(self, recording: Recording) -> list[Event]:
        """Whole recording as one batch, then :meth:`finish`."""
        return self.update(recording) + self.finish()

    def update_events(self, batch: Recording) -> list[PipelineEvent]:
        """Process the next batch of the session; returns the typed events it produced.

        A batch from a shoe IMU (:attr:`~pdr.recording.DeviceInfo.is_foot`) is refused with an :class:`InputError`
        and leaves the state as it was: phone PDR would count its strides as steps of a phone.
        """
        if batch.device.is_foot:
            d = batch.device
            raise InputError(f"this is a foot-mounted IMU recording (device role '{d.role}', placement "
                             f"'{d.placement}'); phone PDR needs a phone: use 'pdr foot' for shoe IMU logs",
                             source=batch.source or None, field="device")
        events: list[PipelineEvent] = []
        if self.grid is None:
            events += self._start(batch)
            if self.grid is None:
                return events
        if LOCATION_META in batch.meta:
            events += self.use_location(batch.meta[LOCATION_META])     # nothing once the dip is set
        self.n_input_samples += max((len(s) for s in batch.streams.values()), default=0)
        for msg in self.grid.push(batch):     # e.g. a stream the first batch lacked joins (pdr.phone.grid)
            self.notices.append(msg)
            events.append(NoticeEvent(msg))
        t, vals = self.grid.pull()
        while t.size:       # in runs over which the same streams are present (pdr.phone.grid)
            events += self._process(t, vals)
            t, vals = self.grid.pull()
        return events

    def finish_events(self) -> list[PipelineEvent]:
        """End the session: process what is buffered, close the last walking bout, emit the last step."""
        events: list[PipelineEvent] = []
        if self.grid is None:
            return [NoticeEvent("no accelerometer data: empty track")]
        t, vals = self.grid.pull()
        while t.size:
            events += self._process(t, vals)
            t, vals = self.grid.pull()
        runs = [self.grid.flush()]
        while runs[-1][0].size:
            runs.append(self.grid.flush())
        if len(runs) > 1:
            runs.pop()          # the empty one that ended the loop
        for i, (t, vals) in enumerate(runs):      # the last run ends the step detector's bouts (final)
            events += self._process(t, vals, final=i == len(runs) - 1)
        if self.pending is not None:
            events += self._emit_step(self.pending, None)
            self.pending = None
        if self.track.n_steps == 0:
            events.append(NoticeEvent("no walking detected: empty track"))
        return events

    @property
    def landmark_updates(self) -> int:
        """Steps whose heading a site landmark corrected."""
        return self.stairs.updates

    @property
    def landmark_attitude_updates(self) -> int:
        """Steps whose landmark also updated the attitude (first UKF row)."""
        return self.stairs.attitude_updates

    # -- state -------------------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """JSON-serialisable state (configuration and site included)."""
        d = {
            "format": STATE_FORMAT, "config": self.config.to_dict(),
            "site": None if self.site is None else self.site.to_dict(),
            "grid": None if self.grid is None else self.grid.state(), "steps": self.steps.state(),
            "attitude": self.attitude.state.state(), "magcal": self.magcal.state(), "floors": self.floors.state(),
            "elevator": self.elevator.state(), "baro_rides": self.baro_rides.state(),
            "stair_flights": self.flights.state(), "track": self.track.state(),
            **self.device_heading.state(),
            **self.drift.state(), "history": self.history.state(), "placement": self.placement,
            "auto_placement": self.auto_placement, "placement_detector": self.placement_detector.state(),
            "t0_ns": self.t0_ns, **self.pocket_heading.state(), **self.modes.state(), **self.turns.state(),
            **self.stairs.state(),
            "pending": None if self.pending is None else self.pending.state(),
            "last_floor": self.last_floor, "notices": self.notices,
            "av_zi": None if self._av_zi is None else self._av_zi.tolist(), "n_input_samples": self.n_input_samples,
            "gyro_yaw": self.gyro_yaw.state(), "phone_yaw_updates": self.phone_yaw_updates,
            "att_q_now": None if self.att_q_now is None else self.att_q_now.tolist(),
            "gyro_compensated": self.gyro_compensated, "mag_os_calibrated": self.mag_os_calibrated,
            "earth_dip_deg": self.attitude.config.earth_dip_deg,
        }
        if self.stages:
            d["stages"] = {st.name: st.state() for st in self.stages}
        return d

    @classmethod
    def from_state(cls, d: dict[str, Any], placement_provider: PlacementProvider | None = None,
                   stages: Sequence[StepStage] = ()) -> PdrPipeline:
        """A pipeline resuming a saved state (:meth:`state`); ``stages``: the plugged-in stages, built as for the
        saved session, each restored from its saved state. A state that cannot be resumed (damaged, of a newer format,
        or of an older one whose fields this version no longer fills in) is refused with an :class:`InputError`
        that says to reprocess the session.
        """
        if not isinstance(d, dict):
            raise InputError(f"pipeline state must be an object, got {type(d).__name__}: it cannot be resumed; "
                             "reprocess the session from its recording", source="pipeline state")
        fmt = d.get("format", 1)
        if isinstance(fmt, bool) or not isinstance(fmt, int) or not 1 <= fmt <= STATE_FORMAT:
            raise InputError(f"pipeline state of format {fmt!r}; this version reads formats 1 to {STATE_FORMAT}: it "
                             "cannot be resumed; reprocess the session from its recording", source="pipeline state",
                             field="format")
        try:
            site = None if d["site"] is None else Site.from_dict(d["site"])
            p = cls(PipelineConfig.from_dict(d["config"]), site, placement_provider)
            c = p.config
            p.grid = None if d["grid"] is None else OnlineGrid.from_state(d["grid"])
            p.steps = StepDetector.from_state(d["steps"])
            p.attitude.state = AttitudeState.from_state(d["attitude"])
            if d.get("magcal") is not None:
                p.magcal = HardIronEstimator.from_state(d["magcal"], c.rate_hz, c.magcal)
            p.floors = FloorTracker.from_state(d["floors"])
            p.elevator = ElevatorDetector.from_state(d["elevator"], c.landmarks)
            if d.get("baro_rides") is not None:         # absent in states saved before rides from the barometer
                p.baro_rides = BaroRides.from_state(d["baro_rides"])
            if d.get("stair_flights") is not None:      # absent in states saved before stair flights were events
                p.flights = StairFlights.from_state(d["stair_flights"])
            p.track = TrackState.from_state(d["track"])
            p.device_heading = DeviceHeading.from_state(d, c.heading_offset, c.heading_process_var)
            p.drift = DriftElimination.from_state(d, c.drift_elimination, p.drift.hde)
            p.history = SampleHistory.from_state(d["history"])
            p.placement, p.t0_ns = d["placement"], int(d["t0_ns"])
            # Absent in states saved before the online placement detector: their placement stays as it was.
            p.auto_placement = bool(d.get("auto_placement", False))
            if d.get("placement_detector") is not None:
                p.placement_detector = PlacementDetector.from_state(d["placement_detector"], c.placement_detect)
            p.pocket_heading = PocketHeading.from_state(d, c.rate_hz, c.pocket_axis, c.heading_process_var,
                                                        c.attitude, p._site_has_landmarks(), p.placement)
            p.modes = StepModeLabeller.from_state(d, c.landmarks, c.rate_hz)
            p.turns = StepTurn.from_state(d, p._max_gap_s())
            p.stairs = StairsLandmarkHeading.from_state(d, site, c.attitude)
            p.pending = None if d["pending"] is None else PendingStep.from_state(d["pending"])
            p.last_floor = float(d["last_floor"])
            p.notices = list(d["notices"])
            p._av_zi = None if d["av_zi"] is None else np.array(d["av_zi"], dtype=np.float64)
            p.n_input_samples = int(d["n_input_samples"])
            if isinstance(d.get("gyro_yaw"), dict):      # older states kept a plain integral (restarted here)
                p.gyro_yaw = GyroYaw.from_state(d["gyro_yaw"], c.rate_hz)
            p.phone_yaw_updates = int(d.get("phone_yaw_updates", 0))
            p.att_q_now = None if d.get("att_q_now") is None else np.array(d["att_q_now"], dtype=np.float64)
            # Absent in states saved before the compensated gyro's prior: their bias estimate goes on as it was.
            p.gyro_compensated = bool(d.get("gyro_compensated", False))
            if p.gyro_compensated:
                p._use_compensated_prior()
            # Absent in states saved before the OS's field calibration was looked for: the estimator goes on as it was.
            p.mag_os_calibrated = bool(d.get("mag_os_calibrated", False))
            # Absent in states saved before the earth's-field gate, and None where no location was known.
            if d.get("earth_dip_deg") is not None:
                p._use_earth_dip(float(d["earth_dip_deg"]))
            saved = d.get("stages") or {}
            p.stages = [st.from_state(saved[st.name]) if st.name in saved else st for st in stages]
            if p.pending is not None or p.track.n_steps:      # a step was processed (see _placement_known)
                p._placement_known()
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad pipeline state ({type(exc).__name__}: {exc}): it cannot be resumed; reprocess the "
                             "session from its recording", source="pipeline state") from None
        return p

    # -- internals ---------------------------------------------------------------------------------
    def _start(self, batch: Recording) -> list[PipelineEvent]:
        events: list[PipelineEvent] = []
        if not batch.has("acc"):
            return [NoticeEvent("batch without accelerometer samples skipped")]
        kinds = ["acc"]
        for k, msg in (("gyro", "no gyroscope: attitude from accelerometer and magnetometer only, heading noisy"),
                       ("mag", "no magnetometer: heading is relative to the initial device heading"),
                       ("baro", "no barometer: floors are not tracked")):
            if batch.has(k):
                kinds.append(k)
            else:
                self.notices.append(msg)
                events.append(NoticeEvent(msg))
        c = self.config
        if c.attitude_source == "phone" or c.use_phone_orientation:
            if batch.has("orientation"):
                kinds.append("orientation")
            elif c.attitude_source == "phone":
                raise InputError("attitude_source 'phone' needs the phone's orientation stream (rotation vector or "
                                 "AHRS), which this log does not have", source=batch.source or None,
                                 field="orientation")
            else:
                msg = "no orientation stream: the phone's heading is not used (--use-phone-orientation)"
                self.notices.append(msg)
                events.append(NoticeEvent(msg))
        if "baro" in kinds and self.floors.config.assumes_default_height():
            msg = (f"no site with the building's floor height or floor altitudes: floor numbers assume floors "
                   f"{self.floors.config.floor_height_m:g} m apart (the default floor height)"
                   + (" until stairs or an elevator between two levels measure the height"
                      if self.floors.config.learns_height() else ""))
            self.notices.append(msg)
            events.append(NoticeEvent(msg))
        if "gyro" in kinds and batch.has("gyro_uncal") and gyro_compensated(
                batch.t_s("gyro"), batch.values("gyro"), batch.t_s("gyro_uncal"), batch.values("gyro_uncal")):
            self.gyro_compensated = True
            self._use_compensated_prior()
        if "mag" in kinds and batch.has("mag_uncal"):
            self.mag_os_calibrated = mag_os_calibrated(batch.t_s("mag"), batch.values("mag"), batch.t_s("mag_uncal"),
                                                       batch.values("mag_uncal"))
        # A stream the first batch lacks joins when a later batch brings it (pdr.phone.grid).
        orientation = c.attitude_source == "phone" or c.use_phone_orientation
        self.grid = OnlineGrid(self.config.rate_hz, tuple(kinds),
                               may_join=("gyro", "mag", "baro") + (("orientation",) if orientation else ()))
        self.t0_ns = 0
        if self.placement is None and c.placement == "auto":
            if self.placement_provider is not None:
                self.placement = _placement_group(self.placement_provider(batch))
            if self.placement is None:
                self.placement = _placement_group(batch.device.placement)
            self.auto_placement = self.placement is None
        return events

    def _process(self, t: FloatArray, vals: dict[str, FloatArray], final: bool = False) -> list[PipelineEvent]:
        assert self.grid is not None and self.grid.first_k is not None
        events: list[PipelineEvent] = []
        n = t.size
        acc = vals["acc"] if n else np.zeros((0, 3))
        g0 = self.steps.samples_seen
        steps, an = self.steps.update(acc, final=final)
        kinds = vals.keys()         # the streams present over these grid points (a stopped one is not)
        gyro = vals["gyro"] if "gyro" in kinds and n else None
        q_phone = grid_attitudes(vals["orientation"]) if "orientation" in kinds and n else None
        mag = vals["mag"] if "mag" in kinds and n else None
        if mag is not None and gyro is not None and not self.mag_os_calibrated:
            # Hard-iron offset learnt online from the rotation (pdr.phone.magcal); applied only once significant; not
            # where the OS calibrated the field already.
            mag = self.magcal.update(mag, gyro, self.attitude.state.bias)
        mag_n = np.linalg.norm(mag, axis=1) if mag is not None else np.full(n, np.nan)
        if "baro" in kinds and n:
            learning = math.isnan(self.floors.learnt_height_m)
            fs = self.floors.track(vals["baro"][:, 0], np.ones(n, dtype=bool), np.linalg.norm(acc, axis=1))
            up, floor, carried = fs.up_m, fs.floor, fs.moving
            # A ride crosses at least one floor: half the lowest floor height is the least (pdr.phone.baro_rides).
            rides = self.baro_rides.update(t, fs.moving, fs.walking, fs.up_m, fs.rate_mps, 0.5 * min(
                self.floors.config.floor_height_range_m[0], self.floors.config.floor_height_m))
            if learning and not math.isnan(self.floors.learnt_height_m):
                msg = (f"floor height {self.floors.learnt_height_m:.2f} m learnt from the climb between two levels "
                       f"(stairs or an elevator, pdr.phone.floors): floor numbers from here on assume floors that "
                       f"far apart")
                self.notices.append(msg)
                events.append(NoticeEvent(msg))
            changes = np.flatnonzero(np.diff(np.concatenate([[self.last_floor], floor])) != 0)
            for i in changes:
                events.append(FloorChangeEvent(float(t[i]), float(floor[i]),
                                               float(self.last_floor if i == 0 else floor[i - 1]),
                                               bool(fs.height_assumed[i])))
            if floor.size:
                self.last_floor = float(floor[-1])
        else:
            # Without a barometer, or while it is stopped: the altitude stays where it was (0 m without one).
            up_last = float(self.history.up[-1]) if self.history.up.size else 0.0
            up, floor, carried = np.full(n, up_last), np.full(n, self.last_floor), np.zeros(n, dtype=bool)
            rides = []
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
                                          None if mag is None else mag[a:b], carried[a:b])
                if q_phone is not None and qs.shape[0]:
                    if self.config.attitude_source == "phone":
                        # The phone's attitude where it has one (the grid holds its last sample at the end).
                        ok = np.isfinite(q_phone[a:b, 0])
                        qs = np.where(ok[:, None], q_phone[a:b], qs)
                    elif cut in by_confirm:
                        # At a confirmed step (a sample that does not depend on the batching): the phone's yaw.
                        st = self.attitude.state
                        st.q, st.P, used = phone_yaw_update(st.q, st.P, q_phone[a:b][-1], self._phone_yaw_var,
                                                            self.config.phone_yaw_gate_sigma)
                        self.phone_yaw_updates += int(used)
                if qs.shape[0]:
                    self.att_q_now = qs[-1].copy()
                hs = self.history.sl(pos, cut + 1)
                self.history.q[hs] = qs
                f_n, yy, yz, yu = attitude_derived(qs, acc[a:b])
                self.history.f_n[hs], self.history.yaw_y[hs], self.history.yaw_z[hs] = f_n, yy, yz
                self.history.y_up[hs] = yu
                if gyro is not None:
                    self.history.gyro_yaw[hs], self.history.up_time[hs] = self.gyro_yaw.update(qs, gyro[a:b])
                pos = cut + 1
            for j in by_confirm.get(cut, []):
                events += self._step(int(steps.start_idx[j]), int(steps.end_idx[j]), float(steps.peak[j]))
        events += self._elevator(t, g0, rides)     # also without samples: a step confirmed at the end walks out
        self.history.trim()
        return events

    def _elevator(self, t: FloatArray, g0: int, rides: list[BaroRide]) -> list[PipelineEvent]:
        """Elevator rides of the batch: from the barometer when the phone has one (``rides``,
        :mod:`pdr.phone.baro_rides`), else from the vertical specific force's impulses
        (:class:`pdr.phone.landmarks.ElevatorDetector`).
        """
        if self._has_baro():
            return [self._ride_event(r.start, r.end, r.t_start_s, r.t_end_s, r.altitude_change_m,
                                     self.floors.floors_between(r.up_start_m, r.up_start_m + r.altitude_change_m),
                                     source="barometer")
                    for r in rides]
        av = self.history.f_n[self.history.sl(g0, g0 + t.size), 2] - GRAVITY_MPS2
        dv = av
        if av.size:
            b, a = self._av_ba
            if self._av_zi is None:
                self._av_zi = iir.lfilter_zi(b, a) * av[0]
            dv, self._av_zi = iir.lfilter(b, a, av, self._av_zi)
        assert self.grid is not None and self.grid.first_k is not None
        k0, rate = self.grid.first_k, self.config.rate_hz
        # A ride is reported once the rider walks out, when its start may have left the history: the grid's times
        # (t_k = k / rate_hz, pdr.phone.grid) of its first and last samples.
        return [self._ride_event(s, e, (k0 + s) / rate, (k0 + e) / rate, 0.0, None, direction)
                for s, e, direction in self.elevator.update(dv, np.zeros(dv.size, dtype=bool))]

    def _ride_event(self, s: int, e: int, t_start_s: float, t_end_s: float, dh: float, floors: int | None,
                    direction: int = 0, source: str = "impulses") -> ElevatorEvent:
        """The event of a ride over grid samples ``s..e`` (its direction from ``dh`` m, else ``direction``): the
        magnetic field's range over the part still in the history, and a site's elevator landmark fixing the
        position.
        """
        mags = self.history.mag_n[self.history.sl(s, e + 1)]
        site_landmark = None
        if self.site is not None:
            lm = self.site.match("elevator", self.track.east_m, self.track.north_m, math.nan)
            if lm is not None:
                self.track.fix(lm.east_m, lm.north_m, 1.0)
                site_landmark = lm.id
        up = dh > 0 if dh else direction > 0
        return ElevatorEvent(t_start_s, t_end_s, "up" if up else "down", dh,
                             float(np.nanmax(mags) - np.nanmin(mags)) if np.isfinite(mags).any() else None,
                             site_landmark, floors, source)

    def use_location(self, fix: object) -> list[PipelineEvent]:
        """The earth's field at a location fix (a batch's ``meta["location"]``, or a session's origin:
        :func:`pdr.geomagnetic.field_at_fix`) gates the magnetometer from here on
        (:attr:`~pdr.phone.attitude.AttitudeConfig.earth_dip_deg`); a notice says so. Nothing without a usable fix, or
        when the dip is set already.
        """
        earth = None if self.attitude.config.earth_dip_deg is not None else field_at_fix(fix)
        if earth is None:
            return []
        self._use_earth_dip(earth.inclination_deg)
        msg = (f"magnetometer rows are checked against the earth's field at the recording's location (dip "
               f"{earth.inclination_deg:.1f} deg, World Magnetic Model)")
        self.notices.append(msg)
        return [NoticeEvent(msg)]

    def _use_earth_dip(self, dip_deg: float) -> None:
        """Field rows whose dip departs from the earth's ``dip_deg`` (deg) are not used (the attitude filter's gate)."""
        self.attitude.set_config(replace(self.attitude.config, earth_dip_deg=float(dip_deg)))

    def _use_compensated_prior(self) -> None:
        """The gyro is the OS's bias-compensated stream (:func:`pdr.phone.attitude.gyro_compensated`): its residual bias
        is small, so the stands' bias estimate starts from the prior ``compensated_bias_prior_s``.
        """
        att = self.attitude.config
        self.attitude.set_config(replace(att, bias_prior_s=att.compensated_bias_prior_s))

    def _placement_known(self) -> None:
        """Attitude parameters of the placement: ``device_heading_sigma_gyro`` for hand and torso,
        ``limb_sigma_a_moving`` and ``limb_mag_bias_gain`` for a trouser pocket and a swinging hand, from the first
        step on (the same sample whether the placement came from the configuration, a provider or the detector), and
        the configured values again when a detected placement changes to another carriage.
        """
        att, base = self.attitude.config, self.config.attitude
        done = self._placement_config_for
        if done is not None and done[0] == self.placement and done[1] is att and done[2] is self.config:
            return      # set from these very (frozen) objects last time: ``want`` would equal ``att``
        sg, sa = self.config.device_heading_sigma_gyro, self.config.limb_sigma_a_moving
        mb = self.config.limb_mag_bias_gain
        limb = self.placement in STRIDE_HEADING_PLACEMENTS
        want = replace(att, sigma_gyro=base.sigma_gyro if sg is None or self.placement not in DEVICE_HEADING_PLACEMENTS
                       else float(sg),
                       sigma_a_moving=base.sigma_a_moving if sa is None or not limb else float(sa),
                       mag_bias_gain=base.mag_bias_gain if mb is None or not limb else float(mb))
        if want != att:
            self.attitude.set_config(want)
        self._placement_config_for = (self.placement, self.attitude.config, self.config)

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
        if q.shape[0] < 3 or not all_finite(q):
            return
        step_t = h.t[h.sl(s, e)]
        new = self.placement_detector.update(stride_cues(q, acc, self.config.rate_hz,
                                                         self.config.placement_detect.smooth_s),
                                             float(step_t[0]), float(step_t[-1]))
        if new == self.placement:
            return
        if self.placement is not None:
            self.notices.append(f"placement changed from {self.placement} to {new} at t={float(h.t[stride][-1]):.2f} s")
        else:
            self.notices.append(f"placement detected: {new}")
        self.placement = new
        self.pocket_heading.reset(new)

    def _step(self, s: int, e: int, peak: float) -> list[PipelineEvent]:
        """One confirmed step ``[s, e)``: its heading and label now, output one step later (:meth:`_emit_step`)."""
        h = self.history
        if not self._has_baro():         # the impulse detector decides rides only without a barometer
            self.elevator.add_step(s)
        for o in self.observers:
            o.confirmed(s, e, h)
        sl = h.sl(s, e)
        q = h.q[sl]
        if q.shape[0] < 3 or not all_finite(q):
            return []
        c = self.config
        if self.auto_placement:
            self._detect_placement(s, e)
        if self.placement is None:
            return []
        # From the first step on, whenever the placement became known (configuration, provider or rule).
        self._placement_known()
        f_n = h.f_n[sl]
        pats = step_patterns(h.an[sl], f_n[:, 2], c.rate_hz)
        st = self.attitude.state
        att_q = st.q if c.attitude_source == "filter" or self.att_q_now is None else self.att_q_now
        win = StepWindow(s, e, h, q, f_n, pca_axis(f_n[:, :2])[0], att_q, st.P)   # RMPCA axis of the step
        if self.placement in STRIDE_HEADING_PLACEMENTS:
            head = self.pocket_heading.estimate(win, self.placement)
            if head.reversed_direction and self.pending is not None:
                # The step waiting for output was resolved by the refuted direction: reverse it too.
                self.pending.reverse()
        else:
            head = self.device_heading.estimate(win, self.placement, self.site is not None)
        mode = self.modes.label(h, s, e, self.placement, self._has_baro())
        rec = PendingStep(s, e, float(h.t[sl][0]), float(h.t[sl][-1]) + 1.0 / c.rate_hz, pats.tolist(),
                          head.est.yaw, head.est.var, head.psi0, head.axis, mode, float(h.up[sl][-1]),
                          float(h.floor[sl][-1]), head.m1.tolist(), att_q.tolist(), peak,
                          _mean_finite(h.gyro_yaw[sl]), _mean_finite(h.up_time[sl]),
                          st.bias.tolist() if self.attitude.bias_known else None, head.pocket_side)
        events: list[PipelineEvent] = []
        if self.pending is not None:
            events += self._emit_step(self.pending, rec)
        self.pending = rec
        return events

    def _emit_step(self, rec: PendingStep, nxt: PendingStep | None) -> list[PipelineEvent]:
        """Output the step ``rec`` (``nxt``: the step after it, None at the end): label correction, turn, length,
        landmark, drift elimination, track, then the plugged-in stages.
        """
        c = self.config
        near = nxt is not None and nxt.t_start - rec.t_end < self._max_gap_s()
        mode = self.modes.corrected(rec.mode, nxt.mode if near and nxt is not None else None)
        on_stairs = mode in ("stairs_up", "stairs_down")
        turn = self.turns.turn(rec, on_stairs, self.placement)
        length = c.step_length.step_length(rec.pats, on_stairs, turn)
        est, landmark, landmark_heading = self.stairs.correct(
            rec, mode, self.modes.prev_mode, HeadingEstimate(rec.yaw, rec.var), self.track, self.attitude.state,
            self.placement)
        events: list[PipelineEvent] = [] if landmark is None else [landmark]
        if self.placement in STRIDE_HEADING_PLACEMENTS:
            self.pocket_heading.corrected(rec.yaw, est.yaw)
        raw_yaw = est.yaw
        est = self.drift.apply(est, length, rec.t_end, self.placement)
        self.track.step(length, est.yaw, (c.step_length_rel_sigma * length) ** 2, est.var)
        self.modes.prev_mode = mode
        step = StepEvent(
            t_s=rec.t_end, t_start_s=rec.t_start, east_m=self.track.east_m, north_m=self.track.north_m, up_m=rec.up,
            floor=rec.floor, heading_deg=yaw_to_heading_deg_float(est.yaw), step_length_m=length,
            turn_deg=math.degrees(turn), mode=mode, placement=self.placement,
            heading_sigma_deg=math.degrees(math.sqrt(est.var)),
            pos_sigma_m=math.sqrt(max(float(self.track.P.trace()), 0.0)), patterns=rec.pats,
            # Inputs of the offline heading smoother (pdr.phone.heading_smoother).
            heading_raw_deg=yaw_to_heading_deg_float(raw_yaw),
            gyro_heading_deg=None if rec.gyro_yaw is None else yaw_to_heading_deg_float(rec.gyro_yaw),
            up_time_s=rec.up_time,
            gyro_bias_dps=None if rec.gyro_bias is None else [math.degrees(b) for b in rec.gyro_bias],
            pocket_side=rec.pocket_side,
            position_fix=landmark is not None, landmark_heading=landmark_heading)
        flight = self.flights.step(rec.t_start, rec.t_end, mode, rec.up, rec.floor)
        if flight is not None:
            t0, t1, direction, n, up0, up1, floors = flight
            events.append(StairFlightEvent(t0, t1, direction, n, up1 - up0, floors if self._has_baro() else None))
        extra: list[PipelineEvent] = []
        for stage in self.stages:
            step, more = stage.step(step, self.track)
            extra += more
        return [*events, step, *extra]

    @property
    def _phone_yaw_var(self) -> float:
        return math.radians(self.config.phone_yaw_sigma_deg) ** 2

    def _has_baro(self) -> bool:
        return self.grid is not None and "baro" in self.grid.kinds

    def _max_gap_s(self) -> float:
        """Longest gap (s) between two steps of one walk (the detector's longest step)."""
        return self.config.step.max_step_s + 1e-9

    def _site_has_landmarks(self) -> bool:
        return self.site is not None and bool(self.site.landmarks)

    def _grid_yaw(self) -> float | None:
        """Yaw (rad, ENU) of the site's building grid for the drift elimination, or None."""
        if self.site is None or self.site.grid_deg is None:
            return None
        return float(heading_deg_to_yaw(self.site.grid_deg))


def _mean_finite(x: FloatArray) -> Any:
    """Mean over the first axis of ``x`` ((N,): a float; (N, k): a list of k floats), or None where any value
    is missing (no gyro).
    """
    # What np.mean computes (numpy's sums and a division), compiled (pdr.filters.numpy_reductions: the same bits)
    # without numpy's dispatch per step.
    if not x.size or not all_finite(x):
        return None
    return pairwise_sum(x) / x.shape[0] if x.ndim == 1 else (column_sums(x) / x.shape[0]).tolist()


def _placement_group(name: str | None) -> str | None:
    if name is None:
        return None
    if name in ("pocket", "hand", "torso"):
        return name
    return PLACEMENT_GROUPS.get(name)


def track_rows(events: list[Event]) -> list[Event]:
    """The step events of an event list, in order."""
    return [e for e in events if e.get("type") == "step"]
