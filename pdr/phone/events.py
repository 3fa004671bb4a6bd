"""The phone pipeline's events: frozen dataclasses, one per kind, each with its row form (:meth:`to_row`) for the
boundary (``pdr track``'s CSV, the service's storage and API, saved states).

Times ``t_s`` are on the log's own clock (s); positions local ENU metres of the site frame; headings compass
azimuths in degrees (:func:`pdr.frames.yaw_to_heading_deg`). A row is ``{"type": KIND, field: value, ...}`` with the
fields in declaration order (:func:`event_from_row` reads it back).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar

from pdr.errors import InputError

#: The row form of an event (a JSON object).
EventRow = dict[str, Any]


class _Event:
    """What every event has: its kind (the row's ``type``) and its row form."""

    KIND: ClassVar[str]

    def to_row(self) -> EventRow:
        """``{"type": KIND, field: value, ...}`` in declaration order."""
        row: EventRow = {"type": self.KIND}
        # A frozen dataclass's instance dict holds its fields, set in declaration order by __init__ (the one way to
        # make one): the row without a getattr per field (an hour-long walk has thousands of rows).
        row.update(self.__dict__)
        return row


@dataclass(frozen=True)
class StepEvent(_Event):
    """One step of the track.

    Attributes
    ----------
    t_s, t_start_s
        End and start of the step (s).
    east_m, north_m, up_m
        Position after the step (m, ENU; ``up_m`` from the barometer, else 0).
    floor
        Floor number.
    heading_deg
        Walking direction (deg, compass azimuth) after the drift elimination.
    step_length_m
        Horizontal step length (m).
    turn_deg
        Change of the step heading since the previous step of the walk (deg; shortens a turning step,
        :func:`pdr.phone.step_length.turn_factor`).
    mode
        Motion mode (``walking``, ``stairs_up``, ...).
    placement
        Carriage the heading method used (``pocket``, ``hand``, ``torso``, ``swinging``).
    heading_sigma_deg, pos_sigma_m
        Standard deviations of the heading (deg) and of the horizontal position (m, root of the covariance trace).
    patterns
        The step's gait patterns (seed 004 eqs. 13-19).
    heading_raw_deg
        Heading before the drift elimination (deg).
    gyro_heading_deg
        The gyro's rotation about the vertical since the start, as a heading with an arbitrary origin (deg;
        :mod:`pdr.phone.gyro_yaw`), None without a gyroscope.
    up_time_s
        Device-frame up direction integrated over the same time (s; ``up_time_s . b`` is what a constant gyro bias
        ``b`` added to it), None without a gyroscope.
    gyro_bias_dps
        The attitude filter's stationary gyro bias estimate (deg/s, device frame), None before the first stationary
        period.
    position_fix, landmark_heading
        A site landmark fixed the position at this step / corrected its heading.
    pocket_side
        A trouser-pocket phone's side of the thigh so far, for the heading smoother
        (:meth:`pdr.phone.walking_direction.PocketSide.mean_corr`:
        positive in front, negative behind); None for other carriages, running strides and older records.
    """

    KIND: ClassVar[str] = "step"
    t_s: float
    t_start_s: float
    east_m: float
    north_m: float
    up_m: float
    floor: float
    heading_deg: float
    step_length_m: float
    turn_deg: float
    mode: str
    placement: str | None
    heading_sigma_deg: float
    pos_sigma_m: float
    patterns: list[float]
    heading_raw_deg: float
    gyro_heading_deg: float | None
    up_time_s: list[float] | None
    gyro_bias_dps: list[float] | None
    position_fix: bool
    landmark_heading: bool
    pocket_side: float | None = None


@dataclass(frozen=True)
class FloorChangeEvent(_Event):
    """The floor number changed at ``t_s`` (s) from ``from_floor`` to ``floor``; ``height_assumed``: the floor
    numbers still assume the default floor height (no site gave the building's, none was learnt yet).
    """

    KIND: ClassVar[str] = "floor_change"
    t_s: float
    floor: float
    from_floor: float
    height_assumed: bool = False


@dataclass(frozen=True)
class LandmarkEvent(_Event):
    """A site landmark (id ``landmark``) was matched at ``t_s`` (s, start of its first step) in motion ``mode``."""

    KIND: ClassVar[str] = "landmark"
    t_s: float
    landmark: str
    mode: str


@dataclass(frozen=True)
class ElevatorEvent(_Event):
    """An elevator ride from ``t_start_s`` to ``t_end_s`` (s): direction ``up``/``down``, barometric height change
    (m), the magnetic field's range over the ride (uT, None without magnetometer), the site landmark that fixed
    the position (None: no match; then absent from the row) and the floors the ride crossed (the floors nearest the
    barometric altitudes at its start and end, with the site's floor altitudes or floor height; None without a
    barometer). ``source``: ``barometer`` (a climb stood through and walked out of, :mod:`pdr.phone.baro_rides`: the
    ride from its start to the cabin stopping) or ``impulses`` (the vertical specific force's start and stop
    impulses, without a barometer).
    """

    KIND: ClassVar[str] = "elevator"
    t_start_s: float
    t_end_s: float
    direction: str
    altitude_change_m: float
    mag_change_uT: float | None
    site_landmark: str | None = None
    floors: int | None = None
    source: str = "impulses"

    def to_row(self) -> EventRow:
        row = super().to_row()
        if self.site_landmark is None:
            del row["site_landmark"]
        return row


@dataclass(frozen=True)
class StairFlightEvent(_Event):
    """A flight of stairs walked from ``t_start_s`` to ``t_end_s`` (s): direction ``up``/``down``, the steps on it,
    the barometric height change (m; 0 without a barometer) and the floors it crossed (the change of the floor shown
    from its foot to the step after it: a storey's two half flights count 0 and 1; None without a barometer).
    Emitted with the first step after the flight (:class:`pdr.phone.floors.StairFlights`).
    """

    KIND: ClassVar[str] = "stair_flight"
    t_start_s: float
    t_end_s: float
    direction: str
    steps: int
    altitude_change_m: float
    floors: int | None = None


@dataclass(frozen=True)
class NoticeEvent(_Event):
    """A degraded input or a decision the user should know of (``message``, one sentence)."""

    KIND: ClassVar[str] = "notice"
    message: str


PipelineEvent = StepEvent | FloorChangeEvent | LandmarkEvent | ElevatorEvent | StairFlightEvent | NoticeEvent
_KINDS: dict[str, type[PipelineEvent]] = {c.KIND: c for c in (StepEvent, FloorChangeEvent, LandmarkEvent,
                                                                ElevatorEvent, StairFlightEvent, NoticeEvent)}


def event_from_row(row: EventRow) -> PipelineEvent:
    """The typed event of a row (:meth:`to_row`); an unknown type or missing field is an :class:`InputError`."""
    cls = _KINDS.get(str(row.get("type")))
    if cls is None:
        raise InputError(f"unknown event type {row.get('type')!r}", field="type", source="event")
    names = {f.name for f in fields(cls)}
    try:
        return cls(**{k: v for k, v in row.items() if k in names})
    except TypeError as exc:
        raise InputError(f"bad {cls.KIND} event ({exc})", field="type", source="event") from None


def to_rows(events: list[PipelineEvent]) -> list[EventRow]:
    """The row form of events, in order."""
    return [e.to_row() for e in events]
