"""``pdr bench server``: replay simulated phones concurrently over loopback and measure ingest latency.

Each phone is a session that pushes its recording as native 1 s batches, as fast as the server answers.
Printed: batches per second over all phones, and p50/p95 latency of a batch during the first minute of
the sessions and during their last minute (at ``--minutes``), so that growth of latency with session
length shows; optionally the time for the worker to drain the processing backlog.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from pdr.recording import Recording
from server.client import Client, add_user, running_server


def simulated_phone(minutes: float, seed: int = 1) -> Recording:
    """A pocket walk with turns and pauses from the simulator (100 Hz IMU, magnetometer, barometer)."""
    from pdr.sim import parse_scenario, simulate

    segments: list[dict[str, Any]] = []
    remaining = minutes * 60.0
    while remaining > 0:
        for seg in ({"type": "walk", "duration_s": 40.0, "speed_mps": 1.3}, {"type": "turn", "angle_deg": 90.0},
                    {"type": "stand", "duration_s": 5.0}):
            segments.append(seg)
        remaining -= 47.0
    scenario = parse_scenario({"name": "bench", "placement": "trouser_pocket", "segments": segments,
                               "rates_hz": {"acc": 100, "gyro": 100, "mag": 50, "baro": 10}})
    return simulate(scenario, seed=seed)


def split_batches(recording: Recording, batch_s: float) -> list[dict[str, Any]]:
    """Native JSON batches of ``batch_s`` seconds each, in time order."""
    from pdr.io.native import batch_to_json

    start, end = recording.time_span_s()
    edges = np.arange(start, end + batch_s, batch_s)
    out = []
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        try:
            part = recording.slice_time(float(a), float(b))
        except ValueError:
            continue
        part = Recording(part.streams, part.device, recording.t0_ns)
        out.append(batch_to_json(part, batch_id=f"b{i:06d}"))
    return out


def _percentiles(values: list[float]) -> dict[str, float]:
    if not values:
        return {"p50_ms": float("nan"), "p95_ms": float("nan"), "n": 0}
    a = np.asarray(values) * 1000.0
    return {"p50_ms": round(float(np.percentile(a, 50)), 2), "p95_ms": round(float(np.percentile(a, 95)), 2),
            "n": int(a.size)}


def replay(url: str, token: str, bodies: list[bytes], phones: int, drain: bool) -> dict[str, Any]:
    """Push ``bodies`` as the batches of ``phones`` concurrent sessions; returns the figures."""
    latencies: list[list[float]] = [[] for _ in range(phones)]
    failures: list[str] = []
    session_ids: list[str] = []
    admin = Client(url, token)
    for p in range(phones):
        reply = admin.request("POST", "/api/v1/sessions", {"session_id": f"bench-{p}-{time.time_ns()}"})
        session_ids.append(reply.json()["id"])

    def run(p: int) -> None:
        c = Client(url, token)
        for body in bodies:
            r = c.request("POST", f"/api/v1/sessions/{session_ids[p]}/batches", raw=body)
            if r.status not in (200, 201):
                failures.append(f"{r.status} {r.body[:200]!r}")
            latencies[p].append(r.seconds)
        c.close()

    t0 = time.perf_counter()
    threads = [threading.Thread(target=run, args=(p,)) for p in range(phones)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.perf_counter() - t0
    per_minute = 60  # batches of 1 s
    first = [x for lat in latencies for x in lat[:per_minute]]
    last = [x for lat in latencies for x in lat[-per_minute:]]
    result: dict[str, Any] = {
        "phones": phones, "batches": phones * len(bodies), "failed": len(failures), "seconds": round(elapsed, 2),
        "batches_per_s": round(phones * len(bodies) / elapsed, 1), "first_minute": _percentiles(first),
        "last_minute": _percentiles(last), "session_minutes": round(len(bodies) / 60.0, 1),
    }
    if failures:
        result["first_failure"] = failures[0]
    if drain:
        t1 = time.perf_counter()
        while True:
            states = [admin.request("GET", f"/api/v1/sessions/{sid}").json() for sid in session_ids]
            if all(s["batches"].get("pending", 0) == 0 and s["batches"].get("processing", 0) == 0 for s in states):
                break
            time.sleep(0.5)
        result["drain_s_after_upload"] = round(time.perf_counter() - t1, 2)
        result["batch_status"] = [s["batches"] for s in states]
    admin.close()
    return result


def _run(args: argparse.Namespace) -> int:
    rec = simulated_phone(args.minutes, seed=args.seed)
    bodies = [json.dumps(b).encode() for b in split_batches(rec, args.batch_s)]
    if args.url:
        result = replay(args.url, args.token, bodies, args.phones, args.drain)
    else:
        with tempfile.TemporaryDirectory(prefix="pdr-bench-") as tmp, running_server(Path(tmp)) as (url, env, _):
            token = add_user(env, "bench")
            result = replay(url, token, bodies, args.phones, args.drain)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"{result['phones']} phones x {result['session_minutes']} min of 1 s batches: "
              f"{result['batches']} batches in {result['seconds']} s = {result['batches_per_s']} batches/s, "
              f"{result['failed']} failed")
        for key in ("first_minute", "last_minute"):
            r = result[key]
            print(f"  latency {key.replace('_', ' ')}: p50 {r['p50_ms']} ms, p95 {r['p95_ms']} ms (n={r['n']})")
        if "drain_s_after_upload" in result:
            print(f"  processing backlog drained {result['drain_s_after_upload']} s after the last upload")
    return 0 if result["failed"] == 0 else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("server", help="replay N simulated phones over loopback; batches/s and latency")
    p.add_argument("--phones", type=int, default=4, help="concurrent phones (4)")
    p.add_argument("--minutes", type=float, default=60.0, help="session length in minutes (60)")
    p.add_argument("--batch-s", type=float, default=1.0, help="batch length in seconds (1)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--url", help="an already running service (default: start one on a free port)")
    p.add_argument("--token", help="API token for --url")
    p.add_argument("--drain", action="store_true", help="also wait until the worker has processed everything")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=_run)
