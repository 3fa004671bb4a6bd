"""CPU cost of the foot navigators relative to the ZUPT-aided INS (issue #5).

A real foot recording is repeated end to end (continuous time axis) to the requested length and each navigator
is run once over it after a short JIT warm-up; the figure is CPU time (``time.process_time``), so that other
processes on the machine change it little. The filters are the causal ones, plus the ZUPT INS with its offline RTS
smoother (``zupt-smoothed``, the default of ``pdr foot``). Each navigator runs in a forked child process, so that
its memory can be told apart: the figure is the growth of the child's peak resident set size over the run (the
input arrays, shared with the parent, are not counted). ``tracemalloc`` would slow the compiled loops tenfold.

Run ``python -m pdr.evaluation.foot_speed /work/shared/data/foot_stride_gcp/own/SensorConnectData_32.csv --minutes 10``.
"""

from __future__ import annotations

import argparse
import multiprocessing
import resource
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from pdr.foot.bc import run_bc
from pdr.foot.detectors import detect
from pdr.foot.filterbank import FilterBankConfig, run_filterbank
from pdr.foot.navigate import foot_imu
from pdr.foot.zupt import run_zupt
from pdr.machine import environment_line


def tiled(t_s: np.ndarray, acc_b: np.ndarray, gyro_b: np.ndarray, rate_hz: float,
          seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The recording repeated to at least ``seconds`` s on one continuous time axis (s, m/s^2, rad/s)."""
    t = t_s - t_s[0]
    period = float(t[-1]) + 1.0 / rate_hz
    reps = max(1, int(np.ceil(seconds / period)))
    return (np.concatenate([t + i * period for i in range(reps)]), np.tile(acc_b, (reps, 1)),
            np.tile(gyro_b, (reps, 1)))


def cpu_costs(t: np.ndarray, acc: np.ndarray, gyro: np.ndarray,
              zv: np.ndarray) -> dict[str, tuple[float, float]]:
    """CPU seconds and peak memory growth (MB) of each navigator over ``(t, acc, gyro)`` with detector flags
    ``zv``, each run in a forked child process.
    """
    runs: dict[str, Callable[[slice], object]] = {
        "zupt": lambda s: run_zupt(t[s], acc[s], gyro[s], zv[s]),
        "zupt-smoothed": lambda s: run_zupt(t[s], acc[s], gyro[s], zv[s], smooth=True),
        "filterbank": lambda s: run_filterbank(t[s], acc[s], gyro[s], zv[s]),
        "filterbank-height": lambda s: run_filterbank(t[s], acc[s], gyro[s], zv[s],
                                                      FilterBankConfig(variant="height")),
        "bc": lambda s: run_bc(t[s], acc[s], gyro[s], zv[s]),
    }
    out: dict[str, tuple[float, float]] = {}
    fork = multiprocessing.get_context("fork")
    for name, run in runs.items():
        run(slice(0, min(t.size, 2000)))                         # compile, in the parent: children inherit it
        receive, send = fork.Pipe(duplex=False)
        child = fork.Process(target=_measure, args=(run, send))   # forked: the run is not pickled
        child.start()
        out[name] = receive.recv()
        child.join()
    return out


def _measure(run: Callable[[slice], object], send: Any) -> None:
    """In a child process: send the CPU seconds of one run and the growth of the peak resident set size, MB."""
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    c0 = time.process_time()
    run(slice(None))
    cpu = time.process_time() - c0
    send.send((cpu, (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0))


def main(argv: Sequence[str] | None = None) -> int:
    from pdr.io import read_recording

    p = argparse.ArgumentParser(prog="python -m pdr.evaluation.foot_speed", description=__doc__.split("\n")[0])
    p.add_argument("recording", help="a foot IMU recording")
    p.add_argument("--minutes", type=float, default=10.0, help="length of the repeated recording")
    args = p.parse_args(argv)
    imu = foot_imu(read_recording(args.recording))
    t, acc, gyro = tiled(imu.t_s, imu.acc_b, imu.gyro_b, imu.rate_hz, 60.0 * args.minutes)
    zv = detect(acc, gyro, imu.rate_hz)
    costs = cpu_costs(t, acc, gyro, zv)
    span = float(t[-1] - t[0])
    print(f"environment: {environment_line()}")
    for name, (c, mb) in costs.items():
        print(f"{name}: {span:.0f} s at {imu.rate_hz:.0f} Hz in {c:.2f} s CPU = {span / c:.0f}x real time, "
              f"{c / costs['zupt'][0]:.1f}x the ZUPT filter's cost; peak memory +{mb:.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
