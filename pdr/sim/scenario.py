"""Simulation scenarios: a walk composed of segments, the recording device and its sensor errors.

A scenario is JSON (schema: ``pdr/sim/scenario.schema.json``, documented in ``mobile_logs/README.md``).
:func:`parse_scenario` validates it and resolves every segment to a :class:`Segment` with an explicit
duration, speed, step frequency, heading change and height change, so that later stages never look at
defaults again. Bad input raises :class:`~pdr.errors.InputError` naming the JSON path
(``segments[2].speed_mps``).

Segment types: ``stand``; ``walk`` / ``run`` (``duration_s`` or ``distance_m``, ``speed_mps``,
``step_frequency_hz``); ``turn`` (``angle_deg``, positive = left, i.e. counter-clockwise seen from above;
walking through the turn at ``speed_mps``, default the previous walking speed, 0 = stepping on the spot);
``stairs`` (``direction`` up/down, ``floors`` or ``steps``, ``riser_m``, ``tread_m``); ``elevator``
(``direction``, ``floors``; waits at the doors, then an acceleration impulse pair); ``escalator``
(``direction``, ``floors``, ``speed_mps`` along an incline of ``incline_deg``, standing on the step).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np

from pdr.errors import InputError
from pdr.frames import heading_deg_to_yaw
from pdr.sim.sensors import GRADES, ErrorModel

#: Placements the simulator models (values of ``DeviceInfo.placement``).
SIM_PLACEMENTS = ("trouser_pocket", "torso", "hand", "foot")
#: Segment types that involve stepping.
STEPPING_TYPES = ("walk", "run", "turn", "stairs")

DEFAULT_RATES_HZ = {"acc": 100.0, "gyro": 100.0, "mag": 50.0, "baro": 10.0}
DEFAULT_FOOT_RATES_HZ = {"acc": 200.0, "gyro": 200.0, "mag": None, "baro": None}

_NOMINAL_RISER_M = 0.17


@dataclass(frozen=True)
class Segment:
    """One resolved segment of a scenario.

    Attributes
    ----------
    kind
        Segment type (``stand``, ``walk``, ``run``, ``turn``, ``stairs``, ``elevator``, ``escalator``).
    mode
        Motion-mode label (``standing``, ``walking``, ``running``, ``stairs_up``, ``stairs_down``,
        ``elevator_up``, ``elevator_down``, ``escalator_up``, ``escalator_down``).
    duration_s
        Length in s.
    speed_mps
        Horizontal walking speed in m/s (0 when not stepping; the ride of escalators is ``ride_speed_mps``).
    step_frequency_hz
        Steps per second (0 when not stepping).
    turn_rad
        Heading change over the segment in rad, counter-clockwise positive.
    climb_m
        Signed height change over the segment in m (stairs, elevator, escalator).
    ride_speed_mps
        Elevator cruise speed or escalator speed along its incline, m/s.
    ramp_s
        Elevator acceleration (and deceleration) time in s.
    wait_s
        Elevator: standing time in the cabin before departure and after arrival, s.
    incline_rad
        Escalator incline in rad.
    landmark
        Landmark label of the segment (``stairs_up``, ``elevator_down``, ``turn_left``, ...) or ``""``.
    """

    kind: str
    mode: str
    duration_s: float
    speed_mps: float = 0.0
    step_frequency_hz: float = 0.0
    turn_rad: float = 0.0
    climb_m: float = 0.0
    ride_speed_mps: float = 0.0
    ramp_s: float = 0.0
    wait_s: float = 0.0
    incline_rad: float = 0.0
    landmark: str = ""

    @property
    def stepping(self) -> bool:
        return self.kind in STEPPING_TYPES


@dataclass(frozen=True)
class MagneticSpec:
    """Magnetic environment: Earth field and indoor disturbances.

    ``total_ut`` intensity in uT, ``inclination_rad`` (positive: field points down),
    ``declination_rad`` (positive: east of north); random indoor anomalies of standard deviation
    ``indoor_disturbance_ut`` per component, one every ``disturbance_spacing_m`` of path, each of radius
    ``disturbance_radius_m``; inside an elevator cabin the field is scaled by ``elevator_field_scale``
    (the magnitude change at the doors); on an escalator it fluctuates by ``escalator_disturbance_ut``.
    """

    total_ut: float = 50.0
    inclination_rad: float = math.radians(66.0)
    declination_rad: float = math.radians(3.0)
    indoor_disturbance_ut: float = 4.0
    disturbance_spacing_m: float = 2.0
    disturbance_radius_m: float = 0.8
    elevator_field_scale: float = 0.55
    escalator_disturbance_ut: float = 6.0


@dataclass(frozen=True)
class Scenario:
    """A validated scenario; build it with :func:`parse_scenario` or :func:`load_scenario`.

    Positions are ENU metres, ``start_yaw_rad`` is counter-clockwise from east (:mod:`pdr.frames`).
    ``mount_rpy_rad`` is None for the placement's default orientation, ``"random"`` for one drawn from
    the seed, else ZYX roll, pitch, yaw in rad applied after the default. ``rates_hz`` maps stream kinds
    to sampling rates (absent: stream not simulated). ``errors`` maps stream kinds to error models.
    ``document`` is the JSON the scenario came from (kept in the recording's metadata).
    """

    segments: tuple[Segment, ...]
    placement: str = "trouser_pocket"
    side: str = "right"
    mount_rpy_rad: tuple[float, float, float] | str | None = None
    rates_hz: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_RATES_HZ))
    truth_rate_hz: float = 100.0
    start_time_ns: int = 0
    start_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_yaw_rad: float = 0.0
    start_floor: int = 0
    floor_height_m: float = 3.0
    altitude_m: float = 100.0
    sea_level_pressure_hpa: float = 1013.25
    height_m: float = 1.75
    errors: Mapping[str, ErrorModel] = field(default_factory=lambda: dict(GRADES["consumer"]))
    magnetic: MagneticSpec = field(default_factory=MagneticSpec)
    name: str = ""
    document: Mapping[str, Any] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return float(sum(s.duration_s for s in self.segments))

    @property
    def boundaries_s(self) -> np.ndarray:
        """(S + 1,) segment start times and the end time, s."""
        return np.concatenate([[0.0], np.cumsum([s.duration_s for s in self.segments])])


@cache
def scenario_schema() -> dict[str, Any]:
    """The JSON Schema of a scenario document."""
    text = resources.files("pdr.sim").joinpath("scenario.schema.json").read_text(encoding="utf-8")
    return dict(json.loads(text))


def _path(parts: Any) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def _schema_error(obj: Any, source: str) -> None:
    validator = jsonschema.Draft202012Validator(scenario_schema())
    errors = sorted(validator.iter_errors(obj), key=lambda e: (len(list(e.absolute_path)), str(e.message)))
    if not errors:
        return
    err = jsonschema.exceptions.best_match(errors) or errors[0]
    where = _path(err.absolute_path)
    if err.validator == "additionalProperties":
        msg = err.message.replace("Additional properties are not allowed", "unknown field(s)")
    elif err.validator == "enum":
        msg = f"{err.instance!r} is not one of {err.validator_value}"
    elif err.validator == "required":
        msg = err.message.replace("is a required property", "is required")
    else:
        msg = err.message
    raise InputError(msg, source=source, field=where)


def default_step_frequency_hz(speed_mps: float, kind: str) -> float:
    """Typical step frequency for a speed: ``1.8 sqrt(v / 1.3)`` walking, ``2.7 (v / 3)^0.3`` running."""
    if kind == "run":
        return float(np.clip(2.7 * (speed_mps / 3.0) ** 0.3, 2.2, 3.6))
    if speed_mps <= 0.0:
        return 1.6
    return float(np.clip(1.8 * math.sqrt(speed_mps / 1.3), 1.2, 2.3))


def _segment(d: Mapping[str, Any], i: int, floor_height: float, last_speed: float, source: str) -> Segment:
    kind = d["type"]
    where = f"segments[{i}]"

    def bad(msg: str, name: str | None = None) -> InputError:
        return InputError(msg, source=source, field=f"{where}.{name}" if name else where)

    if kind == "stand":
        return Segment("stand", "standing", float(d["duration_s"]))
    if kind in ("walk", "run"):
        speed = float(d.get("speed_mps", 1.3 if kind == "walk" else 3.0))
        if ("duration_s" in d) == ("distance_m" in d):
            raise bad("give exactly one of duration_s and distance_m")
        duration = float(d["duration_s"]) if "duration_s" in d else float(d["distance_m"]) / speed
        freq = float(d.get("step_frequency_hz", default_step_frequency_hz(speed, kind)))
        return Segment(kind, "walking" if kind == "walk" else "running", duration, speed, freq)
    if kind == "turn":
        angle = math.radians(float(d["angle_deg"]))
        if angle == 0.0:
            raise bad("a turn needs a non-zero angle", "angle_deg")
        duration = float(d.get("duration_s", max(1.0, 2.0 * abs(angle) / (math.pi / 2))))
        speed = float(d.get("speed_mps", last_speed))
        freq = float(d.get("step_frequency_hz", default_step_frequency_hz(speed, "walk")))
        return Segment("turn", "walking", duration, speed, freq, turn_rad=angle,
                       landmark="turn_left" if angle > 0 else "turn_right")
    sign = 1.0 if d["direction"] == "up" else -1.0
    if kind == "stairs":
        if "floors" in d and "steps" in d and "riser_m" in d:
            raise bad("give at most two of floors, steps and riser_m")
        riser = float(d.get("riser_m", _NOMINAL_RISER_M))
        if "steps" in d and "floors" not in d:
            steps = int(d["steps"])
            climb = steps * riser
        else:
            climb = float(d.get("floors", 1)) * floor_height
            steps = int(d["steps"]) if "steps" in d else max(2, round(climb / riser))
        n = int(steps)
        freq = float(d.get("step_frequency_hz", 1.6 if sign > 0 else 1.8))
        tread = float(d.get("tread_m", 0.29))
        return Segment("stairs", f"stairs_{d['direction']}", n / freq, tread * freq, freq,
                       climb_m=sign * climb, landmark=f"stairs_{d['direction']}")
    floors = int(d.get("floors", 1))
    climb = floors * floor_height
    if kind == "elevator":
        speed = float(d.get("speed_mps", 1.0))
        ramp = float(d.get("ramp_s", 2.0))
        wait = float(d.get("wait_s", 3.0))
        speed = min(speed, climb / ramp)  # the acceleration pulses must not overlap
        need = 2.0 * wait + ramp + climb / speed
        duration = float(d.get("duration_s", need))
        if duration < need - 1e-9:
            raise bad(f"too short: {floors} floor(s) at {speed} m/s with {ramp} s ramps and {wait} s waits "
                      f"take at least {need:.2f} s", "duration_s")
        return Segment("elevator", f"elevator_{d['direction']}", duration, climb_m=sign * climb,
                       ride_speed_mps=speed, ramp_s=ramp, wait_s=wait + 0.5 * (duration - need),
                       landmark=f"elevator_{d['direction']}")
    speed = float(d.get("speed_mps", 0.5))
    incline = math.radians(float(d.get("incline_deg", 30.0)))
    duration = climb / (speed * math.sin(incline))
    return Segment("escalator", f"escalator_{d['direction']}", duration, climb_m=sign * climb,
                   ride_speed_mps=speed, incline_rad=incline, landmark=f"escalator_{d['direction']}")


def _check_bouts(segments: list[Segment], source: str) -> None:
    """Every run of consecutive stepping segments must contain at least one step."""
    i = 0
    while i < len(segments):
        if not segments[i].stepping:
            i += 1
            continue
        j = i
        phase = 0.0
        while j < len(segments) and segments[j].stepping:
            phase += segments[j].duration_s * segments[j].step_frequency_hz
            j += 1
        if phase < 1.0:
            raise InputError(f"segments {i}..{j - 1} walk for {phase:.2f} steps only; a walking bout needs at "
                             "least one step (make it longer)", source=source, field=f"segments[{i}]")
        i = j


def parse_scenario(obj: Any, source: str = "scenario") -> Scenario:
    """Validate a scenario document (a parsed JSON object) and resolve its segments."""
    if not isinstance(obj, Mapping):
        raise InputError(f"a scenario must be a JSON object, got {type(obj).__name__}", source=source)
    _schema_error(obj, source)
    placement = obj.get("placement", "trouser_pocket")
    building = obj.get("building", {})
    floor_height = float(building.get("floor_height_m", 3.0))
    segments: list[Segment] = []
    last_speed = 1.3
    for i, d in enumerate(obj["segments"]):
        seg = _segment(d, i, floor_height, last_speed, source)
        if seg.kind in ("walk", "run", "turn") and seg.speed_mps > 0:
            last_speed = seg.speed_mps
        segments.append(seg)
    _check_bouts(segments, source)
    total = sum(s.duration_s for s in segments)
    if total > 7200.0:
        raise InputError(f"scenario lasts {total:.0f} s; at most 7200 s can be simulated at once",
                         source=source, field="segments")

    defaults = DEFAULT_FOOT_RATES_HZ if placement == "foot" else DEFAULT_RATES_HZ
    rates_in = {**defaults, **obj.get("rates_hz", {})}
    rates = {k: float(v) for k, v in rates_in.items() if v is not None}
    for k in ("acc", "gyro"):
        if k not in rates:
            raise InputError("the accelerometer and gyroscope cannot be left out", source=source,
                             field=f"rates_hz.{k}")

    sensors = obj.get("sensors", {})
    grade = GRADES[sensors.get("grade", "consumer")]
    errors = {k: grade[k].with_overrides(dict(sensors.get(k, {})), source=f"{source}: sensors.{k}")
              for k in ("acc", "gyro", "mag", "baro")}

    mag_in = obj.get("magnetic", {})
    mag_defaults = MagneticSpec()
    magnetic = MagneticSpec(
        total_ut=float(mag_in.get("total_ut", mag_defaults.total_ut)),
        inclination_rad=math.radians(mag_in["inclination_deg"]) if "inclination_deg" in mag_in
        else mag_defaults.inclination_rad,
        declination_rad=math.radians(mag_in["declination_deg"]) if "declination_deg" in mag_in
        else mag_defaults.declination_rad,
        indoor_disturbance_ut=float(mag_in.get("indoor_disturbance_ut", mag_defaults.indoor_disturbance_ut)),
        disturbance_spacing_m=float(mag_in.get("disturbance_spacing_m", mag_defaults.disturbance_spacing_m)),
        disturbance_radius_m=float(mag_in.get("disturbance_radius_m", mag_defaults.disturbance_radius_m)),
        elevator_field_scale=float(mag_in.get("elevator_field_scale", mag_defaults.elevator_field_scale)),
        escalator_disturbance_ut=float(mag_in.get("escalator_disturbance_ut",
                                                  mag_defaults.escalator_disturbance_ut)),
    )

    mount = obj.get("mount_rpy_deg")
    mount_rad: tuple[float, float, float] | str | None
    if mount is None or mount == "random":
        mount_rad = mount
    else:
        r, p, y = (math.radians(float(a)) for a in mount)
        mount_rad = (r, p, y)
    start = obj.get("start", {})
    pos = start.get("position_m", [0.0, 0.0, 0.0])
    return Scenario(
        segments=tuple(segments),
        placement=placement,
        side=obj.get("side", "right"),
        mount_rpy_rad=mount_rad,
        rates_hz=rates,
        truth_rate_hz=float(obj.get("truth_rate_hz", 100.0)),
        start_time_ns=int(obj.get("start_time_ns", 0)),
        start_position_m=(float(pos[0]), float(pos[1]), float(pos[2])),
        start_yaw_rad=float(heading_deg_to_yaw(start.get("heading_deg", 90.0))),
        start_floor=int(start.get("floor", 0)),
        floor_height_m=floor_height,
        altitude_m=float(building.get("altitude_m", 100.0)),
        sea_level_pressure_hpa=float(building.get("sea_level_pressure_hpa", 1013.25)),
        height_m=float(obj.get("person", {}).get("height_m", 1.75)),
        errors=errors,
        magnetic=magnetic,
        name=str(obj.get("name", "")),
        document=json.loads(json.dumps(obj)),
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario JSON file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read scenario ({exc})", source=str(p)) from None
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg} (column {exc.colno})", source=str(p), line=exc.lineno) from None
    return parse_scenario(obj, source=str(p))
