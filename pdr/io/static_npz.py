"""Static IMU recordings as numpy ``.npz`` (``data`` (N, k), ``columns`` (k,) names, ``fs`` Hz), for Allan variance.

Columns are matched by name: a name containing ``gyro``, ``acc`` or ``mag`` (any case) ending in the axis
letter X, Y or Z (e.g. ``Gyro. X``, ``Accel. Z``). A sensor needs all three axes. Timestamps are
``t_ns = round(i * 1e9 / fs)`` from 0.

The files do not store units, so they are decided from the data, never from a file name:

accelerometer
    :func:`pdr.units.detect_acc_unit`: median norm ~1 means g, ~9.8 means m/s^2, ~1000 means mg.
gyroscope
    first :func:`pdr.units.detect_gyro_unit` (impossible rates, tilt cross-check with the accelerometer);
    when that cannot tell, as for any static recording, the static noise decides: the per-axis standard
    deviation of a MEMS gyro at rest is a few mdeg/s to ~0.5 deg/s. A median std above
    :data:`DEG_STD_MIN` (0.05, i.e. 2.9 deg/s if it were rad/s: no gyro is that noisy) means deg/s; below
    :data:`RAD_STD_MAX` (0.02) with a bias under 0.05 means rad/s; in between, or if the accelerometer shows
    motion, the unit is ambiguous and :class:`~pdr.errors.InputError` is raised.
magnetometer
    :func:`pdr.units.detect_mag_unit`.

Any conversion is reported in ``Recording.warnings``. 1,000,000-sample files (2.8 h at 100 Hz) read in well
under a second plus the load time.
"""

from __future__ import annotations

import io
import re
import zipfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io.text import MAX_ABS_NS, read_bytes, strip_gz
from pdr.recording import DeviceInfo, Recording, SensorStream
from pdr.units import ACC_UNITS, GYRO_UNITS, MAG_UNITS, detect_acc_unit, detect_gyro_unit, detect_mag_unit

FORMAT = "static_npz"
DESCRIPTION = "static IMU .npz (data, columns, fs), units detected from the data (e.g. ADIS16405 deg/s and g)"

#: Median per-axis std of a static gyro above which the values must be deg/s.
DEG_STD_MIN = 0.05
#: Median per-axis std (and largest |mean|) below which a static gyro is taken as rad/s.
RAD_STD_MAX = 0.02
#: Std of the accelerometer norm (in its own unit, relative to its mean) above which the sensor is moving.
_STATIC_ACC_REL_STD = 0.02
#: Samples used for the (slower) motion-based gyro check.
_CHECK_SAMPLES = 200_000

_COLUMN = re.compile(r"(gyro|acc|mag)", re.IGNORECASE)
_KINDS = {"gyro": "gyro", "acc": "acc", "mag": "mag"}


def sniff(path: str | Path) -> bool:
    """A ``.npz`` (zip of .npy) with members ``data``, ``columns`` and ``fs``."""
    try:
        p = Path(path)
        if not strip_gz(p.name.lower()).endswith(".npz") or not p.is_file():
            return False
        src = io.BytesIO(read_bytes(p)) if p.name.lower().endswith(".gz") else p
        with zipfile.ZipFile(src) as zf:
            names = {n.removesuffix(".npy") for n in zf.namelist()}
        return {"data", "columns", "fs"} <= names
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return False


