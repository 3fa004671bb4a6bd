"""LORD MicroStrain SensorConnect CSV exports (3DM-GX3/GX5 inertial nodes), with stride ground truth if present.

Column names carry the node name, ``inertial-6253.76535:scaledAccelX``; everything up to the last ``:`` is
stripped (validity flags ``...:estRollX:valid`` become ``estRollX:valid``). Two variants are recognised:

1. raw scaled outputs: ``Time, scaledAccelX/Y/Z`` (g), ``scaledGyroX/Y/Z`` (rad/s), ``scaledMagX/Y/Z``
   (Gauss; 1 G = 100 uT), ``roll, pitch, yaw`` (rad, the node's AHRS);
2. filter outputs: ``Time, estCompensatedAccelX/Y/Z`` (m/s^2, gravity included, bias-compensated),
   ``estAngularRateX/Y/Z`` (rad/s), ``estRoll/estPitch/estYaw`` (rad), each followed by a ``:valid`` flag.
   Rows whose flags are 0 are dropped per stream, with a warning.

``Time`` is in seconds (from 0 in the LLIO walks). The accelerometer is specific force in the sensor frame
(a level node at rest reads (0, 0, -1) g: the LORD sensor frame has z down); acc and mag units given by the
header are cross-checked against the data (:mod:`pdr.units`); a clear mismatch is converted with a warning.
SensorConnect ends every row with a line break: a last row without one (an export cut off, perhaps mid-number) is
dropped with a warning naming file and line.

Orientation convention (verified on the LLIO walks: the accelerometer at rest agrees with the angles to
within a few degrees): roll, pitch, yaw are ZYX Euler angles of the sensor frame relative to local NED,
``R_ned_b = Rz(yaw) Ry(pitch) Rx(roll)``. The ``orientation`` stream is ``q_nb`` into ENU:
``q_enu_b = q_enu_ned * q_ned_b`` with ``q_enu_ned`` the swap of x/y and flip of z.

Ground truth (the LLIO dataset of Cetin and Koroglu): a sibling ``<stem>.mat`` with ``GCP_meters`` (K, 2)
footprint positions in the floor-tile frame and ``GCP_stride_numbers``. Their times come from
``<stem>_strideIndex_timestamp_gcpX_gcpY.csv`` (in the same folder, or in ``../LLIO_training_data/`` or
``./LLIO_training_data/``): row ``i`` gives the sample index at the end of stride ``i``'s stance. With it,
``truth.positions`` is a ``stride`` truth in frame ``map`` (up = 0) at the time of that sample, and
``truth.extra['stride_end_index']`` holds the sample indices. Without it, only stride numbers are known, so no
positions are claimed: the GCPs go to ``truth.extra['gcp_m']`` (K, 2) and ``truth.extra['gcp_stride_number']``
(K,), with a warning. ``GCP_exist_and_correct`` = 0 (partial GCPs) adds a warning too.

The walks are foot-mounted on an unknown side: the device role is ``right_foot`` with
``meta['foot_side'] = 'unknown'``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pdr import quaternion
from pdr.errors import InputError
from pdr.io import matfile
from pdr.io.csvtable import Table, parse_table, split_header
from pdr.io.text import find_member, head, read_text, strip_gz, timestamps_ns
from pdr.io.time_order import keep_increasing
from pdr.recording import DeviceInfo, GroundTruth, PositionTruth, Recording, SensorStream
from pdr.units import ACC_UNITS, GYRO_UNITS, MAG_UNITS, detect_acc_unit, detect_mag_unit

FORMAT = "sensorconnect"
DESCRIPTION = "LORD SensorConnect CSV (foot IMU: scaled or filter outputs), with LLIO stride truth when present"

_TIME_NAMES = ("Time", "Time(s)", "Time (s)")
_MARKERS = ("scaledAccel", "scaledGyro", "estCompensatedAccel", "estAngularRate")

# stream kind -> (column names, documented unit) per variant
_RAW = {"acc": (("scaledAccelX", "scaledAccelY", "scaledAccelZ"), "g"),
        "gyro": (("scaledGyroX", "scaledGyroY", "scaledGyroZ"), "rad/s"),
        "mag": (("scaledMagX", "scaledMagY", "scaledMagZ"), "G")}
_RAW_EULER = ("roll", "pitch", "yaw")
_EST = {"acc": (("estCompensatedAccelX", "estCompensatedAccelY", "estCompensatedAccelZ"), "m/s^2"),
        "gyro": (("estAngularRateX", "estAngularRateY", "estAngularRateZ"), "rad/s")}
_EST_EULER = ("estRoll", "estPitch", "estYaw")

#: q_enu_ned: ENU x = NED y, ENU y = NED x, ENU z = -NED z.
Q_ENU_NED = quaternion.from_rotmat(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]))


def _column_name(raw: str) -> str:
    parts = raw.strip().split(":")
    if len(parts) >= 2 and parts[-1] == "valid":
        return f"{parts[-2]}:valid"
    return parts[-1]


def sniff(path: str | Path) -> bool:
    """A CSV (or .csv.gz) whose header starts with Time and names LORD channels (``node:scaledAccelX`` ...)."""
    try:
        p = Path(path)
        if not strip_gz(p.name.lower()).endswith(".csv"):
            return False
        first = head(p).split(b"\n", 1)[0].decode("utf-8-sig", errors="replace")
        fields = first.split(",")
        return (fields[0].strip() in _TIME_NAMES
                and any(":" in f and _column_name(f).startswith(_MARKERS) for f in fields[1:]))
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return False


def orientation_q_nb(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, 4) ``q_nb`` (body to ENU) from LORD roll, pitch, yaw in rad (ZYX Euler angles relative to NED)."""
    q_ned_b = quaternion.from_euler(roll, pitch, yaw)
    return quaternion.normalize(quaternion.multiply(Q_ENU_NED, q_ned_b))


