"""Checks that a record is fit for an Allan-variance analysis: uniform sampling, gaps, motion.

The estimators need uniformly spaced samples of a sensor at rest. Before computing anything:

- sampling: the median interval gives the rate; the robust jitter (1.4826 MAD of the intervals over
  their median) above ``jitter_tolerance`` means non-uniform sampling, handled by linear resampling
  onto a uniform grid (flagged: interpolation lowers the Allan deviation at the shortest taus);
- gaps: intervals longer than ``gap_factor`` times the median split the record; with
  ``gap_policy="longest"`` the longest gap-free segment is analysed (flagged), with ``"error"`` an
  :class:`InputError` names the first gap;
- motion: in windows of ``window_s``, a standard deviation over ``std_ratio`` times the median window's
  (handling, vibration), for the gyro a window mean over ``rate_ratio`` times the scatter of the
  window means (turning), for the accelerometer a tilt of the mean specific force over ``tilt_deg`` from
  the record's median direction; motion intervals are reported and flag the report
  (``motion_policy="error"`` refuses the record instead).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.recording import SensorStream

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StreamQuality:
    """What was found in (and done to) one stream before the analysis. Times in seconds of the stream."""

    kind: str
    n_samples: int
    duration_s: float
    rate_hz: float
    jitter: float
    gaps: tuple[tuple[float, float], ...]
    segment_s: tuple[float, float]
    n_used: int
    resampled: bool
    motion: tuple[tuple[float, float, str], ...]
    flags: tuple[str, ...]


def _segments(dt: FloatArray, limit: float) -> list[tuple[int, int]]:
    """[start, stop) sample index ranges between gaps."""
    cut = np.flatnonzero(dt > limit) + 1
    edges = np.concatenate(([0], cut, [dt.size + 1]))
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def detect_motion(values: FloatArray, rate_hz: float, kind: str, *, window_s: float = 1.0, std_ratio: float = 5.0,
                  tilt_deg: float = 2.0, rate_ratio: float = 10.0) -> list[tuple[float, float, str]]:
    """Intervals ``(start_s, end_s, reason)`` (from the first sample) where the sensor was not at rest."""
    w = max(8, int(round(window_s * rate_hz)))
    nw = values.shape[0] // w
    if nw < 3:
        return []
    win = values[: nw * w].reshape(nw, w, -1)
    var = win.var(axis=1).sum(axis=1)
    med = float(np.median(var))
    moving = np.zeros(nw, dtype=bool)
    reason = np.full(nw, "", dtype=object)
    if med > 0:
        loud = var > std_ratio**2 * med
        moving |= loud
        reason[loud] = f"window standard deviation over {std_ratio:g} x the median"
    if kind in ("gyro", "gyro_uncal"):
        # turning at a steady rate: window means far outside their own static scatter
        mean = win.mean(axis=1)
        centre = np.median(mean, axis=0)
        spread = np.maximum(1.4826 * np.median(np.abs(mean - centre), axis=0),
                            np.sqrt(np.median(win.var(axis=1), axis=0) / w))
        turning = np.any(np.abs(mean - centre) > rate_ratio * np.maximum(spread, np.finfo(float).tiny), axis=1)
        reason[turning & ~moving] = f"mean rate over {rate_ratio:g} x the static scatter of window means"
        moving |= turning
    if kind in ("acc", "acc_uncal") and values.shape[1] == 3:
        mean = win.mean(axis=1)
        ref = np.median(mean, axis=0)
        if np.linalg.norm(ref) > 0:
            cosang = mean @ ref / (np.linalg.norm(mean, axis=1) * np.linalg.norm(ref) + 1e-300)
            tilt = np.rad2deg(np.arccos(np.clip(cosang, -1.0, 1.0)))
            tilted = tilt > tilt_deg
            reason[tilted & ~moving] = f"specific force tilted over {tilt_deg:g} deg from the median direction"
            moving |= tilted
    out: list[tuple[float, float, str]] = []
    idx = np.flatnonzero(moving)
    if idx.size:
        breaks = np.flatnonzero(np.diff(idx) > 1) + 1
        for run in np.split(idx, breaks):
            out.append((float(run[0] * w / rate_hz), float((run[-1] + 1) * w / rate_hz), str(reason[run[0]])))
    return out


def prepare_stream(stream: SensorStream, *, gap_policy: str = "longest", motion_policy: str = "flag",
                   jitter_tolerance: float = 0.02, gap_factor: float = 1.5, window_s: float = 1.0,
                   std_ratio: float = 5.0, tilt_deg: float = 2.0) -> tuple[FloatArray, float, StreamQuality]:
    """Uniform samples of ``stream`` for the estimators, with the checks of the module docstring.

    Returns
    -------
    values
        (n, k) float64 samples on a uniform grid, in the stream's SI unit.
    rate_hz
        Their sampling rate.
    quality
        The findings; ``flags`` says in words what affects the results.
    """
    if gap_policy not in ("longest", "error") or motion_policy not in ("flag", "error"):
        raise InputError("gap_policy must be 'longest' or 'error' and motion_policy 'flag' or 'error'",
                         field="policy")
    name = f"stream '{stream.kind}'"
    n = len(stream)
    if n < 4:
        raise InputError(f"has {n} samples; an Allan variance needs a long static record", source=name)
    t = (stream.t_ns - stream.t_ns[0]).astype(np.float64) / 1e9
    dt = np.diff(t)
    dt_med = float(np.median(dt))
    if dt_med <= 0:
        raise InputError("median sampling interval is zero", source=name)
    jitter = float(1.4826 * np.median(np.abs(dt - dt_med)) / dt_med)
    flags: list[str] = []
    segs = _segments(dt, gap_factor * dt_med)
    gaps = tuple((float(t[a - 1]), float(t[a] - t[a - 1])) for a, _ in segs[1:])
    if gaps:
        if gap_policy == "error":
            g0, gl = gaps[0]
            raise InputError(f"gap of {gl:.6g} s after t = {g0:.6g} s ({len(gaps)} gaps in all); "
                             "the Allan variance needs an unbroken record (use the longest segment instead)",
                             source=name)
        a, b = max(segs, key=lambda s: s[1] - s[0])
        total, longest = sum(g[1] for g in gaps), max(g[1] for g in gaps)
        flags.append(f"{len(gaps)} gaps (total {total:.6g} s, longest {longest:.6g} s); "
                     f"analysed the longest unbroken segment, {t[a]:.6g}-{t[b - 1]:.6g} s")
    else:
        a, b = 0, n
    ts = t[a:b]
    vals = np.asarray(stream.values[a:b], dtype=np.float64)
    rate = 1.0 / dt_med
    resampled = False
    if jitter > jitter_tolerance and ts.size >= 4:
        grid = ts[0] + np.arange(int(np.floor((ts[-1] - ts[0]) * rate)) + 1) / rate
        vals = np.column_stack([np.interp(grid, ts, vals[:, j]) for j in range(vals.shape[1])])
        resampled = True
        flags.append(f"non-uniform sampling (timing jitter {100 * jitter:.3g} % of the {dt_med * 1e3:.4g} ms "
                     f"interval): linearly resampled to {rate:.6g} Hz, which lowers the Allan deviation at the "
                     "shortest taus")
    motion = detect_motion(vals, rate, stream.kind, window_s=window_s, std_ratio=std_ratio, tilt_deg=tilt_deg)
    motion = [(s + float(ts[0]), e + float(ts[0]), r) for s, e, r in motion]
    if motion:
        total = sum(e - s for s, e, _ in motion)
        msg = (f"motion detected in {len(motion)} interval(s), {total:.6g} s in all (first at {motion[0][0]:.6g} s: "
               f"{motion[0][2]}); the record is not static, the Allan curve mixes motion with sensor noise")
        if motion_policy == "error":
            raise InputError(msg, source=name)
        flags.append(msg)
    quality = StreamQuality(kind=stream.kind, n_samples=n, duration_s=float(t[-1]), rate_hz=float(rate),
                            jitter=jitter, gaps=gaps, segment_s=(float(ts[0]), float(ts[-1])),
                            n_used=int(vals.shape[0]),
                            resampled=resampled, motion=tuple(motion), flags=tuple(flags))
    return vals, float(rate), quality
