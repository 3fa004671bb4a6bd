"""Speed of the phone pipeline: samples per second on a long simulated recording, peak memory, and the
attitude filter side by side with filterpy's UKF (a pure-Python reference) on the same input.

A "time step" is one instant of the input recording (acc, gyro, mag at 100 Hz, barometer slower):
``samples_per_s = number of accelerometer samples / wall time``.
"""

from __future__ import annotations

import math
import resource
import time
import tracemalloc
from typing import Any

import numpy as np

from pdr.machine import environment
from pdr.phone.attitude import AttitudeFilter
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.recording import Recording


def long_walk_scenario(duration_s: float, rate_hz: float = 100.0) -> dict[str, Any]:
    """A hand-held office walk of about ``duration_s`` seconds: straight legs, turns and short stops."""
    segs: list[dict[str, Any]] = []
    t = 0.0
    i = 0
    while t < duration_s:
        segs += [{"type": "walk", "duration_s": 40.0, "speed_mps": 1.2 + 0.1 * (i % 3)},
                 {"type": "turn", "angle_deg": 90 if i % 2 == 0 else -90, "duration_s": 2.0},
                 {"type": "stand", "duration_s": 5.0 if i % 5 == 4 else 1.0}]
        t += 43.0 + (5.0 if i % 5 == 4 else 1.0)
        i += 1
    return {"name": "bench_long_walk", "placement": "hand", "start": {"position_m": [0, 0, 0], "heading_deg": 0},
            "rates_hz": {"acc": rate_hz, "gyro": rate_hz, "mag": rate_hz, "baro": 10.0}, "segments": segs}


def simulated_recording(duration_s: float, rate_hz: float = 100.0, seed: int = 0) -> Recording:
    from pdr.sim import simulate
    return simulate(long_walk_scenario(duration_s, rate_hz), seed)


def bench_pipeline(rec: Recording, config: PipelineConfig | None = None, batch_s: float = 0.0) -> dict[str, Any]:
    """Wall time and samples/s of the pipeline on ``rec`` (one batch or ``batch_s`` chunks).

    Memory: ``pipeline_peak_traced_mb`` is the peak of the memory the pipeline allocates while processing
    the recording (``tracemalloc``, a separate untimed run); ``peak_rss_mb`` is the peak resident set size of
    the whole process (input recording and simulator included).
    """
    n = len(rec.stream("acc"))
    PdrPipeline(config).run(rec.slice_time(*_first_seconds(rec, 30.0)))  # compile the kernels first
    t0 = time.perf_counter()
    p = PdrPipeline(config)
    if batch_s > 0:
        a, b = rec.time_span_s()
        events = []
        s = a
        while s <= b:
            try:
                events += p.update(rec.slice_time(s, s + batch_s))
            except ValueError:
                pass
            s += batch_s
        events += p.finish()
    else:
        events = p.run(rec)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    tracemalloc.start()
    PdrPipeline(config).run(rec)
    _, traced = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"samples": n, "duration_s": rec.duration_s, "wall_s": wall, "samples_per_s": n / wall,
            "times_real_time": rec.duration_s / wall, "peak_rss_mb": peak, "pipeline_peak_traced_mb": traced / 2**20,
            "steps": len(track_rows(events)), "batch_s": batch_s}


def _first_seconds(rec: Recording, s: float) -> tuple[float, float]:
    a, _ = rec.time_span_s()
    return a, a + s


def bench_attitude(acc: np.ndarray, gyro: np.ndarray, mag: np.ndarray, rate_hz: float,
                   filterpy_samples: int = 20000) -> dict[str, Any]:
    """Samples/s of our UKF and EKF kernels and of filterpy's UnscentedKalmanFilter with the same models."""
    out: dict[str, Any] = {}
    for method in ("ukf", "ekf"):
        AttitudeFilter(rate_hz, method=method).run(acc[:100], gyro[:100], mag[:100])   # compile
        t0 = time.perf_counter()
        AttitudeFilter(rate_hz, method=method).run(acc, gyro, mag)
        out[f"{method}_samples_per_s"] = acc.shape[0] / (time.perf_counter() - t0)
    try:
        from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
    except ImportError:
        out["filterpy_samples_per_s"] = None
        return out
    from pdr import quaternion as quat
    ts = 1.0 / rate_hz
    g = np.array([0.0, 0.0, 9.80665])
    h = quat.rotate(quat.IDENTITY, mag[0])

    def fx(x: np.ndarray, dt: float, w: np.ndarray) -> np.ndarray:
        y = quat.multiply(x, quat.from_rotvec(w * dt))
        return np.asarray(y / np.linalg.norm(y))

    def hx(x: np.ndarray) -> np.ndarray:
        xc = quat.conjugate(x / np.linalg.norm(x))
        return np.concatenate([quat.rotate(xc, g), quat.rotate(xc, h)])

    pts = MerweScaledSigmaPoints(4, alpha=1e-3, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(dim_x=4, dim_z=6, dt=ts, hx=hx, fx=fx, points=pts)
    ukf.x = np.array([1.0, 0.0, 0.0, 0.0])
    ukf.P *= 1e-2
    ukf.Q = np.eye(4) * 1e-7
    ukf.R = np.diag([1.0] * 3 + [9.0] * 3)
    m = min(filterpy_samples, acc.shape[0])
    t0 = time.perf_counter()
    for k in range(m):
        ukf.predict(w=gyro[k])
        ukf.update(np.concatenate([acc[k], mag[k]]))
    out["filterpy_samples_per_s"] = m / (time.perf_counter() - t0)
    out["filterpy_samples_timed"] = m
    return out


def run(duration_s: float = 3600.0, rate_hz: float = 100.0, batch_s: float = 0.0) -> dict[str, Any]:
    """Simulate, then time the pipeline and the attitude filters."""
    t0 = time.perf_counter()
    rec = simulated_recording(duration_s, rate_hz)
    sim_s = time.perf_counter() - t0
    res = {"environment": environment(),
           "recording": {"duration_s": rec.duration_s, "rate_hz": rate_hz, "simulate_s": sim_s},
           "pipeline": bench_pipeline(rec, PipelineConfig(), batch_s)}
    n = min(len(rec.stream("acc")), len(rec.stream("gyro")), len(rec.stream("mag")))
    res["attitude"] = bench_attitude(rec.values("acc")[:n], rec.values("gyro")[:n], rec.values("mag")[:n], rate_hz)
    res["pipeline"]["linear_check"] = _linearity(rec)
    return res


def _linearity(rec: Recording) -> dict[str, float]:
    """Wall time on the first quarter and on the whole recording (processing cost is linear)."""
    a, b = rec.time_span_s()
    q = rec.slice_time(a, a + (b - a) / 4)
    t0 = time.perf_counter()
    PdrPipeline().run(q)
    tq = time.perf_counter() - t0
    t0 = time.perf_counter()
    PdrPipeline().run(rec)
    tf = time.perf_counter() - t0
    return {"quarter_s": tq, "full_s": tf, "ratio": tf / tq if tq > 0 else math.nan}
