"""Speed of the whole ``pdr track`` path on a real log: wall time per stage, and the ``ahrs`` package's EKF.

Stages, in the order ``pdr track`` runs them: ``read`` (the log reader), ``grid`` (resampling onto the common
time grid, :class:`~pdr.phone.grid.OnlineGrid`), ``attitude`` (the attitude filter's runs), ``steps`` (the step
detector), ``heading`` (per confirmed step: heading, step length and position), ``other`` (the rest of the
pipeline: floors, magnetometer calibration, elevator detection, event assembly), ``smoother`` (the offline heading
smoother) and ``write`` (the CSV). A stage's time is measured by wrapping the stage object's method on the one
pipeline instance being timed; the pipeline's code is not changed.

Each stage's CPU time of the process (:func:`time.process_time` at the same points) is reported beside its wall time:
on a shared, loaded machine the wall time of a stage also counts the other processes' turns, its CPU time much less.

A "step" of the rates is one accelerometer sample (as in ``pdr bench phone``): ``samples_per_s = number of
accelerometer samples / wall time``. The reference is :class:`ahrs.filters.EKF` (attitude alone, no steps, no
track) on the same accelerometer, gyroscope and magnetometer samples, timed in the same run.

:func:`tile_ipin_log` makes a long log from a short real one (a one-hour log is a 154 s walk tiled 24 times).
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pdr.errors import InputError

#: Stage names in the order they are printed.
STAGES = ("read", "grid", "attitude", "steps", "heading", "other", "smoother", "write")
#: GetSensorData records whose third field is a SensorTimestamp (shifted with the AppTimestamp by tiling).
_SENSOR_TIME_TAGS = frozenset({"ACCE", "GYRO", "MAGN", "PRES", "AHRS", "LIGH", "PROX", "HUMI", "TEMP"})


def tile_ipin_log(src: str | Path, copies: int, out: str | Path) -> Path:
    """Write ``copies`` back-to-back copies of the GetSensorData log ``src`` to ``out``; returns ``out``.

    The header is written once. Copy ``k`` has every AppTimestamp (and the SensorTimestamp of the sensor records)
    shifted by ``k * period``, ``period`` being the longer time span of its two clocks plus 1 s, rounded up to whole
    seconds, so that the clocks keep increasing; values are written with the decimals they had.
    """
    if copies < 1:
        raise ValueError(f"copies must be at least 1, got {copies}")
    if not Path(src).is_file():
        raise InputError("tiling needs a GetSensorData .txt log file" + (", got a folder" if Path(src).is_dir()
                                                                          else ": no such file"), source=str(src))
    lines = Path(src).read_text(encoding="ascii").splitlines()
    header = [ln for ln in lines if ln.startswith("%")]
    body = [ln.split(";") for ln in lines if ln and not ln.startswith("%")]
    shifted: list[tuple[list[str], list[int]]] = []
    lo, hi = [np.inf, np.inf], [-np.inf, -np.inf]   # App, Sensor clock
    for fields in body:
        cols = [1, 2] if fields[0] in _SENSOR_TIME_TAGS and len(fields) > 2 else [1]
        for c in cols:
            v = float(fields[c])
            lo[c - 1], hi[c - 1] = min(lo[c - 1], v), max(hi[c - 1], v)
        shifted.append((fields, cols))
    spans = [b - a for a, b in zip(lo, hi, strict=True) if b >= a]
    period = float(np.ceil(max(spans) + 1.0)) if spans else 1.0
    p = Path(out)
    with p.open("w", encoding="ascii", newline="\n") as f:
        f.write("\n".join(header) + "\n")
        for k in range(copies):
            off = k * period
            for fields, cols in shifted:
                row = list(fields)
                for c in cols:
                    decimals = len(row[c].partition(".")[2])
                    row[c] = f"{float(row[c]) + off:.{decimals}f}"
                f.write(";".join(row) + "\n")
    return p


class StageClock:
    """Accumulated wall and CPU time per stage name (``stages``), filled by :meth:`wrap`-ped methods and :meth:`add`."""

    def __init__(self, stages: tuple[str, ...] = STAGES) -> None:
        self.seconds: dict[str, float] = dict.fromkeys(stages, 0.0)
        self.cpu_seconds: dict[str, float] = dict.fromkeys(stages, 0.0)

    @staticmethod
    def now() -> tuple[float, float]:
        """(wall, CPU) clock readings (s)."""
        return time.perf_counter(), time.process_time()

    def add(self, stage: str, since: tuple[float, float]) -> None:
        """Add the wall and CPU time elapsed since the readings ``since`` (:meth:`now`) to ``stage``."""
        wall, cpu = self.now()
        self.seconds[stage] += wall - since[0]
        self.cpu_seconds[stage] += cpu - since[1]

    def wrap(self, obj: Any, method: str, stage: str) -> Callable[..., Any]:
        """Replace ``obj.method`` (an object's method or a module's function) by a timed call that adds its wall and
        CPU time to ``stage``; returns the original, for the caller to put back where ``obj`` outlives the timing.
        """
        inner: Callable[..., Any] = getattr(obj, method)

        @functools.wraps(inner)
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = self.now()
            try:
                return inner(*args, **kwargs)
            finally:
                self.add(stage, t0)

        setattr(obj, method, timed)
        return inner


def time_track(log: str | Path, out_csv: str | Path) -> dict[str, Any]:
    """One ``pdr track LOG --out OUT`` (smoother on, no site) timed per stage: wall seconds (``stages_s``,
    ``total_s``), CPU seconds (``stages_cpu_s``, ``total_cpu_s``) and sample counts.
    """
    from pdr.io import read_recording
    from pdr.phone.heading_smoother import smoothed_rows
    from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
    from pdr.phone.track_schema import write_csv

    clock = StageClock()
    t_start = clock.now()
    rec = read_recording(log)
    clock.add("read", t_start)
    pipe = PdrPipeline(PipelineConfig())
    clock.wrap(pipe.attitude, "run", "attitude")
    clock.wrap(pipe.steps, "update", "steps")
    clock.wrap(pipe, "_step", "heading")
    start = pipe._start

    def start_and_wrap_grid(batch: Any) -> Any:
        events = start(batch)
        if pipe.grid is not None:
            for m in ("push", "pull", "flush"):
                clock.wrap(pipe.grid, m, "grid")
        return events

    pipe._start = start_and_wrap_grid  # type: ignore[method-assign]
    t0 = clock.now()
    events = pipe.run(rec)
    clock.add("other", t0)
    inner = ("grid", "attitude", "steps", "heading")
    for times in (clock.seconds, clock.cpu_seconds):     # "other": the pipeline's time less its timed stages
        times["other"] -= sum(times[s] for s in inner)
    notices = [str(e["message"]) for e in events if e.get("type") == "notice"]
    t0 = clock.now()
    rows = smoothed_rows(track_rows(events), notices)
    clock.add("smoother", t0)
    t0 = clock.now()
    write_csv(rows, out_csv)
    clock.add("write", t0)
    wall, cpu = clock.now()
    n = len(rec.stream("acc")) if rec.has("acc") else 0
    return {"stages_s": clock.seconds, "total_s": wall - t_start[0], "stages_cpu_s": clock.cpu_seconds,
            "total_cpu_s": cpu - t_start[1], "acc_samples": n, "steps": len(rows), "duration_s": rec.duration_s,
            "recording": rec}


def time_ahrs_ekf(rec: Any) -> dict[str, Any] | None:
    """Wall time of :class:`ahrs.filters.EKF` on the recording's acc, gyro and mag (nearest samples to acc), and the
    package's version (a reference is named with its release), or None when ``ahrs`` is not installed. The inputs are
    prepared before the clock starts.
    """
    try:
        from ahrs.filters import EKF
    except ImportError:
        return None
    from importlib.metadata import version
    acc_s, gyro_s, mag_s = rec.stream("acc"), rec.stream("gyro"), rec.stream("mag")
    t = acc_s.t_ns

    def nearest(s: Any) -> np.ndarray:
        i = np.clip(np.searchsorted(s.t_ns, t), 0, len(s) - 1)
        return np.ascontiguousarray(s.values[i], dtype=np.float64)

    acc = np.ascontiguousarray(acc_s.values, dtype=np.float64)
    gyro, mag = nearest(gyro_s), nearest(mag_s)
    rate = 1e9 * (len(t) - 1) / float(t[-1] - t[0])
    t0 = time.perf_counter()
    EKF(gyr=gyro, acc=acc, mag=mag, frequency=rate, frame="ENU")
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "samples": len(t), "samples_per_s": len(t) / wall, "version": version("ahrs")}


def process_env(pycache: Path, numba_cache: Path | None = None) -> dict[str, str]:
    """The environment of a ``pdr`` process as an installed package runs: bytecode written and read (here under
    ``pycache``, so that the checkout is not written to; ``PYTHONDONTWRITEBYTECODE`` dropped), and numba's cache
    ``numba_cache`` when given (an empty folder: a cold start).
    """
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(pycache)
    if numba_cache is not None:
        env["NUMBA_CACHE_DIR"] = str(numba_cache)
    return env


def time_command(args: list[str], env: dict[str, str] | None = None) -> float:
    """Wall time (s) of a separate ``pdr ARGS`` process (interpreter start, imports, compiled-kernel loading
    included), in the environment ``env`` (None: this process's).
    """
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", "import sys; from pdr.cli import main; sys.exit(main())", *args],
                          capture_output=True, text=True, check=False, env=env)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"pdr {args[0]} failed ({done.returncode}): {done.stderr.strip()[-500:]}")
    return wall


def time_start_up(log: str | Path, tiled: str | Path, tmp: Path, repeat: int, cold: bool) -> dict[str, Any]:
    """Wall times (s) of separate processes, as an installed package runs them (:func:`process_env`):

    - ``track_s``: ``pdr track TILED`` warm (bytecode and compiled kernels cached: best of ``repeat`` after one
      untimed run), and ``track_first_s``: that untimed run (the bytecode cache empty, the kernels cached);
    - ``help_s``: ``pdr --help`` and ``inspect_s``: ``pdr inspect LOG``, warm (best of ``repeat``);
    - ``track_cold_s`` with ``cold``: ``pdr track TILED`` with both caches empty, a fresh install's first run
      (None without).
    """
    env = process_env(tmp / "pycache")
    out_csv = str(tmp / "track_process.csv")
    track = ["track", str(tiled), "--out", out_csv]
    first = time_command(track, env)
    res: dict[str, Any] = {"track_first_s": first,
                           "track_s": min(time_command(track, env) for _ in range(repeat)),
                           "help_s": min(time_command(["--help"], env) for _ in range(repeat)),
                           "inspect_s": min(time_command(["inspect", str(log)], env) for _ in range(repeat)),
                           "track_cold_s": None}
    if cold:
        res["track_cold_s"] = time_command(track, process_env(tmp / "pycache-cold", tmp / "numba-cache-cold"))
    return res


def run(log: str | Path, repeat: int = 1, tile: int = 1, cold: bool = False) -> dict[str, Any]:
    """Best-of-``repeat`` stage times of ``pdr track`` on ``log`` (tiled ``tile`` times first when > 1), and the
    ``ahrs`` EKF on the same data in the same run (best of ``repeat`` as well). ``least_cpu`` holds each stage's
    and the total's least CPU time over the runs (the first run's one-off costs, such as loading the compiled kernels,
    left out when ``repeat`` > 1). ``start_up``: the separate processes of :func:`time_start_up` (``cold``: also
    one with empty caches).
    """
    from pdr.machine import environment

    with tempfile.TemporaryDirectory(prefix="pdr-bench-track-") as tmp:
        src = Path(log)
        if tile > 1:
            src = tile_ipin_log(log, tile, Path(tmp) / f"tiled{tile}_{Path(log).name}")
        runs = [time_track(src, Path(tmp) / "track.csv") for _ in range(max(1, repeat))]
        best = min(runs, key=lambda r: r["total_s"])
        rec = best.pop("recording")
        for r in runs:
            r.pop("recording", None)
        ekf = [e for e in (time_ahrs_ekf(rec) for _ in range(max(1, repeat))) if e is not None]
        start_up = time_start_up(log, src, Path(tmp), max(1, repeat), cold)
        size = src.stat().st_size
    out: dict[str, Any] = {"environment": environment(), "log": str(log), "tile": tile, "bytes": size,
                           "repeat": repeat, "best": best, "all_totals_s": [r["total_s"] for r in runs]}
    out["least_cpu"] = {k: min(r["stages_cpu_s"][k] for r in runs) for k in STAGES}
    out["least_cpu"]["total"] = min(r["total_cpu_s"] for r in runs)
    out["samples_per_s"] = best["acc_samples"] / best["total_s"]
    out["start_up"] = start_up
    out["process_s"] = start_up["track_s"]
    out["process_samples_per_s"] = best["acc_samples"] / out["process_s"]
    if ekf:
        e = min(ekf, key=lambda r: r["wall_s"])
        out["ahrs_ekf"] = e
        out["ratio_to_ahrs_ekf"] = out["samples_per_s"] / e["samples_per_s"]
        out["process_ratio_to_ahrs_ekf"] = out["process_samples_per_s"] / e["samples_per_s"]
    else:
        out["ahrs_ekf"] = None
    return out
