"""Foot navigation of a :class:`~pdr.recording.Recording`: input checks, detector, ZUPT-aided INS.

The entry point of ``pdr foot``. It refuses recordings that are not from a foot-mounted IMU (a phone in a
pocket never comes to rest once per step), puts accelerometer and gyroscope on one time base, and reports
what it found wrong in the input (start in motion, saturated samples, gaps, rate changes) as warnings.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.foot.bc import BCConfig, run_bc
from pdr.foot.detectors import DetectorConfig, detect, stationary_gyro_bias
from pdr.foot.filterbank import FilterBankConfig, run_filterbank
from pdr.foot.zupt import Segmentation, ZuptConfig, run_zupt
from pdr.preprocess import find_gaps
from pdr.recording import Recording

Array = NDArray[np.float64]

#: Navigation methods of ``pdr foot``: ZUPT-aided INS, with step-wise dead reckoning, filter bank (seed 002
#: eq. 12 and the return-to-same-height model of eq. 13), belief condensation (seed 000).
METHODS: tuple[str, ...] = ("zupt", "stepwise", "filterbank", "filterbank-height", "bc")

#: ZUPT-INS settings (``ZuptConfig`` fields, ``pdr foot --zaru/--imu-samples``) and offline options
#: (``smooth``, ``gyro_bias`` of :func:`navigate`) each method has; other methods refuse them.
METHOD_OPTIONS: dict[str, frozenset[str]] = {
    "zupt": frozenset({"zaru", "interval_samples", "smooth", "gyro_bias"}),
    "stepwise": frozenset({"zaru", "interval_samples"}),
    "filterbank": frozenset({"interval_samples"}),
    "filterbank-height": frozenset({"interval_samples"}),
    "bc": frozenset(),
}


def unsupported_options(method: str, zupt: ZuptConfig | None = None, smooth: bool = False,
                        gyro_bias: bool = False) -> list[str]:
    """The settings turned on in ``zupt`` (``zaru``, ``interval_samples``) or by ``smooth``/``gyro_bias`` that
    ``method`` does not have (:data:`METHOD_OPTIONS`), in that order.
    """
    z = zupt or ZuptConfig()
    wanted = {"zaru": z.zaru, "interval_samples": z.interval_samples, "smooth": smooth, "gyro_bias": gyro_bias}
    return [name for name, on in wanted.items() if on and name not in METHOD_OPTIONS[method]]


@dataclass(frozen=True)
class FootImu:
    """Accelerometer and gyroscope of one foot on a common time base.

    Attributes
    ----------
    t_s
        (N,) seconds on the recording's time axis.
    acc_b
        (N, 3) specific force, m/s^2, sensor frame.
    gyro_b
        (N, 3) angular rate, rad/s, sensor frame.
    rate_hz
        Sampling rate from the median interval over the first RATE_WINDOW_S seconds, Hz.
    clock_offset_s
        Add to ``t_s`` for the log's own clock (``t0_ns / 1e9``).
    warnings
        What was found wrong in the input.
    """

    t_s: Array
    acc_b: Array
    gyro_b: Array
    rate_hz: float
    clock_offset_s: float
    warnings: tuple[str, ...] = ()


def saturated_samples(values: Array, min_run: int = 3) -> int:
    """Number of samples that sit at the largest absolute value of their axis for ``min_run`` samples or more.

    A clipped sensor repeats its full-scale reading: runs of identical extreme values betray it.
    """
    v = np.asarray(values, dtype=np.float64)
    count = 0
    for axis in range(v.shape[1]):
        x = v[:, axis]
        peak = float(np.max(np.abs(x)))
        if peak == 0.0:
            continue
        at_peak = np.abs(x) >= peak * (1.0 - 1e-9)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], at_peak.astype(np.int8), [0]])))
        runs = edges[1::2] - edges[::2]
        count += int(np.sum(runs[runs >= min_run]))
    return count


#: Length of the start of a recording whose median sample interval defines its sampling rate, s.
RATE_WINDOW_S = 5.0


def sampling_rate_hz(t_s: Array) -> float:
    """Sampling rate (Hz) from the median interval over the first :data:`RATE_WINDOW_S` of the samples.

    The rate sets sample counts (detector windows, Algorithm 1 counters). Taking it from the start of the
    recording rather than the whole lets an online navigator (:mod:`pdr.foot.online`) fix it as soon as that
    much has arrived, so batch and online processing use the same counts.
    """
    t = np.asarray(t_s, dtype=np.float64)
    head = t[: max(3, int(np.searchsorted(t, t[0] + RATE_WINDOW_S)))]
    return float(1.0 / np.median(np.diff(head)))


def check_foot_recording(recording: Recording) -> None:
    """Refuse recordings that cannot be foot IMU data (a phone, or no accelerometer and gyroscope)."""
    src = recording.source or None
    if not recording.device.is_foot:
        raise InputError("this is a phone recording (device role 'phone'); foot navigation needs a foot-mounted "
                         "IMU: use 'pdr track' for phone logs", source=src)
    for kind in ("acc", "gyro"):
        if not recording.has(kind):
            raise InputError(f"foot navigation needs '{kind}' samples", source=src, field=kind)


def foot_imu(recording: Recording) -> FootImu:
    """Extract and check the foot IMU streams of a recording.

    Raises
    ------
    InputError
        The recording has no accelerometer or gyroscope, or comes from a phone.
    """
    src = recording.source or None
    check_foot_recording(recording)
    warnings = list(recording.warnings)
    t = recording.t_s("acc")
    acc = np.array(recording.values("acc"))
    tg = recording.t_s("gyro")
    gyro = np.array(recording.values("gyro"))
    if tg.shape != t.shape or not np.array_equal(tg, t):
        # Different sample instants: interpolate the gyroscope onto the accelerometer's times.
        inside = (t >= tg[0]) & (t <= tg[-1])
        t, acc = t[inside], acc[inside]
        gyro = np.stack([np.interp(t, tg, gyro[:, i]) for i in range(3)], axis=1)
        warnings.append("accelerometer and gyroscope have different timestamps: gyroscope interpolated")
    if t.size < 10:
        raise InputError(f"only {t.size} IMU samples", source=src, field="acc")
    dt = np.diff(t)
    rate = sampling_rate_hz(t)
    gaps = find_gaps(t, factor=5.0)
    if gaps:
        longest = max(g.end_s - g.start_s for g in gaps)
        warnings.append(f"{len(gaps)} gap(s) in the IMU samples (longest {longest:.3f} s): the filter "
                        "predicts across them")
    half = t.size // 2
    if t.size > 200:
        r1, r2 = 1.0 / np.median(dt[:half]), 1.0 / np.median(dt[half:])
        if abs(r1 - r2) > 0.05 * max(r1, r2):
            warnings.append(f"sampling rate changes from {r1:.1f} Hz to {r2:.1f} Hz")
    for kind, values in (("accelerometer", acc), ("gyroscope", gyro)):
        n_sat = saturated_samples(values)
        if n_sat:
            warnings.append(f"{n_sat} {kind} samples look saturated (repeated full-scale value)")
    return FootImu(t, acc, gyro, rate, recording.origin_ns / 1e9, tuple(warnings))


def labels_at(t_s: Array, label_t_s: ArrayLike, flags: ArrayLike) -> NDArray[np.bool_]:
    """(N,) boolean labels at times ``t_s`` (s): each the label nearest in time among ``(label_t_s, flags)``."""
    lt = np.asarray(label_t_s, dtype=np.float64)
    f = np.asarray(flags, dtype=bool)
    if lt.ndim != 1 or lt.shape != f.shape or lt.size == 0 or np.any(np.diff(lt) <= 0):
        raise InputError("zero-velocity labels need one flag per time, times strictly increasing",
                         field="zero_velocity")
    if lt.size == 1:
        return np.full(np.shape(t_s), bool(f[0]))
    i = np.clip(np.searchsorted(lt, t_s), 1, lt.size - 1)        # lt[i - 1] < t <= lt[i] inside the span
    i = np.where(np.abs(lt[i - 1] - t_s) <= np.abs(lt[i] - t_s), i - 1, i)
    return np.asarray(f[i])


def navigate(recording: Recording, method: str = "zupt", detector: DetectorConfig | None = None,
             zupt: ZuptConfig | None = None, segmentation: Segmentation | None = None,
             filterbank: FilterBankConfig | None = None, smooth: bool = True,
             gyro_bias: bool = False,
             zero_velocity: tuple[ArrayLike, ArrayLike] | None = None) -> tuple[FootImu, Any]:
    """Foot-mounted navigation of a recording.

    Parameters
    ----------
    recording
        A foot IMU recording.
    method
        ``zupt`` (ZUPT-aided INS, seed 001 eqs. 1-5), ``stepwise`` (with the step segmentation and step-wise
        dead reckoning of Algorithm 1), ``filterbank`` / ``filterbank-height`` (seed 002, eqs. 12 / 13), ``bc``
        (belief condensation with the expert context, seed 000).
    detector, zupt, segmentation, filterbank
        Settings (defaults when omitted). The heading drift elimination settings of ``zupt`` (``hde_*``,
        :mod:`pdr.foot.drift`) apply to every method: ``ZuptConfig(hde_directions=0)`` turns it off for all.
    smooth
        ``zupt`` only: the RTS fixed-interval smoother over the whole recording (:func:`pdr.foot.zupt.run_zupt`;
        default on, since this function processes a whole recording offline; :mod:`pdr.foot.online` keeps the
        causal filter); other methods ignore it.
    gyro_bias
        ``zupt`` only, offline: remove the gyroscope bias measured over the still samples of the whole recording
        (:func:`pdr.foot.detectors.stationary_gyro_bias`) before navigating; other methods ignore it.
    zero_velocity
        ``(t_s, flags)``: zero-velocity labels to use instead of the detector's (e.g. a data set's reference
        labels, to separate the detector's share of an error from the filter's), taken at each IMU sample from
        the label nearest in time (s, the recording's clock).

    Returns
    -------
    The checked IMU input and the track: a :class:`ZuptTrack` (warnings of both combined in it) or a
    :class:`~pdr.foot.filterbank.FilterBankTrack`; both have ``t_s``, ``pos_n``, ``vel_n``, ``q_nb``, ``yaw``,
    ``zero_velocity`` and ``pos_var``.
    """
    if method not in METHODS:
        raise InputError(f"unknown foot navigation method '{method}'; expected one of {METHODS}", field="method")
    imu = foot_imu(recording)
    zv = (detect(imu.acc_b, imu.gyro_b, imu.rate_hz, detector) if zero_velocity is None
          else labels_at(imu.t_s, *zero_velocity))
    if method == "bc":
        bc = BCConfig(hde=zupt or ZuptConfig())
        bc_track = run_bc(imu.t_s, imu.acc_b, imu.gyro_b, zv, bc)
        return imu, replace(bc_track, warnings=imu.warnings + bc_track.warnings)
    if method.startswith("filterbank"):
        variant = "height" if method == "filterbank-height" else "speed"
        fb = filterbank or FilterBankConfig(variant=variant, zupt=zupt or ZuptConfig())
        if fb.variant != variant:
            fb = replace(fb, variant=variant)
        fb_track = run_filterbank(imu.t_s, imu.acc_b, imu.gyro_b, zv, fb)
        return imu, replace(fb_track, warnings=imu.warnings + fb_track.warnings)
    seg = (segmentation or Segmentation()) if method == "stepwise" else None
    gyro = imu.gyro_b
    if gyro_bias and method == "zupt":
        gyro = gyro - stationary_gyro_bias(imu.acc_b, gyro, imu.rate_hz)
    track = run_zupt(imu.t_s, imu.acc_b, gyro, zv, zupt, seg, rate_hz=imu.rate_hz,
                     smooth=smooth and seg is None)
    return imu, replace(track, warnings=imu.warnings + track.warnings)
