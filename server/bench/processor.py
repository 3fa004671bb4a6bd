"""``pdr bench processor``: what one live batch costs a worker, stage by stage, without HTTP or a database.

A worker that keeps up with live uploads handles each 1 s batch of a session on its own: it decodes the
stored JSON payload, restores the session's processor from its stored state, updates it, computes the
provisional tail and encodes the new state. This replays a simulated phone session exactly so (warm-up
batches first, so that the pipeline's 30 s history and the classifier's buffers are full) and prints the
mean milliseconds per batch of each stage and the size of the stored state, i.e. the worker's CPU cost
per batch apart from the database (``pdr bench load`` measures the whole deployment). Like a worker, it
runs with ``PDR_NATIVE_THREADS`` BLAS threads (default 1).

``--at 1,120`` (with ``--minutes 121``) also prints the cost in the one-minute windows that start at those
minutes of the session, and the stored state's size at their end: a live session's per-batch cost must stay
flat as it grows, so the two windows should agree.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

STAGES = ("decode", "restore", "update", "tail", "save")


def measure(minutes: float, warmup_s: float, batch_s: float, placement: str, seed: int,
            at_minutes: tuple[float, ...] = ()) -> dict[str, Any]:
    """Mean ms per batch of each stage after ``warmup_s`` seconds of the session, and the state size;
    ``at_minutes``: the same over the one-minute window starting at each of those minutes (``windows``).
    """
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
    per_batch_s: list[tuple[float, ...]] = []
    state_sizes: list[int] = []
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
        per_batch_s.append((t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4))
        state_sizes.append(len(state))
        if i >= warm:
            for stage, dt in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True):
                totals[stage] += dt
    n = len(payloads) - warm
    per_batch = {stage: round(1000.0 * totals[stage] / n, 2) for stage in STAGES}
    return {"batches_measured": n, "batch_s": batch_s, "placement": placement, "ms_per_batch": per_batch,
            "total_ms_per_batch": round(sum(per_batch.values()), 2), "state_bytes": len(state or b""),
            "payload_bytes": len(payloads[-1]),
            "windows": [_window(per_batch_s, state_sizes, m, batch_s) for m in at_minutes]}


def _window(per_batch_s: list[tuple[float, ...]], state_sizes: list[int], minute: float,
            batch_s: float) -> dict[str, Any]:
    """Mean ms per batch of each stage over the batches of ``[minute, minute + 1)`` min, state size at its end."""
    a = int(round(minute * 60.0 / batch_s))
    b = min(len(per_batch_s), a + max(1, int(round(60.0 / batch_s))))
    if a >= len(per_batch_s):
        raise SystemExit(f"pdr bench processor: --at {minute:g} lies beyond the session; raise --minutes")
    rows = per_batch_s[a:b]
    ms = {stage: round(1000.0 * sum(r[k] for r in rows) / len(rows), 2) for k, stage in enumerate(STAGES)}
    return {"minute": minute, "batches": len(rows), "ms_per_batch": ms,
            "total_ms_per_batch": round(sum(ms.values()), 2), "state_bytes": state_sizes[b - 1]}


def _run(args: argparse.Namespace) -> int:
    from server.config import limit_native_threads

    limit_native_threads()  # as in a worker process
    result = measure(args.minutes, args.warmup_s, args.batch_s, args.placement, args.seed, _minutes(args.at))
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    stages = ", ".join(f"{k} {v}" for k, v in result["ms_per_batch"].items())
    print(f"phone processor, {result['placement']}, {result['batches_measured']} live batches of "
          f"{result['batch_s']:g} s: {result['total_ms_per_batch']} ms per batch ({stages})")
    print(f"  stored state {result['state_bytes']} bytes, payload {result['payload_bytes']} bytes")
    for w in result["windows"]:
        stages = ", ".join(f"{k} {v}" for k, v in w["ms_per_batch"].items())
        print(f"  minute {w['minute']:g}-{w['minute'] + 1:g} ({w['batches']} batches): "
              f"{w['total_ms_per_batch']} ms per batch ({stages}); stored state {w['state_bytes']} bytes")
    return 0


def _minutes(text: str | None) -> tuple[float, ...]:
    """``"1,120"`` -> (1.0, 120.0); a clear error for anything else."""
    if not text:
        return ()
    try:
        out = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise SystemExit(f"pdr bench processor: --at takes minutes separated by commas, got {text!r}") from None
    if any(m < 0 for m in out):
        raise SystemExit(f"pdr bench processor: --at minutes must not be negative, got {text!r}")
    return out


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("processor", help="a worker's CPU cost per live phone batch, stage by stage")
    p.add_argument("--minutes", type=float, default=4.0, help="simulated session length in minutes (4)")
    p.add_argument("--warmup-s", type=float, default=60.0, help="batches before measuring, in seconds (60)")
    p.add_argument("--batch-s", type=float, default=1.0, help="batch length in seconds (1)")
    p.add_argument("--placement", default="trouser_pocket", help="session placement (trouser_pocket)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--at", metavar="M1,M2", help="also the one-minute windows starting at these minutes, e.g. 1,120 "
                   "with --minutes 121: per-batch cost as the session grows")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=_run)
