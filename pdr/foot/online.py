"""Online foot navigation: the step-wise ZUPT-aided INS fed batch by batch (seed 001 Sec. 3, Algorithm 1).

:class:`OnlineFootNavigator` gives, batch after batch, the steps that :func:`pdr.foot.navigate.navigate` with
``method="stepwise"`` finds on the whole recording, at a cost proportional to the batch:

* the zero-velocity flag of sample ``k`` depends on samples ``k - before .. k + after``
  (:func:`pdr.foot.detectors.detector_reach`: the statistic's window and the adaptive threshold's +-0.6 s), so
  a flag is final once sample ``k + after`` has arrived; the detector is re-run on the new samples plus the
  ``before + after`` samples of context kept from earlier batches;
* the filter (:func:`pdr.foot.zupt.run_kernel`, the one compiled loop of :func:`pdr.foot.zupt.run_zupt`) runs
  over the samples with final flags and resumes from its saved state (nominal position, velocity and
  attitude, the 9x9 covariance, the step-wise dead reckoning ``(x_l, chi_l)`` and the Algorithm 1 counters);
* the sampling rate (sample counts of windows and counters) is fixed from the first
  :data:`pdr.foot.navigate.RATE_WINDOW_S` seconds, as :func:`pdr.foot.navigate.foot_imu` defines it, and the
  coarse self-initialisation waits for the first stationary run to end or to reach its averaging length.

:meth:`OnlineFootNavigator.finish` flags the last samples as the batch detector does at the end of a recording
(nearest-sample padding), so ``update`` over all batches followed by ``finish`` equals the batch result up to
the rounding of the detector's running sums. The state is JSON-serialisable (:meth:`to_dict`) and restoring it
changes nothing.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.foot.detectors import DetectorConfig, adaptive_threshold, detector_reach, statistic, still_samples
from pdr.foot.navigate import RATE_WINDOW_S, check_foot_recording, sampling_rate_hz
from pdr.foot.stepwise import StepwiseDeadReckoning
from pdr.foot.strides import SwingsSinceReset
from pdr.foot.zupt import (
    FilterState,
    KernelSetup,
    Segmentation,
    StepIncrement,
    ZuptConfig,
    closing_step,
    kernel_setup,
    late_start_warning,
    run_kernel,
)
from pdr.recording import Recording
from pdr.strapdown import initial_attitude_from_gravity

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Gaps longer than this many sample intervals are reported (as :func:`pdr.foot.navigate.foot_imu` does).
GAP_FACTOR = 5.0


@dataclass(frozen=True)
class FootStep:
    """One reset of the step-wise navigation (one stride of the foot).

    Attributes
    ----------
    t_s
        Time of the reset on the log's own clock (``t_ns / 1e9``), s.
    pos_n
        (3,) dead-reckoned position ``x_l`` of the foot at the reset, m, ENU from the start.
    yaw
        Yaw of the sensor at the reset, rad, counter-clockwise from east.
    increment
        The step increment ``(dp_l, dpsi_l, cov)`` of eqs. 7-8 (``t_s`` on the log's clock, ``index`` the
        sample index counted from the first sample of the session) and whether it closes a stride.
    """

    t_s: float
    pos_n: Array
    yaw: float
    increment: StepIncrement

    @property
    def stride(self) -> bool:
        """Whether the foot swung since the reset before (:class:`pdr.foot.strides.SwingsSinceReset`): False for
        the resets Algorithm 1 makes while the foot stands (one every ``c_max_s``), which close no stride
        (:attr:`pdr.step_increment.StepIncrement.stride`).
        """
        return self.increment.stride


def _ints(a: Any) -> IntArray:
    return np.asarray(a, dtype=np.int64).reshape(-1)


def _rows(a: Any) -> Array:
    return np.asarray(a, dtype=np.float64).reshape(-1, 3)


class OnlineFootNavigator:
    """Step-wise foot navigation of one foot IMU, batch by batch.

    Parameters
    ----------
    detector, zupt, segmentation
        Settings as for :func:`pdr.foot.navigate.navigate` (defaults when omitted).
    """

    def __init__(self, detector: DetectorConfig | None = None, zupt: ZuptConfig | None = None,
                 segmentation: Segmentation | None = None) -> None:
        self.detector = detector or DetectorConfig()
        self.zupt = zupt or ZuptConfig()
        self.segmentation = segmentation or Segmentation()
        self.origin_ns: int | None = None      # time axis t_s = (t_ns - origin_ns) / 1e9
        self.first_t_ns: int | None = None     # first navigable sample
        self.rate_hz: float | None = None
        self.n_seen = 0                        # samples received (global index of the next one)
        self.buf_start = 0                     # global index of the buffer's first row
        self.buf_t_ns = np.zeros(0, dtype=np.int64)
        self.buf_acc = np.zeros((0, 3))
        self.buf_gyro = np.zeros((0, 3))
        self.flags_done = 0                    # samples whose zero-velocity flag is final
        self.gaps_checked = 0                  # samples whose interval to the previous one was checked
        self.run_start = -1                    # before initialisation: start of the trailing stationary run
        self.start_index = -1                  # first navigated sample (the initial stationary run), -1: not yet
        self.nav_next = 0                      # next sample for the filter
        self.filter: FilterState | None = None
        self.swings = SwingsSinceReset()       # which resets close a stride (not a stand)
        # Different accelerometer and gyroscope instants: the last gyroscope sample and acc samples after it.
        self.gyro_last: tuple[int, list[float]] | None = None
        self.acc_pending_t_ns = np.zeros(0, dtype=np.int64)
        self.acc_pending = np.zeros((0, 3))
        self.warned: list[str] = []            # warning kinds already reported once
        self.warnings: list[str] = []          # new warnings, taken by :meth:`take_warnings`

    # -- public API ---------------------------------------------------------------------------------------
    def update(self, recording: Recording) -> list[FootStep]:
        """Add a batch of foot IMU samples; returns the steps whose resets became final.

        Raises
        ------
        InputError
            Not foot IMU data, or samples not after those already received.
        """
        check_foot_recording(recording)
        if self.origin_ns is None:
            self.origin_ns = recording.origin_ns
        t_ns, acc, gyro = self._imu_samples(recording)
        if t_ns.size:
            if self.buf_t_ns.size and t_ns[0] <= self.buf_t_ns[-1]:
                raise InputError(f"samples at {(t_ns[0] - self.origin_ns) / 1e9:.3f} s are not after those already "
                                 "received; batches of a foot IMU must arrive in time order",
                                 source=recording.source or None, field="acc")
            if self.first_t_ns is None:
                self.first_t_ns = int(t_ns[0])
            self.buf_t_ns = np.concatenate([self.buf_t_ns, t_ns])
            self.buf_acc = np.concatenate([self.buf_acc, acc])
            self.buf_gyro = np.concatenate([self.buf_gyro, gyro])
            self.n_seen += t_ns.size
        return self._advance(final=False)

    def finish(self) -> list[FootStep]:
        """End of the recording: flag and navigate the last samples; returns the remaining steps, the last one at the
        last sample when the recording ends a stride no reset closed (:func:`pdr.foot.zupt.closing_step`). A session
        calls it on a copy (its provisional tail): the navigator itself closes that stride by its next reset.
        """
        steps = self._advance(final=True) + self._close_stride()
        if self.start_index < 0 and self.n_seen and "no_rest" not in self.warned:
            self.warned.append("no_rest")
            self.warnings.append("the foot never came to rest for the coarse initialisation: no track (is this a "
                                 "foot-mounted IMU?)")
        return steps

    def take_warnings(self) -> list[str]:
        """The warnings found since the last call."""
        out, self.warnings = self.warnings, []
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable state (floats round-trip exactly through JSON)."""
        return {
            "config": {"detector": asdict(self.detector), "zupt": asdict(self.zupt),
                       "segmentation": asdict(self.segmentation)},
            "origin_ns": self.origin_ns, "first_t_ns": self.first_t_ns, "rate_hz": self.rate_hz,
            "n_seen": self.n_seen, "buf_start": self.buf_start, "buf_t_ns": self.buf_t_ns.tolist(),
            "buf_acc": self.buf_acc.tolist(), "buf_gyro": self.buf_gyro.tolist(), "flags_done": self.flags_done,
            "gaps_checked": self.gaps_checked, "run_start": self.run_start, "start_index": self.start_index,
            "nav_next": self.nav_next, "filter": None if self.filter is None else self.filter.to_dict(),
            "gyro_last": None if self.gyro_last is None else [self.gyro_last[0], list(self.gyro_last[1])],
            "acc_pending_t_ns": self.acc_pending_t_ns.tolist(), "acc_pending": self.acc_pending.tolist(),
            "warned": list(self.warned), "warnings": list(self.warnings),
            "swings": self.swings.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> OnlineFootNavigator:
        """Restore a navigator saved by :meth:`to_dict`."""
        cfg = d["config"]
        nav = cls(DetectorConfig(**cfg["detector"]), ZuptConfig(**cfg["zupt"]), Segmentation(**cfg["segmentation"]))
        nav.origin_ns = d["origin_ns"]
        nav.first_t_ns = d["first_t_ns"]
        nav.rate_hz = d["rate_hz"]
        for name in ("n_seen", "buf_start", "flags_done", "gaps_checked", "run_start", "start_index", "nav_next"):
            setattr(nav, name, int(d[name]))
        nav.buf_t_ns = _ints(d["buf_t_ns"])
        nav.buf_acc, nav.buf_gyro = _rows(d["buf_acc"]), _rows(d["buf_gyro"])
        nav.filter = None if d["filter"] is None else FilterState.from_dict(d["filter"], nav.zupt)
        nav.gyro_last = None if d["gyro_last"] is None else (int(d["gyro_last"][0]), list(d["gyro_last"][1]))
        nav.acc_pending_t_ns, nav.acc_pending = _ints(d["acc_pending_t_ns"]), _rows(d["acc_pending"])
        nav.warned, nav.warnings = list(d["warned"]), list(d["warnings"])
        if d.get("swings") is not None:       # absent from states saved before strides were told from stands
            nav.swings = SwingsSinceReset.from_dict(d["swings"])
        return nav

    # -- input ----------------------------------------------------------------------------------------------
    def _imu_samples(self, recording: Recording) -> tuple[IntArray, Array, Array]:
        """Accelerometer and gyroscope on the accelerometer's instants (gyroscope interpolated if they differ)."""
        at, acc = recording.stream("acc").t_ns, np.asarray(recording.values("acc"))
        gt, gyro = recording.stream("gyro").t_ns, np.asarray(recording.values("gyro"))
        if self.gyro_last is None and not self.acc_pending_t_ns.size and np.array_equal(at, gt):
            return np.array(at, dtype=np.int64), np.array(acc), np.array(gyro)
        if "interp" not in self.warned:
            self.warned.append("interp")
            self.warnings.append("accelerometer and gyroscope have different timestamps: gyroscope interpolated")
        at = np.concatenate([self.acc_pending_t_ns, at])
        acc = np.concatenate([self.acc_pending, acc])
        if self.gyro_last is not None:
            gt = np.concatenate([[self.gyro_last[0]], gt])
            gyro = np.concatenate([[self.gyro_last[1]], gyro])
        if gt.size == 0:
            self.acc_pending_t_ns, self.acc_pending = at, acc
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3))
        self.gyro_last = (int(gt[-1]), [float(x) for x in gyro[-1]])
        after = at > gt[-1]
        self.acc_pending_t_ns, self.acc_pending = at[after], acc[after]
        inside = (at >= gt[0]) & ~after           # before the first gyroscope sample: dropped (as foot_imu)
        assert self.origin_ns is not None
        t = (at[inside] - self.origin_ns) / 1e9
        tg = (gt - self.origin_ns) / 1e9
        return (at[inside], acc[inside], np.stack([np.interp(t, tg, gyro[:, i]) for i in range(3)], axis=1))

    # -- processing -----------------------------------------------------------------------------------------
    def _t_s(self, t_ns: IntArray) -> Array:
        assert self.origin_ns is not None
        return (t_ns - np.int64(self.origin_ns)).astype(np.float64) / 1e9

    def _advance(self, final: bool) -> list[FootStep]:
        n = self.n_seen
        if n == 0:
            return []
        if self.rate_hz is None:
            if n < 3 or (not final and self.buf_t_ns[-1] - self.buf_t_ns[0] <= RATE_WINDOW_S * 1e9):
                return []
            self.rate_hz = sampling_rate_hz(self._t_s(self.buf_t_ns))
        rate = self.rate_hz
        self._check_gaps()
        before, after = detector_reach(rate, self.detector)
        z0 = self.flags_done
        z1 = n if final else n - after
        if z1 <= z0:
            return []
        # Flags of [z0, z1): every window inside the buffer, or at a true end of the recording.
        stat = statistic(self.buf_acc, self.buf_gyro, rate, self.detector)
        flags = (stat < adaptive_threshold(stat, rate, self.detector))[z0 - self.buf_start: z1 - self.buf_start]
        still = still_samples(self.buf_acc, self.buf_gyro, rate, self.zupt.zaru_threshold) if self.zupt.zaru else None
        setup = kernel_setup(rate, self.zupt, self.segmentation)
        steps: list[FootStep] = []
        if self.start_index < 0:
            self._initialise(flags, z0, z1, final, setup.min_len, setup.init_len)
            if self.start_index >= 0:
                known_from = self.start_index
                zv = np.concatenate([np.ones(max(0, z0 - known_from), dtype=bool), flags])[
                    max(0, known_from - z0):]
                steps = self._navigate(zv, z1, setup, still)
        else:
            steps = self._navigate(np.concatenate([[False], flags]), z1, setup, still)
        self.flags_done = z1
        # Context for the next flags: the statistic at z1 - (threshold reach) needs raw samples from z1 - before.
        keep = z1 - before
        if self.start_index >= 0:
            keep = min(keep, self.nav_next - 1)
        elif self.run_start >= 0:
            keep = min(keep, self.run_start)
        self._trim(max(keep, self.buf_start))
        return steps

    def _check_gaps(self) -> None:
        """Report intervals longer than GAP_FACTOR sample intervals among the samples not yet checked."""
        assert self.rate_hz is not None
        i0 = max(self.gaps_checked - 1, self.buf_start) - self.buf_start
        dt = np.diff(self.buf_t_ns[i0:]) / 1e9
        long = np.flatnonzero(dt > GAP_FACTOR / self.rate_hz)
        for j in long:
            t = float(self._t_s(self.buf_t_ns[i0 + j: i0 + j + 1])[0])
            self.warnings.append(f"gap of {dt[j]:.3f} s in the IMU samples at {t:.3f} s: the filter predicts "
                                 "across it")
        self.gaps_checked = self.n_seen

    def _initialise(self, flags: NDArray[np.bool_], z0: int, z1: int, final: bool, min_len: int,
                    init_len: int) -> None:
        """Coarse self-initialisation on the first stationary run of ``min_len`` samples (as run_zupt does)."""
        g0 = self.run_start if self.run_start >= 0 else z0
        known = np.concatenate([np.ones(z0 - g0, dtype=bool), flags])      # flags of [g0, z1)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], known.astype(np.int8), [0]])))
        starts, stops = edges[::2], edges[1::2]
        ok = np.flatnonzero(stops - starts >= min_len)
        if ok.size:
            a, stop = g0 + int(starts[ok[0]]), g0 + int(stops[ok[0]])
            closed = stop < z1 or final
            if closed or stop - a >= init_len:
                b = min(stop, a + init_len)
                rows = slice(a - self.buf_start, b - self.buf_start)
                q0 = initial_attitude_from_gravity(np.mean(self.buf_acc[rows], axis=0), yaw=self.zupt.yaw0)
                self.filter = FilterState.initial(q0, self.zupt)
                self.start_index, self.nav_next, self.run_start = a, a + 1, -1
                assert self.rate_hz is not None and self.first_t_ns is not None
                t_a = int(self.buf_t_ns[a - self.buf_start])
                warning = late_start_warning(a, (t_a - self.first_t_ns) / 1e9, self.rate_hz)
                if warning:
                    self.warnings.append(warning)
                return
            self.run_start = a
            return
        self.run_start = g0 + int(starts[-1]) if starts.size and stops[-1] == known.size else -1

    def _navigate(self, zv: NDArray[np.bool_], z1: int, setup: KernelSetup,
                  still: NDArray[np.bool_] | None) -> list[FootStep]:
        """Run the filter over samples [nav_next, z1); ``zv`` holds the flags of [nav_next - 1, z1), ``still``
        the zero angular-rate candidates of the whole buffer (``None`` without the update).
        """
        assert self.filter is not None and self.origin_ns is not None
        k0 = self.nav_next - 1
        rows = slice(k0 - self.buf_start, z1 - self.buf_start)
        t = self._t_s(self.buf_t_ns[rows])
        if t.size < 2:
            return []
        out = run_kernel(t, np.ascontiguousarray(self.buf_acc[rows]), np.ascontiguousarray(self.buf_gyro[rows]),
                         np.ascontiguousarray(zv), 1, self.filter, self.zupt, setup,
                         still=None if still is None else np.ascontiguousarray(still[rows]))
        self.nav_next = z1
        strides = self.swings.update(zv, t, out.step_idx)
        offset = self.origin_ns / 1e9
        yaw = quat.to_euler(quat.normalize(out.qs[out.step_idx]))[2] if out.step_idx.size else np.zeros(0)
        steps = []
        for i, k in enumerate(out.step_idx):
            t_log = float(t[k] + offset)
            inc = StepIncrement(t_log, int(k0 + k), out.step_dp[i].copy(), float(out.step_dpsi[i]),
                                out.step_cov[i].copy(), strides[i])
            steps.append(FootStep(t_log, out.pos[k].copy(), float(yaw[i]), inc))
        return steps

    def _close_stride(self) -> list[FootStep]:
        """The step at the last navigated sample that closes a stride ended after the last reset (none otherwise)."""
        k = self.nav_next - 1
        if self.filter is None or not self.swings.swung or k <= self.start_index:
            return []
        assert self.origin_ns is not None
        t_log = float(self._t_s(self.buf_t_ns[k - self.buf_start:k - self.buf_start + 1])[0] + self.origin_ns / 1e9)
        inc = closing_step(self.filter, t_log, k)
        at = StepwiseDeadReckoning(self.filter.dr[:3], float(self.filter.dr[3]))
        at.update(inc)
        self.swings.swung = False
        return [FootStep(t_log, at.pos_n, math.atan2(math.sin(at.heading), math.cos(at.heading)), inc)]

    def _trim(self, keep: int) -> None:
        cut = keep - self.buf_start
        if cut > 0:
            self.buf_t_ns, self.buf_acc, self.buf_gyro = self.buf_t_ns[cut:], self.buf_acc[cut:], self.buf_gyro[cut:]
            self.buf_start = keep