def read(path: str | Path) -> Recording:
    """Read a static ``.npz`` recording, converting units detected from the data to SI (with warnings)."""
    p = Path(path)
    source = str(p)
    raw = read_bytes(p)
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            arrays = {k: z[k] for k in ("data", "columns", "fs") if k in z.files}
            files = sorted(z.files)
    except Exception as exc:  # noqa: BLE001 - numpy raises many types on corrupt archives
        raise InputError(f"not a readable .npz archive ({type(exc).__name__}: {exc})", source=source) from None
    missing = [k for k in ("data", "columns", "fs") if k not in arrays]
    if missing:
        raise InputError(f"missing arrays {missing} (file has {files})", source=source, field=missing[0])
    data, columns, fs_arr = arrays["data"], arrays["columns"], arrays["fs"]
    if data.ndim != 2 or data.dtype.kind not in "fiu":
        raise InputError(f"expected a numeric (N, k) array, got {data.dtype} of shape {data.shape}", source=source,
                         field="data")
    names = [str(c) for c in np.atleast_1d(columns)]
    if len(names) != data.shape[1]:
        raise InputError(f"{len(names)} column names for {data.shape[1]} data columns", source=source,
                         field="columns")
    try:
        fs = float(np.asarray(fs_arr, dtype=np.float64).ravel()[0])
    except (TypeError, ValueError, IndexError):
        raise InputError("sampling rate is not a number", source=source, field="fs") from None
    if not np.isfinite(fs) or fs <= 0:
        raise InputError(f"sampling rate must be a positive number of Hz, got {fs}", source=source, field="fs")
    if data.shape[0] < 2:
        raise InputError(f"need at least 2 samples, got {data.shape[0]}", source=source, field="data")
    if not 1e9 / fs >= 1 or (data.shape[0] - 1) * (1e9 / fs) > MAX_ABS_NS:
        raise InputError(f"sampling rate {fs:g} Hz gives no nanosecond time axis for {data.shape[0]} samples (a "
                         "period of at least 1 ns, all within int64 nanoseconds)", source=source, field="fs")
    data = np.asarray(data, dtype=np.float64)
    finite = np.isfinite(data)
    if not finite.all():
        row, col = (int(x) for x in np.argwhere(~finite)[0])
        raise InputError(f"sample {row} is not finite ({data[row, col]})", source=source, field=names[col])

    groups = _group_columns(names, source)
    n = data.shape[0]
    step = 1e9 / fs
    t_ns = (np.arange(n, dtype=np.int64) * int(step) if step.is_integer()
            else np.round(np.arange(n) * step).astype(np.int64))
    t_s = t_ns / 1e9
    warnings: list[str] = []
    units: dict[str, str] = {}
    values = {kind: data[:, idx] for kind, idx in groups.items()}
    streams: dict[str, SensorStream] = {}
    if "acc" in values:
        unit = detect_acc_unit(_thin(values["acc"]))
        if unit is None:
            norm = float(np.median(np.linalg.norm(_thin(values["acc"]), axis=1)))
            raise InputError(f"cannot tell the accelerometer unit: median norm {norm:.4g} is neither ~1 (g) nor "
                             "~9.8 (m/s^2)", source=source, field=names[groups["acc"][0]])
        units["acc"] = unit
        streams["acc"] = SensorStream("acc", t_ns,
                                        _to_si(values["acc"], ACC_UNITS[unit], unit, groups["acc"], names, source))
    if "gyro" in values:
        unit, why = _gyro_unit(values["gyro"], t_s, values.get("acc"))
        if unit is None:
            raise InputError(f"cannot tell the gyroscope unit (deg/s or rad/s): {why}", source=source,
                             field=names[groups["gyro"][0]])
        units["gyro"] = unit
        streams["gyro"] = SensorStream("gyro", t_ns,
                                        _to_si(values["gyro"], GYRO_UNITS[unit], unit, groups["gyro"], names, source))
        if unit != "rad/s":
            warnings.append(f"gyro: values are in {unit} ({why}); converted to rad/s")
    if "mag" in values:
        unit = detect_mag_unit(_thin(values["mag"]))
        if unit is None:
            raise InputError("cannot tell the magnetometer unit (uT, G or nT)", source=source,
                             field=names[groups["mag"][0]])
        units["mag"] = unit
        streams["mag"] = SensorStream("mag", t_ns,
                                        _to_si(values["mag"], MAG_UNITS[unit], unit, groups["mag"], names, source))
    if units.get("acc", "m/s^2") != "m/s^2":
        warnings.append(f"acc: values are in {units['acc']} (median norm "
                        f"{float(np.median(np.linalg.norm(_thin(values['acc']), axis=1))):.4g}); converted to m/s^2")
    if units.get("mag", "uT") != "uT":
        warnings.append(f"mag: values are in {units['mag']}; converted to uT")
    return Recording(streams, device=DeviceInfo(platform="imu"), t0_ns=0, source=source, format=FORMAT,
                     warnings=tuple(warnings), meta={"fs_hz": fs, "columns": names, "units": units, "static": True})


