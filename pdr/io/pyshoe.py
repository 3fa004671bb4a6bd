"""PyShoe VICON trials (Wagstaff et al. 2020): foot-mounted IMU ``.mat`` files with dense VICON truth.

One trial per ``.mat`` file (``scipy.io.loadmat``; also ``.mat.gz``):

``imu`` (N, 6)
    ax, ay, az in m/s^2 (specific force, sensor frame) and gx, gy, gz in rad/s: already SI, not converted.
``ts`` (1, N)
    seconds (relative clock); kept as ``t_ns = round(ts * 1e9)``.
``gt`` (N, 3)
    VICON foot position in metres at every IMU sample -> ``truth.positions`` (kind ``dense``, frame ``map``:
    the motion-capture frame is not north-aligned) as ``(x, -y, z)``: the stored frame is left-handed, so its
    y axis is negated (:data:`VICON_TO_RIGHT_HANDED`) to give the right-handed, z-up frame the truth of a
    :class:`~pdr.recording.Recording` is expressed in. Evidence: ``gt`` z rises with the foot (z is up); the
    IMU data are self-consistent only as a right-handed set (x forward, y right, z down: at rest
    ``az ~ -9.8``; negating the gyroscope or one accelerometer axis makes the ZUPT-aided INS fail), and a
    right-handed ENU track matches ``gt`` x-y by a rotation only after a mirror (2-D ARMSE 0.06 m against
    0.9 m). PyShoe's own INS (``ins_tools/EKF.py``) integrates in a z-down frame (gravity ``+g`` on z), whose
    x-y plane has the stored frame's handedness, which is why its rotation-only scorer works on ``gt`` as
    stored.
``zv_<detector>_opt`` (1, N)
    zero-velocity labels of each detector (shoe, ared, amvd, mbgtd, vicon) at its optimal threshold ->
    ``truth.extra['zero_velocity_<detector>']`` (N,) bool; ``truth.extra['zero_velocity']`` is the label of
    ``best_detector`` (what PyShoe trained on) and ``truth.extra['zero_velocity_t_s']`` their times.
``trial_error``, ``best_detector``, ``best_error``, ``G_<detector>_opt``
    reference ZUPT-INS RMSE (m) per detector and optimal thresholds -> ``meta``. The third slot of
    ``trial_error``, documented as amvd's, holds ared's error again: PyShoe's ``run_threshold_optimization.py``
    builds the array as ``[shoe, ared, ared, mbgtd, vicon]`` (it equals the second slot in all 28 shared files), so
    ``meta['trial_error_m']`` has no amvd entry.

The files do not say which foot carried the IMU: the device role is ``right_foot`` with
``meta['foot_side'] = 'unknown'``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pdr.errors import InputError
from pdr.io import matfile
from pdr.io.text import timestamps_ns
from pdr.io.time_order import keep_increasing
from pdr.recording import DeviceInfo, GroundTruth, PositionTruth, Recording, SensorStream

FORMAT = "pyshoe"
DESCRIPTION = "PyShoe VICON trial .mat (foot IMU 200 Hz: imu, ts, gt VICON positions, zero-velocity labels)"

#: Zero-velocity detectors of the PyShoe files (labels ``zv_<detector>_opt``, thresholds ``G_<detector>_opt``).
DETECTORS: tuple[str, ...] = ("shoe", "ared", "amvd", "mbgtd", "vicon")
#: What each slot of ``trial_error`` really holds (module doc: the amvd slot repeats ared).
TRIAL_ERROR_SLOTS: tuple[str | None, ...] = ("shoe", "ared", None, "mbgtd", "vicon")
IMU_MODEL = "LORD MicroStrain 3DM-GX3-25"
#: Axis signs taking the stored (left-handed) VICON positions to a right-handed z-up frame.
VICON_TO_RIGHT_HANDED = np.array([1.0, -1.0, 1.0])


def sniff(path: str | Path) -> bool:
    """A ``.mat`` file with variables ``imu`` and ``ts`` (and no SensorConnect/IPIN variables)."""
    names = matfile.variables(path)
    return {"imu", "ts"} <= names


def read(path: str | Path) -> Recording:
    """Read a PyShoe trial into a foot :class:`Recording` with VICON position truth and zero-velocity labels."""
    p = Path(path)
    source = str(p)
    mat = matfile.load(p)
    imu = matfile.array(mat, "imu", source, ncol=6)
    ts = matfile.array(mat, "ts", source, vector=True)
    if ts.size != imu.shape[0]:
        raise InputError(f"{ts.size} timestamps but {imu.shape[0]} imu rows", source=source, field="ts")
    if ts.size == 0:
        raise InputError("no samples", source=source, field="imu")
    t_ns = timestamps_ns(ts, source, "ts", scale=1e9)
    warnings: list[str] = []
    keep = keep_increasing(t_ns, source, "ts", warnings)  # the same rows of imu, gt and the labels are dropped
    t_ns, imu = t_ns[keep], imu[keep]
    t0 = int(t_ns[0])
    t_s = (t_ns - t0).astype(np.float64) / 1e9
    streams = {"acc": SensorStream("acc", t_ns, imu[:, :3]), "gyro": SensorStream("gyro", t_ns, imu[:, 3:])}

    positions = None
    if "gt" in mat:
        gt = matfile.array(mat, "gt", source, ncol=3, finite=False)
        if gt.shape[0] != ts.size:
            raise InputError(f"{gt.shape[0]} VICON rows but {ts.size} timestamps", source=source, field="gt")
        gt = gt[keep]
        ok = np.all(np.isfinite(gt), axis=1)
        if not ok.all():
            warnings.append(f"{int((~ok).sum())} VICON samples without a position (NaN) left out of the truth")
        positions = PositionTruth(t_s[ok], gt[ok] * VICON_TO_RIGHT_HANDED, kind="dense", frame="map")

    extra: dict[str, np.ndarray] = {}
    for det in DETECTORS:
        key = f"zv_{det}_opt"
        if key in mat:
            zv = matfile.array(mat, key, source, vector=True)
            if zv.size != ts.size:
                raise InputError(f"{zv.size} labels but {ts.size} timestamps", source=source, field=key)
            extra[f"zero_velocity_{det}"] = zv[keep] != 0
    best = matfile.scalar(mat, "best_detector")
    best = str(best).strip() if best is not None else None
    if best is not None and f"zero_velocity_{best}" in extra:
        extra["zero_velocity"] = extra[f"zero_velocity_{best}"]
    if extra:
        extra["zero_velocity_t_s"] = t_s

    meta: dict[str, object] = {"foot_side": "unknown", "imu_model": IMU_MODEL}
    if "trial_error" in mat:
        err = matfile.array(mat, "trial_error", source, vector=True, finite=False)
        if err.size == len(TRIAL_ERROR_SLOTS):
            meta["trial_error_m"] = {d: float(e) for d, e in zip(TRIAL_ERROR_SLOTS, err, strict=True) if d}
    if best is not None:
        meta["best_detector"] = best
    best_error = matfile.scalar(mat, "best_error")
    if best_error is not None:
        meta["best_error_m"] = float(best_error)
    thresholds = {d: float(matfile.scalar(mat, f"G_{d}_opt")) for d in DETECTORS
                  if matfile.scalar(mat, f"G_{d}_opt") is not None}
    if thresholds:
        meta["zv_thresholds"] = thresholds
    return Recording(streams, device=DeviceInfo(platform="imu", model=IMU_MODEL, role="right_foot",
                                                placement="foot", device_id=p.name.split(".")[0]),
                     t0_ns=t0, truth=GroundTruth(positions=positions, extra=extra), source=source, format=FORMAT,
                     warnings=tuple(warnings), meta=meta)
