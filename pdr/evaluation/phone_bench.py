"""Speed of the phone pipeline: samples per second on a long simulated recording, peak memory, and the
attitude filter side by side with filterpy's UKF (a pure-Python reference) on the same input; with a site, the
pipeline with the map-matching stage and the stage's own cost per step event.

A "time step" is one instant of the input recording (acc, gyro, mag at 100 Hz, barometer slower):
``samples_per_s = number of accelerometer samples / wall time``.
"""

from __future__ import annotations

import math
import resource
import time
import tracemalloc
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.machine import environment
from pdr.phone.attitude import AttitudeFilter
from pdr.phone.events import PipelineEvent, StepEvent
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.phone.stage import StepStage
from pdr.phone.track import TrackState
from pdr.recording import Recording
from pdr.site.plan import SitePlan


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


def bench_pipeline(rec: Recording, config: PipelineConfig | None = None, batch_s: float = 0.0,
                   stages: Callable[[], Sequence[StepStage]] = tuple) -> dict[str, Any]:
    """Wall time and samples/s of the pipeline on ``rec`` (one batch or ``batch_s`` chunks), with the plugged-in
    stages ``stages()`` builds (none by default).

    Memory: ``pipeline_peak_traced_mb`` is the peak of the memory the pipeline allocates while processing
    the recording (``tracemalloc``, a separate untimed run); ``peak_rss_mb`` is the peak resident set size of
    the whole process (input recording and simulator included).
    """
    n = len(rec.stream("acc"))
    PdrPipeline(config, stages=stages()).run(rec.slice_time(*_first_seconds(rec, 30.0)))  # compile the kernels first
    t0 = time.perf_counter()
    p = PdrPipeline(config, stages=stages())
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
    PdrPipeline(config, stages=stages()).run(rec)
    _, traced = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"samples": n, "duration_s": rec.duration_s, "wall_s": wall, "samples_per_s": n / wall,
            "times_real_time": rec.duration_s / wall, "peak_rss_mb": peak, "pipeline_peak_traced_mb": traced / 2**20,
            "steps": len(track_rows(events)), "batch_s": batch_s, "_events": events, "_stages": p.stages}


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


class TimedStage:
    """A plugged-in stage with a stopwatch: the wall and CPU time (s) its ``step`` took over the steps it saw (the
    CPU time leaves out the waits for other processes on shared cores).
    """

    def __init__(self, stage: StepStage) -> None:
        self.stage, self.name = stage, stage.name
        self.wall_s, self.cpu_s, self.steps = 0.0, 0.0, 0

    def step(self, event: StepEvent, track: TrackState) -> tuple[StepEvent, list[PipelineEvent]]:
        t0, c0 = time.perf_counter(), time.process_time()
        out = self.stage.step(event, track)
        self.wall_s += time.perf_counter() - t0
        self.cpu_s += time.process_time() - c0
        self.steps += 1
        return out

    def state(self) -> dict[str, Any]:
        return self.stage.state()

    def from_state(self, d: dict[str, Any]) -> TimedStage:
        return TimedStage(self.stage.from_state(d))


#: Half width (m) of the corridor site built about the simulated walk (``--site`` without a file).
CORRIDOR_HALF_WIDTH_M = 1.5


def corridor_site(rows: Sequence[dict[str, Any]], half_width_m: float = CORRIDOR_HALF_WIDTH_M
                  ) -> tuple[SitePlan, tuple[float, float]]:
    """A one-floor site whose walkable area is a corridor about a PDR track (its rows, m, from the origin), and the
    start (the origin): a building the steps fit, so that the map matcher is timed matching, not suspended.
    """
    from pdr.site.geometry import corridor_ring, simplify_path

    xy = np.array([[0.0, 0.0]] + [[float(r["east_m"]), float(r["north_m"])] for r in rows])
    if len(xy) < 3:
        raise InputError("a corridor site needs a walk of a few steps", source="bench", field="site")
    path = simplify_path(xy, 0.7 * half_width_m)   # corners, not arcs
    ring = corridor_ring(path, half_width_m)
    plan = SitePlan.from_dict({"name": "bench corridor", "floors": [
        {"floor": 0, "walkable": {"type": "Polygon", "coordinates": [ring.tolist()]}}]}, source="bench corridor")
    return plan, (0.0, 0.0)


def bench_map_stage(rec: Recording, plan: SitePlan, start_en: tuple[float, float], floor: int,
                    batch_s: float = 0.0) -> dict[str, Any]:
    """The pipeline with the map-matching stage (:class:`pdr.mapmatch.stage.MapMatchStage`) on ``plan`` from
    ``start_en`` (m): samples/s of the whole, and the stage's own cost in step events per second of its wall time.
    """
    from pdr.mapmatch.stage import MapMatchStage

    res = bench_pipeline(rec, PipelineConfig(), batch_s,
                         stages=lambda: [TimedStage(MapMatchStage(plan, start_en, floor, source="--start"))])
    timed = res["_stages"][0]
    notices = [e for e in res["_events"] if e.get("type") == "notice" and "map matching" in str(e.get("message"))]
    return {**res, "stage_steps": timed.steps, "stage_wall_s": timed.wall_s,
            "stage_steps_per_s": timed.steps / timed.wall_s if timed.wall_s > 0 else math.nan,
            "stage_cpu_s": timed.cpu_s,
            "stage_steps_per_cpu_s": timed.steps / timed.cpu_s if timed.cpu_s > 0 else math.nan,
            "stage_times_real_time_cpu": rec.duration_s / timed.cpu_s if timed.cpu_s > 0 else math.nan,
            "particles": timed.stage.config.particles, "map_notices": len(notices),
            "walls": int(sum(len(f.walls()) for f in plan.floors.values()))}


def run(duration_s: float = 3600.0, rate_hz: float = 100.0, batch_s: float = 0.0,
        site: SitePlan | None = None, start: tuple[tuple[float, float], int] | None = None,
        corridor: bool = False) -> dict[str, Any]:
    """Simulate, then time the pipeline and the attitude filters; with ``site`` and ``start`` (or ``corridor``: a
    corridor site about the simulated walk) also the pipeline with the map-matching stage.
    """
    t0 = time.perf_counter()
    rec = simulated_recording(duration_s, rate_hz)
    sim_s = time.perf_counter() - t0
    res = {"environment": environment(),
           "recording": {"duration_s": rec.duration_s, "rate_hz": rate_hz, "simulate_s": sim_s},
           "pipeline": bench_pipeline(rec, PipelineConfig(), batch_s)}
    if corridor:
        site, start_en = corridor_site(track_rows(res["pipeline"]["_events"]))
        start = (start_en, 0)
    res["pipeline"] = _public(res["pipeline"])
    if site is not None and start is not None:
        res["map"] = _public(bench_map_stage(rec, site, start[0], start[1], batch_s))
        res["map"]["site"] = "a corridor 3 m wide about the PDR track" if corridor else "given"
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


def _public(d: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in d.items() if not k.startswith("_")}
