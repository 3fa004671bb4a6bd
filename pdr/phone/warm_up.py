"""The warm-up walk: the phone pipeline and the offline heading smoother run once on a short simulated walk, so that
their numba kernels are compiled into (or loaded from) numba's cache before real work needs them.

**Compiling in two processes.** numba compiles one kernel at a time, in the order a walk calls them, and the attitude
filter's UKF kernel (:data:`pdr.phone.attitude.kernel.run_ukf`, with numba's ``np.linalg`` and ``@`` that it pulls
in) is most of the whole: 33 of 52 s of the service's sequential warm-up (numba's compile events, quiet 2-core
machine). The pipeline calls it before the heading, step length, floors and smoother kernels, which therefore wait
for it. :func:`compile_alongside` starts ``python -m pdr.phone.warm_up``: this walk with :class:`TiltOnlyAttitude` in
place of the filter (the accelerometer's tilt, no kernel), so that the child compiles every other kernel into the
shared cache while the caller compiles the filter's, and the caller then loads them. What a kernel compiles to depends
only on its argument types, which the stand-in's output shares with the filter's (float64 (N, 4) quaternions, C
order), not on their values. numba writes each cache file whole (a temporary file, then a rename), so two processes
can fill one cache. ``pdr serve`` does this at its start (:mod:`server.warmup`, whose child also warms the reader and
the classifier), and the commands that run the pipeline on their first run (:func:`pdr.cli.track.compile_ahead`).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from typing import IO

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.phone.attitude import AttitudeFilter
from pdr.recording import Recording

#: A short hand-held walk: straight, a turn, straight, so that steps, headings and the smoother all run.
WALK = {"name": "warm_up", "placement": "hand", "start": {"position_m": [0, 0, 0], "heading_deg": 0},
        "rates_hz": {"acc": 100.0, "gyro": 100.0, "mag": 100.0, "baro": 10.0},
        "segments": [{"type": "stand", "duration_s": 2.0}, {"type": "walk", "duration_s": 12.0, "speed_mps": 1.3},
                     {"type": "turn", "angle_deg": 90, "duration_s": 2.0},
                     {"type": "walk", "duration_s": 12.0, "speed_mps": 1.3}]}


class TiltOnlyAttitude(AttitudeFilter):
    """Stand-in for the attitude filter in the warm-up's child process (module doc): each sample's attitude is the
    shortest rotation taking the specific force (body frame) onto up (ENU), yaw left free; no gyro, no field, no
    kernel, and the filter's state is left as it starts.
    """

    def run(self, acc_b: NDArray[np.float64], gyro_b: NDArray[np.float64] | None = None,
            mag_b: NDArray[np.float64] | None = None, carried: NDArray[np.bool_] | None = None
            ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        acc = np.ascontiguousarray(acc_b, dtype=np.float64)
        q = quat.from_two_vectors(acc, np.broadcast_to([0.0, 0.0, 1.0], acc.shape)) if acc.shape[0] else (
            np.zeros((0, 4)))
        return np.ascontiguousarray(q), np.zeros(acc.shape[0], dtype=np.int64)


def warm_up(extra: Sequence[Callable[[Recording], object]] = (), attitude_filter: bool = True) -> float:
    """Run the pipeline and the smoother once on :data:`WALK`, then each of ``extra`` on that recording; returns the
    wall time in s. ``attitude_filter=False``: the pipeline's attitude filter is :class:`TiltOnlyAttitude` (the child
    process of :func:`compile_alongside`).
    """
    from pdr.phone.heading_smoother import smooth_track
    from pdr.phone.pipeline import PdrPipeline, track_rows
    from pdr.sim import simulate

    t0 = time.perf_counter()
    rec = simulate(WALK, 0)
    pipeline = PdrPipeline()
    if not attitude_filter:
        att = pipeline.attitude
        pipeline.attitude = TiltOnlyAttitude(att.rate_hz, att.config, att.method)
    smooth_track(track_rows(pipeline.run(rec)))
    for f in extra:
        f(rec)
    return time.perf_counter() - t0


def compile_alongside(module: str = __name__, stderr: IO[bytes] | int = subprocess.DEVNULL
                      ) -> subprocess.Popen[bytes] | None:
    """Start ``python -m module`` (this module's :func:`main` by default): the warm-up walk without the attitude filter,
    compiling the other kernels into this process' cache (its environment, ``NUMBA_CACHE_DIR`` included) while this
    process compiles the filter's (module doc). None on a machine of one core (the two would take turns, not run
    alongside), or when the process cannot be started.
    """
    if (os.cpu_count() or 1) < 2:
        return None
    try:
        return subprocess.Popen([sys.executable, "-m", module], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=stderr)
    except OSError:
        return None


#: Longest wait (s) for the process of :func:`compile_alongside` once its caller is done (it compiles a subset of the
#: caller's kernels, so it is normally done first); then it is stopped.
ALONGSIDE_WAIT_S = 120.0


def filter_kernel_cached(method: str = "ukf") -> bool:
    """Whether numba's cache holds the attitude filter's kernel of ``method`` (``ukf`` or ``ekf``) for its current
    source: when it does not, this is a first run that compiles (:func:`pdr.filters.compiled.is_cached`).
    """
    from pdr.filters.compiled import is_cached
    from pdr.phone.attitude.kernel import run_ekf, run_ukf

    return is_cached(run_ukf if method == "ukf" else run_ekf)


def wait_alongside(process: subprocess.Popen[bytes]) -> bytes | None:
    """Wait for the process of :func:`compile_alongside` (at most :data:`ALONGSIDE_WAIT_S`): what it printed, or None
    when it was stopped at the end of the wait.
    """
    try:
        out, _ = process.communicate(timeout=ALONGSIDE_WAIT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.communicate()
        return None
    return out


def main() -> int:
    """The child process of :func:`compile_alongside`: the walk with the stand-in attitude; prints its seconds."""
    print(f"{warm_up(attitude_filter=False):.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
