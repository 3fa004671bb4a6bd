"""``pdr worker``: a processing worker for ``PDR_WORKER=redis`` deployments.

Reads the same configuration as ``pdr serve`` (``DATABASE_URL``, ``REDIS_URL``, ``PDR_REDIS_NAMESPACE``,
``PDR_PROCESSOR``), upgrades the database schema, compiles (or loads) the processing kernels into
``PDR_DATA_DIR/numba-cache`` as ``pdr serve`` does (:mod:`server.warmup`), then runs an RQ worker on the
namespace's queue (see :mod:`server.queue`) plus the reconciler thread. Start as many as the processing load
needs, on any machine that reaches the database and Redis. SIGTERM/SIGINT stop it after the current job (a second
one at once); a lost Redis connection is retried with backoff instead of ending the process.
"""

from __future__ import annotations

import argparse
import logging
import os
import socket
import sys
import time
import uuid

from server.config import limit_native_threads, load_settings, safe_url


def _run(args: argparse.Namespace) -> int:
    from server import warmup

    settings = load_settings()
    warmup.use_cache_dir(settings.data_dir / "numba-cache")   # as pdr serve's, before numba is imported
    import redis
    from rq import SimpleWorker

    from server import migrations
    from server.db import make_engine
    from server.leases import Leases
    from server.processing import SessionProcessing
    from server.queue import RetryPolicy, SessionQueue, WorkerRuntime, redis_client, set_runtime
    from server.scaleout import load_processor_factory
    from server.store import Store

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    limit_native_threads()
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrations.upgrade(settings.database_url)
    store = Store(make_engine(settings.database_url))
    name = args.name or f"{settings.redis_namespace}-{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:6]}"
    connection = redis_client(settings.redis_url)
    runtime = WorkerRuntime(SessionProcessing(store, load_processor_factory(settings.processor)),
                            Leases(store.engine, name, ttl_s=args.lease_s, max_attempts=args.max_attempts),
                            SessionQueue(connection, settings.redis_namespace),
                            RetryPolicy(retries=args.retries))
    set_runtime(runtime)
    # Compiled before the first job, not during it: a queued session waits for a warm worker meanwhile.
    warmup.start().join()
    kernels = warmup.status()
    print(f"pdr worker {name}: compiled kernels ready in {kernels['seconds']} s"
          + (f" (warm-up failed: {kernels['error']})" if kernels["error"] else ""), file=sys.stderr, flush=True)
    stop_reconciler = runtime.start_reconciler(args.reconcile_s)
    print(f"pdr worker {name}: queue '{settings.redis_namespace}' on {safe_url(settings.redis_url)}, "
          f"database {safe_url(settings.database_url)}", file=sys.stderr, flush=True)
    delay, restarts = 1.0, 0
    try:
        while True:
            started = time.monotonic()
            try:
                worker = SimpleWorker([runtime.queue.queue], connection=connection, name=f"{name}-{restarts}")
                worker.work(burst=args.burst, logging_level="INFO" if args.verbose else "WARNING",
                            with_scheduler=False)
                return 0
            except redis.exceptions.RedisError as exc:
                restarts += 1
                if time.monotonic() - started > 60.0:
                    delay = 1.0  # a new outage after a long healthy run
                print(f"pdr worker {name}: Redis unavailable ({exc}); retrying in {delay:.0f} s", file=sys.stderr,
                      flush=True)
                time.sleep(delay)
                delay = min(delay * 2.0, 30.0)
    finally:
        stop_reconciler.set()
        store.engine.dispose()


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("worker", help="run a processing worker (PDR_WORKER=redis deployments)")
    p.add_argument("--name", help="worker name (default: namespace-host-pid-random)")
    p.add_argument("--burst", action="store_true", help="exit when the queue is empty")
    p.add_argument("--lease-s", type=float, default=float(os.environ.get("PDR_LEASE_S", "30")),
                   help="session lease time-to-live, s: how long a dead worker blocks its session (30)")
    p.add_argument("--reconcile-s", type=float, default=float(os.environ.get("PDR_RECONCILE_S", "10")),
                   help="period of the reconciler that requeues unprocessed sessions, s (10)")
    p.add_argument("--max-attempts", type=int, default=int(os.environ.get("PDR_MAX_ATTEMPTS", "5")),
                   help="interrupted attempts before a batch becomes a dead letter (5)")
    p.add_argument("--retries", type=int, default=6, help="retries of a transient failure within a job (6)")
    p.add_argument("-v", "--verbose", action="store_true", help="log every job")
    p.set_defaults(func=_run)
