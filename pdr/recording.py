"""The sensor data model: validated, read-only containers for a recording or a batch of it.

A :class:`Recording` holds one device's sensor streams, each with its own timestamps, plus device
metadata and any ground truth. Arrays are float64 (values) and int64 (raw nanosecond timestamps),
one row per sample, made read-only at construction. Units and frames follow :mod:`pdr.frames`:
every stream kind has one fixed SI unit and layout, listed in :data:`STREAM_KINDS`.

Time: ``t_ns`` are the raw int64 nanoseconds of the log's clock (epoch or since boot; whatever
the source wrote). Inside, time is float64 seconds ``t_s = (t_ns - t0_ns) / 1e9`` relative to the
recording's origin ``t0_ns``; the log's own clock in seconds is ``t0_ns / 1e9 + t_s``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class StreamKind:
    """Layout of one kind of sensor stream."""

    name: str
    columns: tuple[str, ...]
    unit: str
    description: str
    sensor: str         # the sensor's name in messages to the user ("gyroscope")


_XYZ = ("x", "y", "z")

#: Every stream kind the data model accepts, with its column layout and SI unit (body frame unless noted).
STREAM_KINDS: Mapping[str, StreamKind] = MappingProxyType({
    k.name: k
    for k in (
        StreamKind("acc", _XYZ, "m/s^2", "specific force including gravity, body frame", "accelerometer"),
        StreamKind("gyro", _XYZ, "rad/s", "angular rate, body frame", "gyroscope"),
        StreamKind("mag", _XYZ, "uT", "magnetic field, body frame", "magnetometer"),
        StreamKind("baro", ("p",), "hPa", "static air pressure", "barometer"),
        StreamKind("gravity", _XYZ, "m/s^2", "gravity estimate of the platform, body frame (points up at rest)",
                   "gravity sensor"),
        StreamKind("lin_acc", _XYZ, "m/s^2", "linear acceleration (acc minus gravity), body frame",
                   "linear acceleration sensor"),
        StreamKind("orientation", ("w", "x", "y", "z"), "1",
                   "platform attitude q_nb (Hamilton, scalar first), body to ENU navigation frame", "orientation"),
        StreamKind("acc_uncal", _XYZ, "m/s^2", "uncalibrated specific force, body frame", "uncalibrated accelerometer"),
        StreamKind("gyro_uncal", _XYZ, "rad/s", "uncalibrated angular rate, body frame", "uncalibrated gyroscope"),
        StreamKind("mag_uncal", _XYZ, "uT", "uncalibrated magnetic field, body frame", "uncalibrated magnetometer"),
        StreamKind("temperature", ("t",), "degC", "sensor temperature", "temperature sensor"),
    )
})

#: Key of :attr:`Recording.meta` holding a location fix that geo-references the recording (a phone's GNSS fix:
#: ``{"lat_deg", "lon_deg", "t_ns", ...}``, WGS-84 degrees), as the Sensor Logger reader writes it.
LOCATION_META = "location"


DeviceRole = Literal["phone", "left_foot", "right_foot"]
DEVICE_ROLES: tuple[str, ...] = ("phone", "left_foot", "right_foot")
#: Roles of shoe IMUs: their recordings go to foot-mounted navigation (:mod:`pdr.foot`), not to phone PDR.
FOOT_ROLES: tuple[str, ...] = ("left_foot", "right_foot")

#: Known carriage placements; ``None`` on a :class:`DeviceInfo` means unknown.
PLACEMENTS: tuple[str, ...] = (
    "trouser_pocket_front", "trouser_pocket_back", "trouser_pocket", "hand", "bag", "torso", "neck",
    "armband", "foot", "vehicle_mount",
)
PLATFORMS: tuple[str, ...] = ("android", "ios", "imu", "unknown")


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _as_float(values: Any, name: str, ndim: int) -> FloatArray:
    try:
        arr = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"values are not numeric ({exc})", source=name) from None
    if arr.ndim != ndim:
        raise InputError(f"expected a {ndim}-D array, got shape {arr.shape}", source=name)
    return arr


def _check_finite(arr: FloatArray, name: str) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise InputError(f"sample {row} is not finite ({arr[row].tolist()})", source=name)


def _check_increasing(t: np.ndarray, name: str) -> None:
    if t.size > 1:
        dt = np.diff(t)
        bad = np.flatnonzero(dt <= 0)
        if bad.size:
            i = int(bad[0]) + 1
            what = "duplicates" if dt[i - 1] == 0 else "goes back from"
            raise InputError(
                f"timestamp of sample {i} ({t[i]}) {what} sample {i - 1} ({t[i - 1]}); "
                "timestamps must be strictly increasing", source=name)


@dataclass(frozen=True)
class SensorStream:
    """One sensor's samples.

    Parameters
    ----------
    kind
        A key of :data:`STREAM_KINDS` (``acc``, ``gyro``, ``mag``, ``baro``, ...).
    t_ns
        (N,) int64 raw timestamps in nanoseconds, strictly increasing.
    values
        (N, k) float64 samples in the kind's SI unit and layout; all finite.
    """

    kind: str
    t_ns: IntArray
    values: FloatArray

    def __post_init__(self) -> None:
        spec = STREAM_KINDS.get(self.kind)
        if spec is None:
            raise InputError(f"unknown stream kind; expected one of {sorted(STREAM_KINDS)}",
                             source=str(self.kind))
        name = f"stream '{self.kind}'"
        try:
            t = np.array(self.t_ns)
        except (TypeError, ValueError) as exc:
            raise InputError(f"timestamps are not integers ({exc})", source=name) from None
        if t.ndim != 1:
            raise InputError(f"timestamps must be a 1-D array, got shape {t.shape}", source=name)
        if t.dtype.kind == "f":
            if not np.all(np.isfinite(t)):
                raise InputError(f"timestamp of sample {int(np.argmax(~np.isfinite(t)))} is not finite",
                                 source=name)
            t = np.round(t)
        if t.dtype.kind not in "iuf":
            raise InputError(f"timestamps must be integer nanoseconds, got dtype {t.dtype}", source=name)
        t = t.astype(np.int64)
        single_column_1d = len(spec.columns) == 1 and np.ndim(self.values) == 1
        v = _as_float(self.values, name, 1)[:, None] if single_column_1d else _as_float(self.values, name, 2)
        if v.shape != (t.size, len(spec.columns)):
            raise InputError(
                f"values must have shape ({t.size}, {len(spec.columns)}) for columns {spec.columns}, "
                f"got {v.shape}", source=name)
        _check_finite(v, name)
        _check_increasing(t, name)
        object.__setattr__(self, "t_ns", _readonly(t))
        object.__setattr__(self, "values", _readonly(v))

    def __len__(self) -> int:
        return int(self.t_ns.size)

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, SensorStream) and self.kind == other.kind
                and np.array_equal(self.t_ns, other.t_ns) and np.array_equal(self.values, other.values))

    __hash__ = None  # type: ignore[assignment]

    @property
    def spec(self) -> StreamKind:
        return STREAM_KINDS[self.kind]

    def t_s(self, t0_ns: int) -> FloatArray:
        """(N,) float64 seconds relative to ``t0_ns``."""
        return (self.t_ns - np.int64(t0_ns)).astype(np.float64) / 1e9

    def median_rate_hz(self) -> float:
        """Median sampling rate in Hz (NaN with fewer than two samples)."""
        if self.t_ns.size < 2:
            return float("nan")
        return float(1e9 / np.median(np.diff(self.t_ns)))

    def select(self, mask: NDArray[np.bool_]) -> SensorStream:
        """The samples where ``mask`` is true."""
        return SensorStream(self.kind, self.t_ns[mask], self.values[mask])


@dataclass(frozen=True)
class DeviceInfo:
    """Who recorded: platform (android/ios/imu/unknown), model, role on the body and placement if known."""

    platform: str = "unknown"
    model: str = ""
    role: str = "phone"
    placement: str | None = None
    device_id: str = ""

    def __post_init__(self) -> None:
        if self.platform not in PLATFORMS:
            raise InputError(f"unknown platform; expected one of {PLATFORMS}", field="platform",
                             source=str(self.platform))
        if self.role not in DEVICE_ROLES:
            raise InputError(f"unknown device role; expected one of {DEVICE_ROLES}", field="role",
                             source=str(self.role))
        if self.placement is not None and self.placement not in PLACEMENTS:
            raise InputError(f"unknown placement; expected one of {PLACEMENTS} or none", field="placement",
                             source=str(self.placement))

    @property
    def is_foot(self) -> bool:
        """A shoe IMU: a foot role, or a device placed on the foot whatever its role."""
        return self.role in FOOT_ROLES or self.placement == "foot"


def _checked_times(t: Any, name: str, strictly: bool = False) -> FloatArray:
    arr = _as_float(t, name, 1)
    _check_finite(arr[:, None], name)
    if strictly:
        _check_increasing(arr, name)
    elif arr.size > 1 and np.any(np.diff(arr) < 0):
        i = int(np.flatnonzero(np.diff(arr) < 0)[0]) + 1
        raise InputError(f"time of entry {i} ({arr[i]}) goes back from entry {i - 1}", source=name)
    return _readonly(arr)


@dataclass(frozen=True)
class PositionTruth:
    """Reference positions at known times, in a local metric frame.

    Parameters
    ----------
    t_s
        (K,) float64 seconds on the recording's time axis, non-decreasing.
    pos_m
        (K, 3) float64 positions in metres: east, north, up of a local ENU frame (or the map frame
        named by ``frame``); up is 0 where unknown.
    floor
        (K,) float64 floor numbers, NaN where unknown.
    kind
        ``landmark`` (surveyed points passed), ``waypoint``, ``stride`` (per-stride footprints)
        or ``dense`` (e.g. VICON at every sample).
    frame
        ``enu`` (north-aligned) or ``map`` (a floor-plan frame that is not north-aligned).
    origin_lat_lon_deg
        Geodetic origin of the local ENU frame, when the source gave latitude/longitude.
    """

    t_s: FloatArray
    pos_m: FloatArray
    floor: FloatArray | None = None
    kind: str = "landmark"
    frame: str = "enu"
    origin_lat_lon_deg: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        t = _checked_times(self.t_s, "truth positions t_s")
        p = _as_float(self.pos_m, "truth positions pos_m", 2)
        if p.shape != (t.size, 3):
            raise InputError(f"pos_m must have shape ({t.size}, 3), got {p.shape}", source="truth positions")
        _check_finite(p, "truth positions pos_m")
        f = np.full(t.size, np.nan) if self.floor is None else _as_float(self.floor, "truth floor", 1)
        if f.shape != t.shape:
            raise InputError(f"floor must have shape ({t.size},), got {f.shape}", source="truth positions")
        if self.kind not in ("landmark", "waypoint", "stride", "dense"):
            raise InputError("kind must be landmark, waypoint, stride or dense", source="truth positions")
        if self.frame not in ("enu", "map"):
            raise InputError("frame must be enu or map", source="truth positions")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "pos_m", _readonly(p))
        object.__setattr__(self, "floor", _readonly(f))

    def __len__(self) -> int:
        return int(self.t_s.size)


@dataclass(frozen=True)
class Labels:
    """Labelled time intervals (motion modes, landmarks, activities).

    ``label[i]`` holds on ``[t_start_s[i], t_end_s[i])`` seconds of the recording's time axis.
    """

    t_start_s: FloatArray
    t_end_s: FloatArray
    label: tuple[str, ...]

    def __post_init__(self) -> None:
        a = _checked_times(self.t_start_s, "labels t_start_s")
        b = _as_float(self.t_end_s, "labels t_end_s", 1)
        _check_finite(b[:, None], "labels t_end_s")
        labels = tuple(str(x) for x in self.label)
        if not (a.size == b.size == len(labels)):
            raise InputError(f"t_start_s, t_end_s and label differ in length ({a.size}, {b.size}, "
                             f"{len(labels)})", source="labels")
        if np.any(b < a):
            i = int(np.flatnonzero(b < a)[0])
            raise InputError(f"interval {i} ends ({b[i]}) before it starts ({a[i]})", source="labels")
        object.__setattr__(self, "t_start_s", a)
        object.__setattr__(self, "t_end_s", _readonly(b))
        object.__setattr__(self, "label", labels)

    def __len__(self) -> int:
        return len(self.label)

    def at(self, t_s: FloatArray, default: str = "") -> NDArray[np.object_]:
        """Label in force at each time (``default`` outside every interval); later intervals win."""
        t = np.asarray(t_s, dtype=np.float64)
        out = np.full(t.shape, default, dtype=object)
        for a, b, name in zip(self.t_start_s, self.t_end_s, self.label, strict=True):
            out[(t >= a) & (t < b)] = name
        return out


@dataclass(frozen=True)
class GroundTruth:
    """Whatever reference the source carries; every field is optional.

    ``positions``: sparse or dense reference positions. ``step_times_s``: (M,) times of true steps
    (foot contacts). ``step_count``: number of true steps when only a count is known.
    ``step_lengths_m``: (M,) true step lengths, aligned with ``step_times_s``. ``modes``: motion mode
    intervals. ``landmarks``: landmark intervals (stairs, elevator, escalator, turns). ``extra``:
    named arrays for anything else (e.g. ``zero_velocity`` flags with ``zero_velocity_t_s``,
    simulator attitude ``q_nb`` with ``trajectory_t_s``), each documented by the reader that sets it.
    """

    positions: PositionTruth | None = None
    step_times_s: FloatArray | None = None
    step_count: int | None = None
    step_lengths_m: FloatArray | None = None
    modes: Labels | None = None
    landmarks: Labels | None = None
    extra: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.step_times_s is not None:
            st = _checked_times(self.step_times_s, "truth step_times_s")
            object.__setattr__(self, "step_times_s", st)
            if self.step_count is None:
                object.__setattr__(self, "step_count", int(st.size))
        if self.step_lengths_m is not None:
            sl = _as_float(self.step_lengths_m, "truth step_lengths_m", 1)
            if self.step_times_s is None or sl.shape != self.step_times_s.shape:
                raise InputError("step_lengths_m needs step_times_s of the same length", source="truth")
            object.__setattr__(self, "step_lengths_m", _readonly(sl))
        if self.step_count is not None and int(self.step_count) < 0:
            raise InputError("step_count must be non-negative", source="truth")
        extra = {}
        for k, v in dict(self.extra).items():
            extra[str(k)] = _readonly(np.array(v))
        object.__setattr__(self, "extra", MappingProxyType(extra))

    def is_empty(self) -> bool:
        return (self.positions is None and self.step_times_s is None and self.step_count is None
                and self.modes is None and self.landmarks is None and not self.extra)

    def kinds(self) -> list[str]:
        """Names of the kinds of truth present (for summaries)."""
        names = [n for n in ("positions", "step_times_s", "step_lengths_m", "modes", "landmarks")
                 if getattr(self, n) is not None]
        if self.step_count is not None and self.step_times_s is None:
            names.append("step_count")
        return names + sorted(self.extra)


@dataclass(frozen=True)
class Recording:
    """One device's sensor streams over a span of time, with metadata and optional ground truth.

    Parameters
    ----------
    streams
        Stream kind -> :class:`SensorStream`; at least one stream.
    device
        The recording device.
    t0_ns
        Origin of the float time axis ``t_s`` (int nanoseconds on the log's clock). Defaults to the
        earliest first timestamp of any stream.
    truth
        Ground truth carried by the source, on the same ``t_s`` axis.
    source
        Where it came from (path or session), for messages.
    format
        Name of the reader that produced it.
    warnings
        Problems found and repaired while reading (unit conversions, dropped samples, ...).
    meta
        Free-form metadata from the source (JSON-serialisable values).
    """

    streams: Mapping[str, SensorStream]
    device: DeviceInfo = field(default_factory=DeviceInfo)
    t0_ns: int | None = None
    truth: GroundTruth = field(default_factory=GroundTruth)
    source: str = ""
    format: str = ""
    warnings: tuple[str, ...] = ()
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        streams = dict(self.streams)
        if not streams:
            raise InputError("a recording needs at least one sensor stream", source=self.source or None)
        for key, s in streams.items():
            if not isinstance(s, SensorStream):
                raise InputError("not a SensorStream", source=f"stream '{key}'")
            if key != s.kind:
                raise InputError(f"stored under '{key}' but its kind is '{s.kind}'", source=f"stream '{key}'")
        order = [k for k in STREAM_KINDS if k in streams]
        object.__setattr__(self, "streams", MappingProxyType({k: streams[k] for k in order}))
        if self.t0_ns is None:
            firsts = [int(s.t_ns[0]) for s in streams.values() if len(s)]
            object.__setattr__(self, "t0_ns", min(firsts) if firsts else 0)
        elif isinstance(self.t0_ns, bool) or not isinstance(self.t0_ns, int | np.integer):
            raise InputError(f"t0_ns must be an integer number of nanoseconds, got {self.t0_ns!r}",
                             source=self.source or None, field="t0_ns")
        elif not -(2**63) <= int(self.t0_ns) < 2**63:  # the time axis subtracts it from int64 timestamps
            raise InputError(f"t0_ns {self.t0_ns} is outside the int64 nanosecond range",
                             source=self.source or None, field="t0_ns")
        else:
            object.__setattr__(self, "t0_ns", int(self.t0_ns))
        object.__setattr__(self, "warnings", tuple(self.warnings))
        object.__setattr__(self, "meta", MappingProxyType(dict(self.meta)))

    @property
    def origin_ns(self) -> int:
        """``t0_ns`` as a plain int (never None after construction)."""
        assert self.t0_ns is not None  # set in __post_init__
        return self.t0_ns

    def has(self, kind: str) -> bool:
        return kind in self.streams and len(self.streams[kind]) > 0

    def stream(self, kind: str) -> SensorStream:
        """The stream of this kind; :class:`InputError` naming what is available if absent."""
        if kind not in self.streams:
            raise InputError(f"recording has no '{kind}' stream (it has {sorted(self.streams)})",
                             source=self.source or None)
        return self.streams[kind]

    def t_s(self, kind: str) -> FloatArray:
        """(N,) float64 seconds of stream ``kind`` on the recording's time axis."""
        return self.stream(kind).t_s(self.origin_ns)

    def values(self, kind: str) -> FloatArray:
        """(N, k) float64 samples of stream ``kind`` in its SI unit."""
        return self.stream(kind).values

    def time_span_s(self) -> tuple[float, float]:
        """(start, end) seconds covered by any stream."""
        starts = [s.t_s(self.origin_ns)[0] for s in self.streams.values() if len(s)]
        ends = [s.t_s(self.origin_ns)[-1] for s in self.streams.values() if len(s)]
        if not starts:
            return (0.0, 0.0)
        return (float(min(starts)), float(max(ends)))

    @property
    def duration_s(self) -> float:
        a, b = self.time_span_s()
        return b - a

    def slice_time(self, start_s: float, end_s: float) -> Recording:
        """Samples with ``start_s <= t_s < end_s`` of every stream (truth and t0 unchanged)."""
        out = {}
        for k, s in self.streams.items():
            t = s.t_s(self.origin_ns)
            sel = s.select((t >= start_s) & (t < end_s))
            if len(sel):
                out[k] = sel
        if not out:
            raise InputError(f"no samples between {start_s} s and {end_s} s", source=self.source or None)
        return replace(self, streams=out)

    def with_streams(self, streams: Mapping[str, SensorStream], warnings: tuple[str, ...] = ()) -> Recording:
        """A copy with the given streams replaced or added, and extra warnings appended."""
        merged = dict(self.streams)
        merged.update(streams)
        return replace(self, streams=merged, warnings=self.warnings + tuple(warnings))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Recording):
            return NotImplemented
        return (dict(self.streams) == dict(other.streams) and self.device == other.device
                and self.t0_ns == other.t0_ns and truth_equal(self.truth, other.truth))

    __hash__ = None  # type: ignore[assignment]


