"""Detection of unit mistakes in formats whose units are ambiguous.

Some log formats do not say in which unit a sensor was written (an IMU CSV may hold g or m/s^2,
deg/s or rad/s, Gauss or uT). The physics of a person carrying a sensor on Earth pins most of them
down from the data alone:

acceleration
    The median norm of specific force including gravity is close to 1 g whatever the motion
    (walking, running, at rest): ~9.8 in m/s^2, ~1 in g, ~1000 in mg.
magnetic field
    The geomagnetic field is 25-65 uT (0.25-0.65 G, 25 000-65 000 nT); indoor disturbances and
    uncalibrated hard-iron offsets move it by a few times, never by the factor 100 between uT and G.
pressure
    Air pressure where people live is 300-1100 hPa (30-110 kPa, 30 000-110 000 Pa).
angular rate
    The hard case: a static gyro reads noise and bias in either unit. Two pieces of evidence are used,
    conservatively. (1) Magnitude: no human motion turns a body segment faster than ~45 rad/s
    (2600 deg/s), so a 99th-percentile rate above that means deg/s. (2) Consistency with the
    accelerometer: the direction ``u`` of low-passed specific force turns with the sensor,
    ``du/dt = -omega x u`` (omega in rad/s, body frame), so the ratio of ``|du/dt|`` to ``|omega x u|``
    is about 1 for rad/s and pi/180 for deg/s. Linear acceleration scatters it (0.6-1.8 on the rad/s
    gyros of the shared phone and foot datasets), but the two units are a factor 57 apart. The ratio
    needs only the accelerometer's direction, so it works whatever the accelerometer's unit.
    Without enough tilting motion and without an impossible magnitude, the unit is undecided.

:func:`check_units` applies these checks to the streams of a :class:`~pdr.recording.Recording`
that a reader stored in the project's SI units (:data:`~pdr.recording.STREAM_KINDS`) without being
sure of the source unit: clear mistakes are converted with a warning, undecidable streams raise
:class:`~pdr.errors.InputError` unless the caller names a fallback unit.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2
from pdr.recording import Recording, SensorStream

FloatArray = NDArray[np.float64]

#: Factor that converts each accepted unit to the SI unit of its quantity.
ACC_UNITS: Mapping[str, float] = {"m/s^2": 1.0, "g": GRAVITY_MPS2, "mg": GRAVITY_MPS2 * 1e-3}
GYRO_UNITS: Mapping[str, float] = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
MAG_UNITS: Mapping[str, float] = {"uT": 1.0, "G": 100.0, "nT": 1e-3}
PRESSURE_UNITS: Mapping[str, float] = {"hPa": 1.0, "kPa": 10.0, "Pa": 0.01}

#: Median norm of specific force (incl. gravity) accepted for each acceleration unit.
_ACC_MEDIAN_NORM = {"m/s^2": (6.0, 16.0), "g": (0.6, 1.6), "mg": (600.0, 1600.0)}
#: Median norm of the magnetic field accepted for each unit (earth field 25-65 uT, times 0.2-40 for
#: indoor disturbances and uncalibrated hard-iron offsets).
_MAG_MEDIAN_NORM = {"uT": (8.0, 2500.0), "G": (0.08, 25.0), "nT": (8e3, 2.5e6)}
#: Air pressure where people walk, hPa: about 1080 at the Dead Sea shore (-430 m) in a winter high, the highest
#: recorded at sea level 1084; about 330 on the summit of Everest (8849 m). A barometer reading outside is no air
#: pressure on Earth (a sensor's error value, 0 before its first reading, or another unit).
AIR_PRESSURE_HPA = (300.0, 1100.0)
#: Median pressure accepted for each unit (:data:`AIR_PRESSURE_HPA`, in each unit).
_PRESSURE_MEDIAN = {unit: (AIR_PRESSURE_HPA[0] / factor, AIR_PRESSURE_HPA[1] / factor)
                    for unit, factor in PRESSURE_UNITS.items()}
#: 99th-percentile angular rate above which the data cannot be rad/s (no body segment turns faster).
MAX_HUMAN_RATE_RADPS = 45.0
#: Accept a tilt-rate ratio within this factor of 1 (rad/s) or of pi/180 (deg/s); they are 57 apart.
_RATIO_TOLERANCE = 4.0
#: Minimum median tilt rate (rad/s) of the selected samples for the accelerometer cross-check.
_MIN_TILT_RATE_RADPS = 0.15
#: Smoothing window of the cross-check (s): removes step-frequency linear acceleration.
_CROSSCHECK_WINDOW_S = 0.5

_FAMILIES: Mapping[str, str] = {
    "acc": "acc", "acc_uncal": "acc", "gravity": "acc",
    "gyro": "gyro", "gyro_uncal": "gyro",
    "mag": "mag", "mag_uncal": "mag",
    "baro": "pressure",
}
_UNITS_OF: Mapping[str, Mapping[str, float]] = {
    "acc": ACC_UNITS, "gyro": GYRO_UNITS, "mag": MAG_UNITS, "pressure": PRESSURE_UNITS}

#: Stream kinds :func:`check_units` can check.
CHECKABLE_KINDS: tuple[str, ...] = tuple(_FAMILIES)


def _rows(values: ArrayLike, ncol: int | None, what: str) -> FloatArray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 1 and ncol in (None, 1):
        v = v[:, None]
    if v.ndim != 2 or (ncol is not None and v.shape[1] != ncol) or v.shape[0] == 0:
        raise InputError(f"expected a non-empty (N, {ncol or 'k'}) array, got shape {v.shape}", source=what)
    return v


def _row_norms(v: FloatArray) -> FloatArray:
    """Euclidean norm of each row of ``v`` (N, k), finite for any finite values (``hypot``: the squares of values
    beyond 1e154 would overflow).
    """
    return np.asarray(np.hypot.reduce(v, axis=1), dtype=np.float64)


def _by_range(stat: float, ranges: Mapping[str, tuple[float, float]]) -> str | None:
    hits = [u for u, (lo, hi) in ranges.items() if lo <= stat <= hi]
    return hits[0] if len(hits) == 1 else None


def detect_acc_unit(values: ArrayLike) -> str | None:
    """Unit of specific force including gravity: ``"m/s^2"``, ``"g"``, ``"mg"`` or None if unclear.

    Parameters
    ----------
    values
        (N, 3) accelerometer samples in an unknown unit (gravity included).
    """
    v = _rows(values, 3, "accelerometer")
    return _by_range(float(np.median(_row_norms(v))), _ACC_MEDIAN_NORM)


def detect_mag_unit(values: ArrayLike) -> str | None:
    """Unit of a magnetometer: ``"uT"``, ``"G"``, ``"nT"`` or None if unclear (mT is not told from G).

    Parameters
    ----------
    values
        (N, 3) magnetic field samples in an unknown unit.
    """
    v = _rows(values, 3, "magnetometer")
    return _by_range(float(np.median(_row_norms(v))), _MAG_MEDIAN_NORM)


def detect_pressure_unit(values: ArrayLike) -> str | None:
    """Unit of a barometer: ``"hPa"``, ``"kPa"``, ``"Pa"`` or None if unclear.

    Parameters
    ----------
    values
        (N,) or (N, 1) static pressure samples in an unknown unit.
    """
    v = _rows(values, 1, "barometer")
    return _by_range(float(np.median(v)), _PRESSURE_MEDIAN)


def _moving_average(x: FloatArray, n: int) -> FloatArray:
    """Centred moving average along axis 0 with window ``n`` samples (edges use shorter windows)."""
    if n <= 1:
        return x
    c = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x]), axis=0)
    i = np.arange(x.shape[0])
    lo = np.clip(i - n // 2, 0, x.shape[0])
    hi = np.clip(i - n // 2 + n, 0, x.shape[0])
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def tilt_rate_ratio(t_gyro_s: ArrayLike, gyro: ArrayLike, t_acc_s: ArrayLike, acc: ArrayLike) -> float | None:
    """Ratio of the accelerometer's tilt rate to the gyro's tilt-axis rate (about 1 for rad/s, pi/180 for deg/s).

    The direction ``u = f/|f|`` of low-passed specific force obeys ``du/dt = -omega x u`` in the body
    frame (omega in rad/s); the ratio is ``median |du/dt| / median |omega x u|`` over the samples
    whose tilt rate is in the upper half. Both signals are smoothed with the same 0.5 s moving
    average, and ``du/dt`` is a central difference across that window (robust to timestamp jitter).
    Linear acceleration makes ``u`` wander more than the sensor turns, so the ratio scatters around 1
    (0.6-1.8 for rad/s gyros on hand-held and pocket phones and foot IMUs in the shared datasets), far
    from the factor 57 between the two units.

    Parameters
    ----------
    t_gyro_s, gyro
        (N,) seconds and (N, 3) angular rate in the unknown unit, body frame.
    t_acc_s, acc
        (M,) seconds and (M, 3) specific force in any unit, same body frame.

    Returns
    -------
    float or None
        The ratio, or None when the streams barely overlap or the sensor did not tilt enough (median
        selected tilt rate below 0.15 rad/s).
    """
    tg = np.asarray(t_gyro_s, dtype=np.float64)
    ta = np.asarray(t_acc_s, dtype=np.float64)
    w = _rows(gyro, 3, "gyroscope")
    f = _rows(acc, 3, "accelerometer")
    lo, hi = max(tg[0], ta[0]), min(tg[-1], ta[-1])
    keep = (ta >= lo) & (ta <= hi)
    if keep.sum() < 10:
        return None
    ta, f = ta[keep], f[keep]
    dt = float(np.median(np.diff(ta)))
    if not dt > 0:
        return None
    n = max(1, int(round(_CROSSCHECK_WINDOW_S / dt)))
    w_a = np.column_stack([np.interp(ta, tg, w[:, k]) for k in range(3)])
    f_s = _moving_average(f, n)
    w_s = _moving_average(w_a, n)
    norm = _row_norms(f_s)
    ok = norm > 0
    h = max(1, n // 2)
    if ok.sum() <= 2 * h + 10:
        return None
    u, tu, wu = f_s[ok] / norm[ok, None], ta[ok], w_s[ok]
    du = np.linalg.norm((u[2 * h:] - u[:-2 * h]) / (tu[2 * h:] - tu[:-2 * h])[:, None], axis=1)
    perp = np.linalg.norm(np.cross(wu[h:-h], u[h:-h]), axis=1)
    sel = du >= np.median(du)
    tilt = float(np.median(du[sel]))
    gyro_tilt = float(np.median(perp[sel]))
    if tilt < _MIN_TILT_RATE_RADPS or gyro_tilt <= 0:
        return None
    return tilt / gyro_tilt


def detect_gyro_unit(values: ArrayLike, t_s: ArrayLike | None = None, acc_t_s: ArrayLike | None = None,
                     acc: ArrayLike | None = None) -> str | None:
    """Unit of a gyroscope: ``"rad/s"``, ``"deg/s"`` or None if the data cannot tell.

    Parameters
    ----------
    values
        (N, 3) angular rate in an unknown unit, body frame.
    t_s
        (N,) seconds of the gyro samples; needed for the accelerometer cross-check.
    acc_t_s, acc
        (M,) seconds and (M, 3) specific force of the same device (any unit), for the cross-check.

    Returns
    -------
    str or None
        ``"deg/s"`` when the 99th-percentile rate exceeds :data:`MAX_HUMAN_RATE_RADPS` or the tilt-rate
        ratio is within a factor 4 of pi/180; ``"rad/s"`` when the ratio is within a factor 4 of 1;
        None otherwise (e.g. a static gyro).
    """
    w = _rows(values, 3, "gyroscope")
    if float(np.percentile(_row_norms(w), 99)) > MAX_HUMAN_RATE_RADPS:
        return "deg/s"
    if t_s is None or acc is None or acc_t_s is None:
        return None
    ratio = tilt_rate_ratio(t_s, w, acc_t_s, acc)
    if ratio is None:
        return None
    for unit, factor in GYRO_UNITS.items():
        if abs(np.log(ratio / factor)) < np.log(_RATIO_TOLERANCE):
            return unit
    return None


def _describe(values: FloatArray, family: str) -> str:
    if family == "pressure":
        return f"median {float(np.median(values)):.4g}"
    norms = _row_norms(values)
    if family == "gyro":
        return f"99th-percentile norm {float(np.percentile(norms, 99)):.4g}"
    return f"median norm {float(np.median(norms)):.4g}"


@dataclass(frozen=True)
class _Check:
    kind: str
    family: str
    detected: str | None


def check_units(recording: Recording, kinds: Iterable[str] | None = None,
                fallback: Mapping[str, str] | None = None) -> Recording:
    """Verify that streams a reader stored as SI really are SI; convert clear mistakes with a warning.

    Parameters
    ----------
    recording
        Streams whose values were stored as if in the SI unit of their kind.
    kinds
        Stream kinds to check (default: every present kind in :data:`CHECKABLE_KINDS`).
    fallback
        Stream kind -> unit to assume when the data cannot tell (e.g. ``{"gyro": "rad/s"}`` for a
        format documented as rad/s); without one, an undecidable stream raises.

    Returns
    -------
    Recording
        The recording with mis-scaled streams converted to SI and one warning per conversion.

    Raises
    ------
    InputError
        Naming the stream, when its unit cannot be decided and no fallback was given, or when a
        fallback or kind is not known.
    """
    fallback = dict(fallback or {})
    wanted = list(kinds) if kinds is not None else [k for k in CHECKABLE_KINDS if recording.has(k)]
    for k in list(wanted) + list(fallback):
        if k not in _FAMILIES:
            raise InputError(f"cannot check the unit of this kind (checkable: {', '.join(CHECKABLE_KINDS)})",
                             source=f"stream '{k}'")
    for k, u in fallback.items():
        if u not in _UNITS_OF[_FAMILIES[k]]:
            raise InputError(f"unknown fallback unit '{u}' (known: {', '.join(_UNITS_OF[_FAMILIES[k]])})",
                             source=f"stream '{k}'")
    order = sorted((k for k in wanted if recording.has(k)), key=lambda k: _FAMILIES[k] != "acc")
    new: dict[str, SensorStream] = {}
    notes: list[str] = []
    origin = recording.origin_ns
    for kind in order:
        stream = recording.stream(kind)
        family = _FAMILIES[kind]
        v = stream.values
        if family == "acc":
            detected = detect_acc_unit(v)
        elif family == "mag":
            detected = detect_mag_unit(v)
        elif family == "pressure":
            detected = detect_pressure_unit(v)
        else:
            acc_stream = new.get("acc") or (recording.streams.get("acc"))
            if acc_stream is not None and len(acc_stream) > 1 and len(stream) > 1:
                detected = detect_gyro_unit(v, stream.t_s(origin), acc_stream.t_s(origin), acc_stream.values)
            else:
                detected = detect_gyro_unit(v)
        si = next(iter(_UNITS_OF[family]))
        if detected is None:
            if kind in fallback:
                detected = fallback[kind]
            else:
                raise InputError(
                    f"cannot tell the unit from the data ({_describe(v, family)}; candidates "
                    f"{', '.join(_UNITS_OF[family])}); give the unit explicitly", source=f"stream '{kind}'")
        if detected != si:
            factor = _UNITS_OF[family][detected]
            new[kind] = SensorStream(kind, stream.t_ns, v * factor)
            notes.append(f"stream '{kind}': values look like {detected} ({_describe(v, family)}), "
                         f"converted to {si} (x{factor:.6g})")
    if not new:
        return recording
    return recording.with_streams(new, warnings=tuple(notes))


#: Largest magnitude a sensor can report, per stream kind, in the kind's SI unit: far beyond any real sensor's range
#: (high-g accelerometers: 200 g; gyros: 2000 deg/s = 35 rad/s; magnetometers: a few mT), so only a corrupt field
#: reaches it (1e308 is finite, but its square overflows the filters). One table for the readers
#: (:func:`check_ranges`) and the service's batches (``server.plausibility.check_units``).
MAX_ABS_SI: Mapping[str, float] = {"acc": 1e4, "acc_uncal": 1e4, "gravity": 1e4, "lin_acc": 1e4, "gyro": 1e4,
                                   "gyro_uncal": 1e4, "mag": 1e6, "mag_uncal": 1e6, "baro": 1e4}


#: Accepted distance of the norm of an attitude quaternion (``orientation``) from 1: the readers normalise them, so
#: only a corrupt sample (a rotation vector of 1e308, read as the zero quaternion) is farther.
QUATERNION_NORM_TOLERANCE = 0.5


def check_ranges(recording: Recording, source: str) -> None:
    """:class:`InputError` naming ``source``, the stream and its first sample (and time) with a value beyond
    :data:`MAX_ABS_SI`, or an ``orientation`` that is no attitude (:data:`QUATERNION_NORM_TOLERANCE`).
    """
    if recording.has("orientation"):
        q = recording.values("orientation")
        with np.errstate(over="ignore"):
            norm = np.sqrt(np.einsum("ij,ij->i", q, q))
        lo, hi = (1.0 - QUATERNION_NORM_TOLERANCE, 1.0 + QUATERNION_NORM_TOLERANCE)
        in_range = norm.size == 0 or lo <= norm.min() <= norm.max() <= hi
        rows = np.flatnonzero(~((norm >= lo) & (norm <= hi))) if not in_range else np.zeros(0, dtype=np.intp)
        if rows.size:
            i = int(rows[0])
            raise InputError(f"sample {i} (t {recording.t_s('orientation')[i]:.3f} s) is a quaternion of norm "
                             f"{norm[i]:.3g} ({q[i].tolist()}), not an attitude (a unit quaternion)", source=source,
                             field="orientation")
    for kind, limit in MAX_ABS_SI.items():
        if not recording.has(kind):
            continue
        values = recording.values(kind)
        if values.size == 0 or -limit <= values.min() <= values.max() <= limit:    # two passes, no temporaries
            continue
        rows = np.flatnonzero((np.abs(values) > limit).any(axis=1))
        if rows.size:
            i = int(rows[0])
            raise InputError(f"sample {i} (t {recording.t_s(kind)[i]:.3f} s) holds a value of magnitude "
                             f"{float(np.abs(values[i]).max()):.3g} {recording.stream(kind).spec.unit}, beyond any "
                             f"sensor (limit {limit:g})", source=source, field=kind)