def read(path: str | Path) -> Recording:
    """Read a SensorConnect CSV (plain or .gz) into a foot :class:`Recording`, with stride truth if found."""
    p = Path(path)
    source = str(p)
    text = read_text(p)
    first_line = text.split("\n", 1)[0]
    raw_header = split_header(first_line, source=source) if first_line.strip() else []
    rename = {h: _column_name(h) for h in raw_header}
    warnings: list[str] = []
    table = parse_table(text, source, rename=rename, notes=warnings, terminated=True)
    time_col = next((n for n in _TIME_NAMES if n in table.header), None)
    if time_col is None:
        raise InputError(f"no Time column (header has {list(table.header)})", source=source, line=1, field="Time")
    if len(table) == 0:
        raise InputError("no samples after the header", source=source, line=2)
    t_s = table.column(time_col)
    t_ns = timestamps_ns(t_s, source, time_col, scale=1e9)
    in_order = keep_increasing(t_ns, source, time_col, warnings, lines=table.lines())  # < 1 ns apart: repeats

    variant = 2 if "estCompensatedAccelX" in table.header or "estAngularRateX" in table.header else 1
    channels, euler = (_EST, _EST_EULER) if variant == 2 else (_RAW, _RAW_EULER)
    streams: dict[str, SensorStream] = {}
    for kind, (cols, unit) in channels.items():
        if all(c in table.header for c in cols):
            ok = _valid_rows(table, cols, kind, warnings) & in_order
            with np.errstate(over="ignore"):     # a value beyond a float in SI: named by stack_scaled
                factor = _si_factor(kind, unit, table.stack(cols)[ok], warnings)
            streams[kind] = SensorStream(kind, t_ns[ok], table.stack_scaled(cols, factor, unit)[ok])
    if all(c in table.header for c in euler):
        ok = _valid_rows(table, euler, "orientation", warnings) & in_order
        angles = table.stack(euler)[ok]
        streams["orientation"] = SensorStream("orientation", t_ns[ok],
                                              orientation_q_nb(angles[:, 0], angles[:, 1], angles[:, 2]))
    if "acc" not in streams and "gyro" not in streams:
        raise InputError("neither accelerometer nor gyroscope columns found (expected scaledAccelX... or "
                         f"estCompensatedAccelX...; header has {list(table.header)})", source=source, line=1)

    node = next((h.strip().split(":")[0] for h in raw_header if ":" in h), "")
    truth, truth_warnings, truth_meta = _stride_truth(p, t_s - t_s[0])
    meta = {"variant": variant, "node": node, "foot_side": "unknown", **truth_meta}
    device = DeviceInfo(platform="imu", model="LORD MicroStrain (SensorConnect)", role="right_foot",
                        placement="foot", device_id=node)
    return Recording(streams, device=device, t0_ns=int(t_ns[0]), truth=truth, source=source, format=FORMAT,
                     warnings=tuple(warnings + truth_warnings), meta=meta)