def _to_si(v: NDArray[np.float64], factor: float, unit: str, cols: list[int], names: list[str],
           source: str) -> NDArray[np.float64]:
    """``v`` (columns ``cols`` of the data, in ``unit``) times ``factor``; :class:`InputError` naming the sample and
    column of a value that the factor takes beyond any float (1e308 g).
    """
    with np.errstate(over="ignore"):
        out = v * factor
    bad = ~np.isfinite(out)
    if bad.any():
        row, col = (int(x) for x in np.argwhere(bad)[0])
        raise InputError(f"sample {row} ({v[row, col]:g} {unit}) is beyond any float once converted to SI",
                         source=source, field=names[cols[col]])
    return out


def _thin(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """At most about :data:`_CHECK_SAMPLES` rows, evenly spread over the recording (for unit statistics)."""
    return v[:: max(1, v.shape[0] // _CHECK_SAMPLES)]


def _group_columns(names: list[str], source: str) -> dict[str, list[int]]:
    """Stream kind -> column indices in X, Y, Z order."""
    found: dict[str, dict[str, int]] = {}
    for i, name in enumerate(names):
        m = _COLUMN.search(name)
        axis = name.strip()[-1:].upper()
        if m and axis in ("X", "Y", "Z"):
            found.setdefault(_KINDS[m.group(1).lower()], {})[axis] = i
    if not found:
        raise InputError(f"no gyro/accel/mag X/Y/Z columns among {names}", source=source, field="columns")
    out = {}
    for kind, axes in found.items():
        if set(axes) != {"X", "Y", "Z"}:
            raise InputError(f"{kind} needs X, Y and Z columns; found only {sorted(axes)}", source=source,
                             field="columns")
        out[kind] = [axes["X"], axes["Y"], axes["Z"]]
    return out


def _gyro_unit(gyro: NDArray[np.float64], t_s: NDArray[np.float64],
               acc: NDArray[np.float64] | None) -> tuple[str | None, str]:
    """Unit of a gyroscope from motion evidence, else from the noise of a static recording; with the reason."""
    k = min(gyro.shape[0], _CHECK_SAMPLES)
    unit = detect_gyro_unit(gyro[:k], t_s[:k], t_s[:k], acc[:k]) if acc is not None else detect_gyro_unit(gyro[:k])
    if unit is not None:
        return unit, "rates or tilt changes seen by the accelerometer"
    if acc is not None:
        norm = np.linalg.norm(_thin(acc), axis=1)
        if float(np.std(norm)) > _STATIC_ACC_REL_STD * float(np.mean(norm)):
            return None, "the sensor moves but the gyro and accelerometer do not agree on a unit"
    std = float(np.median(np.std(gyro, axis=0)))
    bias = float(np.max(np.abs(np.mean(gyro, axis=0))))
    lsb = _quantum(gyro[:k, 0])
    detail = f"static noise std {std:.3g}, bias {bias:.3g}" + (f", quantised in steps of {lsb:.3g}" if lsb else "")
    if std > DEG_STD_MIN:
        return "deg/s", detail
    if std < RAD_STD_MAX and bias < DEG_STD_MIN:
        return "rad/s", detail
    return None, detail + " fits neither a static gyro in rad/s nor one in deg/s"


def _quantum(x: NDArray[np.float64]) -> float | None:
    """The common step of a quantised signal (None if it is not visibly quantised)."""
    u = np.unique(x)
    if u.size < 3 or u.size > x.size // 4:
        return None
    return float(np.min(np.diff(u)))
