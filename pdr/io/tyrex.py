"""Tyrex attitude benchmark (Michel et al. 2017/2018): Android logger folders with Qualisys motion-capture truth.

One recording is a folder (or a zip of it) of space-separated text files (each plain or ``.gz``), no header, first
column the phone's time ``t`` in seconds since boot (all files share that clock):

``accelerometer.txt``
    ``t ax ay az``: m/s^2, gravity included, Android device frame -> ``acc`` (required).
``gyroscope-calibrated.txt`` / ``gyroscope.txt``
    ``t gx gy gz`` rad/s (TYPE_GYROSCOPE) -> ``gyro``; ``t gx gy gz bx by bz`` (TYPE_GYROSCOPE_UNCALIBRATED)
    -> ``gyro_uncal`` (first three), the OS's bias estimate (last three) -> ``meta['gyro_os_bias']``.
``magnetometer-calibrated.txt`` / ``magnetometer.txt``
    the same in uT -> ``mag``, ``mag_uncal`` and ``meta['mag_os_bias']`` (hard-iron estimate).
``linear-acceleration.txt``
    ``t ax ay az`` m/s^2 without gravity -> ``lin_acc`` (upstream only; absent from ../shared/data).
``rotation-vector.txt``
    ``t x y z w accuracy``: the phone's own fused attitude -> ``orientation`` (``q_nb``, body to ENU with
    magnetic north, :func:`pdr.io.android.rotation_vector_to_q_nb` with the logged ``w``); the accuracy (rad)
    -> ``meta['rotation_vector_accuracy_rad']``.
``record.properties``
    ``[Device]`` Manufacturer, Model, OSVersion, ID and ``[Time]`` StartTime (Unix s) -> device and ``meta``.
``timeAlignment.txt``
    seconds to add to the phone's time to get motion-capture time.

Time: ``t_ns = round(t * 1e9)``, so ``t0_ns / 1e9 + t_s`` (what ``pdr track`` writes) is the phone's seconds
since boot, as in the files' first column. A row whose time repeats or goes back is dropped with a warning naming
file and line (:mod:`pdr.io.time_order`). The logger ends every line with a line break (all 108 files of
../shared/data do): a last line without one (the recording cut off, perhaps mid-number) is dropped with a warning.

The folder name ``<Walker>_<Device>_<Dist|NoDist>_<Motion>`` gives ``meta['walker']``, ``meta['disturbed']``,
``meta['carriage']`` (FrontPocket, BackPocket, Swinging, Texting, RunningPocket, ...) and
``meta['placement_label']`` (:data:`PLACEMENT_OF_CARRIAGE`). The label is NOT put into
:attr:`DeviceInfo.placement`: a user's log does not say where the phone is, so ``pdr track`` must find out
(auto placement) and an evaluation of it must not be handed the answer.

Truth (when ``../../qualisys/<folder name>.mat[.gz]`` exists beside the ``android`` folder): the Qualisys
export (one struct holding ``FrameRate`` and ``RigidBodies.Positions`` (3, K) mm, ``RigidBodies.Rotations``
(9, K), column-major device-to-world matrices). The world frame is X east, Y magnetic north (within a few
degrees), Z up: a magnetic ENU frame, the frame of the rotation vector and of the pipeline without a
declination. Mocap frame ``k`` (0-based) is at mocap time ``k / FrameRate``, i.e. phone time
``k / FrameRate - alignment``. ``alignment`` is ``timeAlignment.txt`` refined by :func:`refine_alignment`
(the lag, within +/- :data:`ALIGN_SEARCH_S`, that best matches the mocap body rate to the gyroscope;
``meta['time_alignment_file_s']`` and ``meta['time_alignment_s']`` hold both). ``meta['field_azimuth_mocap_deg']``
(:func:`field_azimuth_deg`) says how far magnetic north is from the mocap Y axis. Frames with hidden markers
(NaN) and frames inside a rotation glitch (:func:`rotation_glitches`: the rigid body briefly fitted the wrong
way round) are invalid. Truth, on the recording's ``t_s`` axis:

- ``positions``: :class:`PositionTruth` of the frames with a position (metres, ``kind='dense'``, ``frame='enu'``);
- ``extra['trajectory_t_s']`` (K,) every frame's time; ``extra['q_nb']`` (K, 4) the mocap attitude, NaN where
  invalid; ``extra['walk_pos_m']`` (K, 2) the walking path, :func:`walking_path` (the horizontal position
  averaged over one stride, :data:`WALK_SMOOTHING_S`), NaN where it cannot be formed;
  ``extra['walking_heading_rad']`` (K,) ENU yaw of that path's velocity, NaN below
  :data:`MIN_WALK_SPEED_MPS`.

The walking direction over a step is the direction of ``walk_pos_m`` between the step's start and end.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.io import matfile
from pdr.io.android import rotation_vector_to_q_nb
from pdr.io.bundle import Bundle, is_zip
from pdr.io.text import drop_cut_off_last_line, find_member, parse_float_rows, timestamps_ns
from pdr.io.time_order import keep_increasing
from pdr.recording import DeviceInfo, GroundTruth, PositionTruth, Recording, SensorStream

FORMAT = "tyrex"
DESCRIPTION = ("Tyrex attitude-benchmark Android logger folder (record.properties, accelerometer.txt, "
               "gyroscope[-calibrated].txt, ...), Qualisys truth from ../../qualisys/NAME.mat")

FloatArray = NDArray[np.float64]

_XYZ = ("t", "x", "y", "z")
_XYZ_BIAS = ("t", "x", "y", "z", "bias_x", "bias_y", "bias_z")
#: File name (without ``.gz``) -> (stream kind, columns). ``bias`` columns go to ``meta``.
FILES: dict[str, tuple[str, tuple[str, ...]]] = {
    "accelerometer.txt": ("acc", _XYZ),
    "gyroscope-calibrated.txt": ("gyro", _XYZ),
    "gyroscope.txt": ("gyro_uncal", _XYZ_BIAS),
    "magnetometer-calibrated.txt": ("mag", _XYZ),
    "magnetometer.txt": ("mag_uncal", _XYZ_BIAS),
    "linear-acceleration.txt": ("lin_acc", _XYZ),
    "rotation-vector.txt": ("orientation", ("t", "x", "y", "z", "w", "accuracy")),
}
PROPERTIES = "record.properties"
ALIGNMENT = "timeAlignment.txt"
#: Carriage (the folder name's motion) -> placement label of :data:`pdr.recording.PLACEMENTS`.
PLACEMENT_OF_CARRIAGE: dict[str, str] = {
    "FrontPocket": "trouser_pocket_front", "BackPocket": "trouser_pocket_back", "RunningPocket": "trouser_pocket",
    "Swinging": "hand", "Texting": "hand", "Phoning": "hand", "AR": "hand", "RunningHand": "hand",
}
#: Half-width (s) of the lag search that refines ``timeAlignment.txt`` (SOURCE.md: it is good to 1-2 frames).
ALIGN_SEARCH_S = 0.1
#: Lag resolution (s) of that search.
ALIGN_STEP_S = 0.001
#: Rate error (rad/s) beyond which a frame is an outlier in the alignment fit (glitches, hidden markers).
ALIGN_CLIP_RADPS = 1.0
#: Mocap rotation rate (rad/s) taken as a jump of the rigid-body fit: the fastest rotation the gyroscope of any of
#: the 18 shared recordings measures is 21.8 rad/s (running, thigh); a wrong-way-round fit jumps by 30-180 rad/s.
GLITCH_RATE_RADPS = 30.0
#: Two jumps closer than this (s) bound a glitch: every frame between them is invalid.
GLITCH_SPAN_S = 1.0
#: Averaging window (s) of the walking path: about one stride, so the body's sway at the step and stride
#: frequencies cancels.
WALK_SMOOTHING_S = 1.0
#: Longest run of hidden frames (s) the walking path bridges by linear interpolation.
MAX_GAP_S = 0.5
#: Speed (m/s) of the walking path below which its direction is undefined (standing, turning on the spot).
MIN_WALK_SPEED_MPS = 0.2

_NAME = re.compile(r"^(?P<walker>[A-Za-z]+)_(?P<device>[A-Za-z0-9]+)_(?P<dist>Dist|NoDist)_(?P<motion>[A-Za-z]+)$")
_NUMERIC_LINE = re.compile(rb"^\s*-?\d+(\.\d+)?([eE][-+]?\d+)?(\s+[-+0-9.eE]+){3,}\s*$")


def _is_archive(p: Path) -> bool:
    return p.is_file() and (p.name.lower().endswith(".zip") or is_zip(p))


def _logger_folder(path: str | Path) -> tuple[Bundle, bytes | None] | None:
    """A folder (or a zip of it) with ``record.properties`` holding a ``[Device]`` section, and the bytes of its
    ``accelerometer.txt[.gz]`` (None when missing); None for anything else (never raises on foreign input).
    """
    try:
        p = Path(path)
        if not (p.is_dir() or _is_archive(p)):
            return None
        bundle = Bundle(p, anchor=PROPERTIES)
        props = bundle.get(PROPERTIES)
        if props is None or b"[Device]" not in props[:1024]:
            return None
        return bundle, bundle.get("accelerometer.txt")
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return None


def _numeric_start(acc: bytes) -> bool:
    return _NUMERIC_LINE.match(acc[:512].split(b"\n", 1)[0]) is not None


def sniff(path: str | Path) -> bool:
    """A folder (or a zip of it) with ``record.properties`` (a ``[Device]`` section) and a numeric
    ``accelerometer.txt[.gz]``.
    """
    found = _logger_folder(path)
    return found is not None and found[1] is not None and _numeric_start(found[1])


def near_miss(path: str | Path) -> str | None:
    """Why a logger folder (its ``record.properties`` with a ``[Device]`` section) is not read as a recording, or
    None: the ``accelerometer.txt[.gz]`` that :func:`sniff` needs is missing or does not start with a row of numbers.
    """
    found = _logger_folder(path)
    if found is None:
        return None
    bundle, acc = found
    if acc is not None:
        return None if _numeric_start(acc) else (
            f"a Tyrex logger recording whose {bundle.name('accelerometer.txt')} does not start with a row of "
            "numbers (t ax ay az)")
    others = [name for name in FILES if bundle.get(name) is not None]
    return ("a Tyrex logger recording (record.properties) without accelerometer.txt[.gz], the accelerometer it is "
            "read from" + (f" (it has {', '.join(others)})" if others else "; it has no sensor file at all"))


def read(path: str | Path) -> Recording:
    """Read one recording folder or a zip of it (and, for a folder, its Qualisys truth when present); see the
    module docstring.
    """
    p = Path(path)
    if not (p.is_dir() or _is_archive(p)):
        raise InputError("a Tyrex logger recording is a folder (record.properties, accelerometer.txt, ...) or a "
                         "zip of it", source=str(p))
    bundle = Bundle(p, anchor=PROPERTIES)
    if bundle.get("accelerometer.txt") is None:
        raise InputError("no accelerometer.txt[.gz] in the recording", source=str(p))
    streams: dict[str, SensorStream] = {}
    meta: dict[str, Any] = {"files": []}
    read_warnings: list[str] = []
    for name, (kind, columns) in FILES.items():
        if bundle.get(name) is None:
            continue
        t_ns, arr = _table(bundle.text(name), bundle.name(name), columns, read_warnings)
        meta["files"].append(name)
        if kind == "orientation":
            streams[kind] = SensorStream(kind, t_ns, rotation_vector_to_q_nb(arr[:, 1:4], arr[:, 4]))
            meta["rotation_vector_accuracy_rad"] = float(np.median(arr[:, 5]))
        else:
            streams[kind] = SensorStream(kind, t_ns, arr[:, 1:4])
        if len(columns) == 7:
            meta[f"{kind.removesuffix('_uncal')}_os_bias"] = _bias_changes(arr)
    props = _properties(bundle.text(PROPERTIES), bundle.name(PROPERTIES)) if bundle.get(PROPERTIES) else {}
    device = DeviceInfo(platform="android", model=props.get("Device.Model", ""), role="phone", placement=None,
                        device_id=props.get("Device.ID", ""))
    meta["properties"] = props
    name = _recording_name(p, bundle)
    m = _NAME.match(name)
    if m:
        meta.update(walker=m["walker"], device_name=m["device"], disturbed=m["dist"] == "Dist",
                    carriage=m["motion"], placement_label=PLACEMENT_OF_CARRIAGE.get(m["motion"]))
    rec = Recording(streams, device=device, source=str(p), format=FORMAT, meta=meta)
    mat = _qualisys_file(p) if p.is_dir() else None
    if mat is None:
        why = ("no motion-capture file ../../qualisys/<name>.mat beside the folder" if p.is_dir() else
               "motion capture is read only beside a folder (../../qualisys/<name>.mat), not from a zip")
        return Recording(streams, device=device, t0_ns=rec.origin_ns, source=str(p), format=FORMAT, meta=meta,
                         warnings=(*read_warnings, f"{why}: no truth"))
    if bundle.get(ALIGNMENT) is None:
        raise InputError("motion capture present but no timeAlignment.txt to put it on the phone's clock",
                         source=str(p))
    alignment = _alignment(bundle.text(ALIGNMENT), bundle.name(ALIGNMENT))
    truth, truth_meta, warnings = _mocap_truth(mat, rec, alignment, bundle.name(ALIGNMENT))
    meta.update(truth_meta)
    return Recording(streams, device=device, t0_ns=rec.origin_ns, truth=truth, source=str(p), format=FORMAT,
                     meta=meta, warnings=(*read_warnings, *warnings))


def _recording_name(p: Path, bundle: Bundle) -> str:
    """The recording's name: the folder's, or inside a zip the folder holding ``record.properties``, else the
    zip's name without ``.zip``.
    """
    if p.is_dir():
        return p.name
    inner = bundle.name(PROPERTIES).rsplit(":", 1)[-1].split("/")
    return inner[-2] if len(inner) > 1 else p.name.removesuffix(".zip")


# -- phone files -------------------------------------------------------------------------------------------
def _table(text: str, source: str, columns: tuple[str, ...],
           warnings: list[str]) -> tuple[NDArray[np.int64], FloatArray]:
    """Times (int64 ns) and numeric rows of one space-separated file (rows whose time repeats or goes back in
    nanoseconds, and a last line without its line break, dropped with a warning); InputError naming file, line and
    field on bad input.
    """
    rows: list[list[str]] = []
    numbers: list[int] = []
    text = drop_cut_off_last_line(text, source, None, warnings, terminated=True)
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip():
            rows.append(line.split())
            numbers.append(number)
    if not rows:
        raise InputError("empty file: no samples", source=source)
    arr = parse_float_rows(rows, numbers, source, columns)
    t_ns = timestamps_ns(arr[:, 0], source, "t", scale=1e9)
    keep = keep_increasing(t_ns, source, "t", warnings, lines=numbers)  # rows < 1 ns apart are repeats
    return t_ns[keep], arr[keep]


def _bias_changes(arr: FloatArray) -> list[list[float]]:
    """``[t, bx, by, bz]`` (phone s; the stream's unit) at the first sample and where the OS bias estimate changes."""
    b = arr[:, 4:7]
    at = np.concatenate([[0], np.flatnonzero(np.any(np.diff(b, axis=0) != 0, axis=1)) + 1])
    return [[float(arr[i, 0]), *map(float, b[i])] for i in at]


def _properties(text: str, source: str) -> dict[str, str]:
    """``Section.Key`` -> value of an INI-like ``record.properties``."""
    out: dict[str, str] = {}
    section = ""
    for number, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith(("#", ";")):
            continue
        if s.startswith("[") and s.endswith("]"):
            section = s[1:-1].strip()
            continue
        key, sep, value = s.partition("=")
        if not sep or not key.strip():
            raise InputError(f"expected '[Section]' or 'key = value', found '{s[:40]}'", source=source, line=number)
        out[f"{section}.{key.strip()}" if section else key.strip()] = value.strip()
    return out


def _alignment(text: str, source: str) -> float:
    """Seconds to add to phone time to get mocap time: the one number of ``timeAlignment.txt``."""
    fields = text.split()
    try:
        if len(fields) != 1:
            raise ValueError
        value = float(fields[0])
    except ValueError:
        raise InputError(f"expected one number (seconds to add to phone time), found '{' '.join(fields)[:40]}'",
                         source=source, line=1) from None
    if not np.isfinite(value) or abs(value) > 1e6:
        raise InputError(f"time alignment {value} s is not a plausible offset", source=source, line=1)
    return value


# -- motion capture ----------------------------------------------------------------------------------------
def _qualisys_file(folder: Path) -> Path | None:
    return find_member(folder.resolve().parent.parent / "qualisys", f"{folder.name}.mat")


def _mocap_arrays(path: Path) -> tuple[float, FloatArray, FloatArray]:
    """Frame rate (Hz), positions (K, 3) m and device-to-world rotations (K, 3, 3) of a Qualisys export."""
    source = str(path)
    mat = matfile.load(path, structs=True)
    exports = [v for v in mat.values() if hasattr(v, "RigidBodies") and hasattr(v, "FrameRate")]
    if len(exports) != 1:
        raise InputError(f"expected one Qualisys export struct (with RigidBodies and FrameRate), found "
                         f"{len(exports)} among {sorted(mat)}", source=source)
    qtm = exports[0]
    rb = qtm.RigidBodies
    try:
        rate = float(qtm.FrameRate)
        pos = np.asarray(rb.Positions, dtype=np.float64)
        rot = np.asarray(rb.Rotations, dtype=np.float64)
    except (AttributeError, TypeError, ValueError) as exc:
        raise InputError(f"unreadable RigidBodies ({exc})", source=source, field="RigidBodies") from None
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(f"frame rate {rate} is not positive", source=source, field="FrameRate")
    if pos.ndim != 2 or pos.shape[0] != 3:
        raise InputError(f"expected one rigid body's positions (3, K), got shape {pos.shape}", source=source,
                         field="RigidBodies.Positions")
    if rot.shape != (9, pos.shape[1]):
        raise InputError(f"expected rotations (9, {pos.shape[1]}), got shape {rot.shape}", source=source,
                         field="RigidBodies.Rotations")
    # Column-major 3x3 per frame: element (i, j) is row i + 3 j.
    r = rot.T.reshape(-1, 3, 3).transpose(0, 2, 1)
    return rate, pos.T / 1000.0, r


def rotation_glitches(t_s: FloatArray, q_nb: FloatArray, rate_radps: float = GLITCH_RATE_RADPS,
                      span_s: float = GLITCH_SPAN_S) -> NDArray[np.bool_]:
    """(K,) frames inside a rigid-body fit glitch.

    A jump is a rotation between consecutive valid frames faster than ``rate_radps``; the frames from a jump
    to the next one less than ``span_s`` later are invalid (the fit went wrong and came back), and so are the
    two frames at a lone jump. ``q_nb`` (K, 4) may hold NaN rows (hidden frames, ignored).
    """
    ok = np.flatnonzero(np.all(np.isfinite(q_nb), axis=1))
    bad = np.zeros(t_s.size, dtype=bool)
    if ok.size < 2:
        return bad
    rate = quat.angle_between(q_nb[ok[1:]], q_nb[ok[:-1]]) / np.diff(t_s[ok])
    jumps = np.flatnonzero(rate > rate_radps)
    for j in jumps:
        bad[ok[j]:ok[j + 1] + 1] = True
    for a, b in zip(jumps[:-1], jumps[1:], strict=True):
        if t_s[ok[b + 1]] - t_s[ok[a]] < span_s:
            bad[ok[a]:ok[b + 1] + 1] = True
    return bad


def body_rate(t_s: FloatArray, q_nb: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Body-frame angular rate (M, 3) rad/s between consecutive frames that are both valid, and its times (M,)."""
    ok = np.all(np.isfinite(q_nb), axis=1)
    pair = ok[:-1] & ok[1:]
    dq = quat.multiply(quat.conjugate(q_nb[:-1][pair]), q_nb[1:][pair])
    dt = np.diff(t_s)[pair]
    return quat.to_rotvec(dq) / dt[:, None], 0.5 * (t_s[:-1] + t_s[1:])[pair]


def refine_alignment(t_frame_s: FloatArray, q_nb: FloatArray, gyro_t_s: FloatArray, gyro: FloatArray,
                     search_s: float = ALIGN_SEARCH_S, step_s: float = ALIGN_STEP_S) -> float:
    """Lag (s) to add to mocap frame times (already on the phone's axis) that best matches the mocap body rate
    to the gyroscope (mean rate error with each frame's error clipped at :data:`ALIGN_CLIP_RADPS`).
    """
    w, tw = body_rate(t_frame_s, q_nb)
    lags = np.arange(-search_s, search_s + 0.5 * step_s, step_s)
    cost = np.empty(lags.size)
    for i, lag in enumerate(lags):
        g = np.column_stack([np.interp(tw + lag, gyro_t_s, gyro[:, k]) for k in range(3)])
        cost[i] = np.mean(np.minimum(np.linalg.norm(g - w, axis=1), ALIGN_CLIP_RADPS))
    return float(lags[int(np.argmin(cost))])


def field_azimuth_deg(t_frame_s: FloatArray, q_nb: FloatArray, mag_t_s: FloatArray, mag_b: FloatArray,
                      max_dt_s: float) -> float | None:
    """Compass azimuth (deg, clockwise from the mocap Y axis) of the median horizontal magnetic field rotated into
    the mocap frame by the mocap attitude (frames within ``max_dt_s`` of a magnetometer sample); None without any.

    Near 0 in an undisturbed field: how far the mocap Y axis is from magnetic north.
    """
    ok = np.flatnonzero(np.all(np.isfinite(q_nb), axis=1))
    if ok.size == 0:
        return None
    j = np.clip(np.searchsorted(t_frame_s[ok], mag_t_s), 1, ok.size - 1)
    j = np.where(np.abs(t_frame_s[ok][j - 1] - mag_t_s) < np.abs(t_frame_s[ok][j] - mag_t_s), j - 1, j)
    near = np.abs(t_frame_s[ok][j] - mag_t_s) <= max_dt_s
    if not near.any():
        return None
    m_n = quat.rotate(q_nb[ok][j[near]], mag_b[near])
    return float(np.degrees(np.arctan2(np.median(m_n[:, 0]), np.median(m_n[:, 1]))))


def walking_path(t_s: FloatArray, pos_m: FloatArray, window_s: float = WALK_SMOOTHING_S,
                 max_gap_s: float = MAX_GAP_S) -> FloatArray:
    """(K, 2) horizontal walking path: ``pos_m`` (K, >=2, NaN rows where hidden) averaged over ``window_s``.

    ``t_s`` (K,) are uniformly spaced frame times. Hidden runs up to ``max_gap_s`` are bridged linearly first;
    an output frame whose window touches a longer gap, or runs past either end, is NaN.
    """
    t = np.asarray(t_s, dtype=np.float64)
    xy = np.asarray(pos_m, dtype=np.float64)[:, :2]
    n = t.size
    if n < 2:
        return np.full((n, 2), np.nan)
    dt = float(np.median(np.diff(t)))
    ok = np.all(np.isfinite(xy), axis=1)
    filled = np.full_like(xy, np.nan)
    if ok.sum() >= 2:
        idx = np.flatnonzero(ok)
        for k in range(2):
            filled[:, k] = np.interp(t, t[idx], xy[idx, k], left=np.nan, right=np.nan)
        # Gaps longer than max_gap_s stay NaN.
        gap = np.diff(t[idx]) > max_gap_s + 0.5 * dt
        for a, b in zip(idx[:-1][gap], idx[1:][gap], strict=True):
            filled[a + 1:b] = np.nan
    half = max(1, int(round(0.5 * window_s / dt)))
    width = 2 * half + 1
    valid = np.all(np.isfinite(filled), axis=1)
    zero = np.where(valid[:, None], filled, 0.0)
    c = np.concatenate([np.zeros((1, 2)), np.cumsum(zero, axis=0)])
    cv = np.concatenate([[0], np.cumsum(valid)])
    out = np.full((n, 2), np.nan)
    if n >= width:
        sums = c[width:] - c[:-width]
        counts = cv[width:] - cv[:-width]
        full = counts == width
        out[half:n - half][full] = sums[full] / width
    return out


def walking_heading(t_s: FloatArray, walk_pos_m: FloatArray, min_speed_mps: float = MIN_WALK_SPEED_MPS) -> FloatArray:
    """(K,) ENU yaw (rad) of the walking path's velocity (central differences); NaN where slower than
    ``min_speed_mps`` or undefined.
    """
    if t_s.size < 3:
        return np.full(t_s.size, np.nan)
    v = np.gradient(walk_pos_m, t_s, axis=0)
    yaw = np.arctan2(v[:, 1], v[:, 0])
    slow = ~(np.hypot(v[:, 0], v[:, 1]) >= min_speed_mps)
    yaw[slow] = np.nan
    return yaw


def _mocap_truth(path: Path, rec: Recording, alignment_s: float, align_source: str
                 ) -> tuple[GroundTruth, dict[str, Any], list[str]]:
    rate, pos, rot = _mocap_arrays(path)
    k = pos.shape[0]
    if k < 2:
        raise InputError(f"only {k} motion-capture frames", source=str(path), field="RigidBodies.Positions")
    warnings: list[str] = []
    t0 = rec.origin_ns / 1e9
    t_frame = np.arange(k) / rate - alignment_s - t0          # on the recording's t_s axis
    rot_ok = np.all(np.isfinite(rot), axis=(1, 2))
    q = np.full((k, 4), np.nan)
    if rot_ok.any():
        q[rot_ok] = quat.from_rotmat(rot[rot_ok])
    start, end = rec.time_span_s()
    if not np.any((t_frame >= start) & (t_frame <= end)):
        raise InputError(f"no motion-capture frame falls within the phone's recording with this alignment "
                         f"({alignment_s} s): frames at {t_frame[0] + t0:.1f}-{t_frame[-1] + t0:.1f} s, phone "
                         f"samples at {start + t0:.1f}-{end + t0:.1f} s", source=align_source, line=1)
    glitch = rotation_glitches(t_frame, q)
    refined = 0.0
    if rec.has("gyro") and rot_ok.sum() > 10 * rate:
        q_clean = np.where(glitch[:, None], np.nan, q)
        refined = refine_alignment(t_frame, q_clean, rec.t_s("gyro"), rec.values("gyro"))
        t_frame = t_frame + refined
    elif not rec.has("gyro"):
        warnings.append("no gyroscope: timeAlignment.txt used as it is (not refined)")
    q[glitch] = np.nan
    pos_ok = np.all(np.isfinite(pos), axis=1)
    hidden = int(np.count_nonzero(~(pos_ok & rot_ok)))
    if hidden:
        warnings.append(f"{hidden} of {k} motion-capture frames hidden (NaN): left out of the truth")
    if glitch.any():
        warnings.append(f"{int(glitch.sum())} motion-capture frames in rotation glitches: attitude truth NaN there")
    if pos_ok.sum() < 2:
        raise InputError("fewer than two motion-capture frames with a position", source=str(path),
                         field="RigidBodies.Positions")
    if rec.has("mag"):
        meta_azimuth = field_azimuth_deg(t_frame, q, rec.t_s("mag"), rec.values("mag"), 0.5 / rate)
    else:
        meta_azimuth = None
    walk = walking_path(t_frame, pos)
    positions = PositionTruth(t_frame[pos_ok], pos[pos_ok], kind="dense", frame="enu")
    extra = {"trajectory_t_s": t_frame, "q_nb": q, "walk_pos_m": walk,
             "walking_heading_rad": walking_heading(t_frame, walk)}
    meta = {"mocap_file": path.name, "mocap_rate_hz": rate, "mocap_frames": k, "mocap_hidden_frames": hidden,
            "mocap_glitch_frames": int(glitch.sum()), "time_alignment_file_s": alignment_s,
            "time_alignment_s": alignment_s - refined, "field_azimuth_mocap_deg": meta_azimuth}
    return GroundTruth(positions=positions, extra=extra), meta, warnings