def _si_factor(kind: str, unit: str, values: np.ndarray, warnings: list[str]) -> float:
    """Factor to SI of the header's unit, unless the data clearly is in another unit (then with a warning)."""
    if kind == "acc":
        detected, units = (detect_acc_unit(values) if len(values) else None), ACC_UNITS
    elif kind == "mag":
        detected, units = (detect_mag_unit(values) if len(values) else None), MAG_UNITS
    else:
        return GYRO_UNITS[unit]
    if detected is not None and detected != unit:
        warnings.append(f"{kind}: the header implies {unit} but the data is in {detected} "
                        f"(median norm {float(np.median(np.linalg.norm(values, axis=1))):.3g}); read as {detected}")
        return units[detected]
    return units[unit]


def _valid_rows(table: Table, cols: tuple[str, ...], kind: str, warnings: list[str]) -> np.ndarray:
    """Rows whose ``:valid`` flags (when present) are all non-zero."""
    ok = np.ones(len(table), dtype=bool)
    for c in cols:
        flag = f"{c}:valid"
        if flag in table.header:
            ok &= table.column(flag) != 0
    if not ok.all():
        warnings.append(f"{kind}: dropped {int((~ok).sum())} of {ok.size} rows flagged invalid by the filter")
    return ok


def _llio_file(p: Path, stem: str) -> Path | None:
    name = f"{stem}_strideIndex_timestamp_gcpX_gcpY.csv"
    for folder in (p.parent, p.parent.parent / "LLIO_training_data", p.parent / "LLIO_training_data"):
        found = find_member(folder, name)
        if found is not None:
            return found
    return None


def _stride_truth(p: Path, t_rel_s: np.ndarray) -> tuple[GroundTruth, list[str], dict[str, object]]:
    """GCP truth from the sibling .mat (and LLIO stride times); see the module docstring."""
    stem = strip_gz(p.name)[: -len(".csv")]
    mat_path = find_member(p.parent, f"{stem}.mat")
    if mat_path is None:
        return GroundTruth(), [], {}
    src = str(mat_path)
    mat = matfile.load(mat_path)
    if "GCP_meters" not in mat:
        return GroundTruth(), [], {}
    gcp = matfile.array(mat, "GCP_meters", src, ncol=2)
    k = gcp.shape[0]
    if "GCP_stride_numbers" in mat:
        strides = matfile.array(mat, "GCP_stride_numbers", src, vector=True).astype(np.int64)
    else:
        strides = np.arange(k)
    if strides.size != k:
        raise InputError(f"{strides.size} stride numbers for {k} GCPs", source=src, field="GCP_stride_numbers")
    warnings: list[str] = []
    meta: dict[str, object] = {}
    complete = matfile.scalar(mat, "GCP_exist_and_correct")
    for key, name in (("numberOfStrides", "number_of_strides"), ("tile_edge_length", "tile_edge_length_m")):
        value = matfile.scalar(mat, key)
        if value is not None:
            meta[name] = value
    if complete is not None:
        meta["gcp_complete"] = bool(complete)
        if not complete:
            warnings.append(f"{mat_path.name}: GCP_exist_and_correct = 0, the footprint truth is partial or coarse")
    llio = _llio_file(p, stem)
    if llio is not None:
        table = parse_table(read_text(llio), str(llio))
        idx = table.column("strideIndex")
        if np.any(idx != np.round(idx)) or np.any(idx < 0) or np.any(idx >= t_rel_s.size):
            i = int(np.flatnonzero((idx != np.round(idx)) | (idx < 0) | (idx >= t_rel_s.size))[0])
            raise InputError(f"stride index {idx[i]} is not a sample of the {t_rel_s.size}-sample log",
                             source=str(llio), line=table.line(i), field="strideIndex")
        if strides.max(initial=-1) < idx.size:
            sample = idx.astype(np.int64)[strides]
            t = t_rel_s[sample]
            stamp = table.column("timestamp")[strides] - (t_rel_s[0] if t_rel_s.size else 0.0)
            if np.max(np.abs(stamp - t), initial=0.0) > 0.01:
                warnings.append(f"{llio.name}: stride timestamps differ from the log's Time at strideIndex by up "
                                f"to {np.max(np.abs(stamp - t)):.3f} s; Time at strideIndex is used")
            pos = np.column_stack([gcp, np.zeros(k)])
            positions = PositionTruth(t, pos, kind="stride", frame="map")
            return GroundTruth(positions=positions, extra={"stride_end_index": sample}), warnings, meta
        warnings.append(f"{llio.name}: {idx.size} strides but GCPs up to stride {strides.max()}; stride times unknown")
    warnings.append("footprint GCPs without stride times: stored in truth.extra['gcp_m'] and "
                    "truth.extra['gcp_stride_number'], not as timed positions")
    return GroundTruth(extra={"gcp_m": gcp, "gcp_stride_number": strides}), warnings, meta