def _arr_eq(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=np.asarray(a).dtype.kind == "f"))


def truth_equal(a: GroundTruth, b: GroundTruth) -> bool:
    """Element-wise equality of two ground truths (NaN equals NaN)."""
    if (a.positions is None) != (b.positions is None) or (a.modes is None) != (b.modes is None):
        return False
    if (a.landmarks is None) != (b.landmarks is None):
        return False
    if a.positions is not None and b.positions is not None:
        pa, pb = a.positions, b.positions
        if not (_arr_eq(pa.t_s, pb.t_s) and _arr_eq(pa.pos_m, pb.pos_m) and _arr_eq(pa.floor, pb.floor)
                and pa.kind == pb.kind and pa.frame == pb.frame and pa.origin_lat_lon_deg == pb.origin_lat_lon_deg):
            return False
    for la, lb in ((a.modes, b.modes), (a.landmarks, b.landmarks)):
        if la is not None and lb is not None and not (
                _arr_eq(la.t_start_s, lb.t_start_s) and _arr_eq(la.t_end_s, lb.t_end_s) and la.label == lb.label):
            return False
    if set(a.extra) != set(b.extra) or not all(_arr_eq(a.extra[k], b.extra[k]) for k in a.extra):
        return False
    return (_arr_eq(a.step_times_s, b.step_times_s) and _arr_eq(a.step_lengths_m, b.step_lengths_m)
            and a.step_count == b.step_count)


def geo_origin(recording: Recording) -> tuple[float, float] | None:
    """(lat, lon) in WGS-84 degrees where a recording's local east/north frame starts: its truth's geodetic origin,
    else its location fix (:data:`LOCATION_META`), else None (the recording is not geo-referenced).
    """
    pos = recording.truth.positions
    if pos is not None and pos.origin_lat_lon_deg:
        return float(pos.origin_lat_lon_deg[0]), float(pos.origin_lat_lon_deg[1])
    fix = recording.meta.get(LOCATION_META)
    if isinstance(fix, Mapping) and fix.get("lat_deg") is not None and fix.get("lon_deg") is not None:
        return float(fix["lat_deg"]), float(fix["lon_deg"])
    return None
