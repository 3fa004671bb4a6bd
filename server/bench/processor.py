"""``pdr bench processor``: what one live batch costs a worker, stage by stage, without HTTP or a database.

A worker that keeps up with live uploads handles each 1 s batch of a session on its own: it decodes the
stored JSON payload, restores the session's processor from its stored state, updates it, computes the
provisional tail and encodes the new state. This replays a simulated phone session exactly so (warm-up
batches first, so that the pipeline's 30 s history and the classifier's buffers are full) and prints the
mean milliseconds per batch of each stage and the size of the stored state, i.e. the worker's CPU cost
per batch apart from the database (``pdr bench load`` measures the whole deployment). Like a worker, it
runs with ``PDR_NATIVE_THREADS`` BLAS threads (default 1).
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

STAGES = ("decode", "restore", "update", "tail", "save")


def measure(minutes: float, warmup_s: float, batch_s: float, placement: str, seed: int) -> dict[str, Any]:
    """Mean ms per batch of each stage after ``warmup_s`` seconds of the session, and the state size."""
    from pdr.io.native import batch_from_json
    from server.bench.server import simulated_phone, split_batches
    from server.phone_processor import PhoneProcessor
    from server.processing import SessionContext

    payloads = [json.dumps(b).encode() for b in split_batches(simulated_phone(minutes, seed=seed), batch_s)]
    warm = min(len(payloads) - 1, int(round(warmup_s / batch_s)))
    if warm < 0 or len(payloads) - warm < 1:
        raise SystemExit("pdr bench processor: the session is too short for the warm-up; raise --minutes")
    ctx = SessionContext("bench", "phone", placement, {})
    totals = dict.fromkeys(STAGES, 0.0)
    state: bytes | None = None
    for i, payload in enumerate(payloads):
        t0 = time.perf_counter()
        recording = batch_from_json(json.loads(payload))
        t1 = time.perf_counter()
        processor = PhoneProcessor(ctx, state)
        t2 = time.perf_counter()
        processor.update(recording)
        t3 = time.perf_counter()
        processor.tail()
        t4 = time.perf_counter()
        state = processor.to_bytes()
        t5 = time.perf_counter()
        if i >= warm:
            for stage, dt in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True):
                totals[stage] += dt
    n = len(payloads) - warm
    per_batch = {stage: round(1000.0 * totals[stage] / n, 2) for stage in STAGES}
    return {"batches_measured": n, "batch_s": batch_s, "placement": placement, "ms_per_batch": per_batch,
            "total_ms_per_batch": round(sum(per_batch.values()), 2), "state_bytes": len(state or b""),
            "payload_bytes": len(payloads[-1])}


def _run(args: argparse.Namespace) -> int:
    from server.config import limit_native_threads

    limit_native_threads()  # as in a worker process
    result = measure(args.minutes, args.warmup_s, args.batch_s, args.placement, args.seed)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    stages = ", ".join(f"{k} {v}" for k, v in result["ms_per_batch"].items())
    print(f"phone processor, {result['placement']}, {result['batches_measured']} live batches of "
          f"{result['batch_s']:g} s: {result['total_ms_per_batch']} ms per batch ({stages})")
    print(f"  stored state {result['state_bytes']} bytes, payload {result['payload_bytes']} bytes")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("processor", help="a worker's CPU cost per live phone batch, stage by stage")
    p.add_argument("--minutes", type=float, default=4.0, help="simulated session length in minutes (4)")
    p.add_argument("--warmup-s", type=float, default=60.0, help="batches before measuring, in seconds (60)")
    p.add_argument("--batch-s", type=float, default=1.0, help="batch length in seconds (1)")
    p.add_argument("--placement", default="trouser_pocket", help="session placement (trouser_pocket)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=_run)
