"""``pdr bench load``: many phones pushing 1 s batches in real time against web processes + workers.

Starts a scale-out deployment on this machine (:mod:`server.bench.cluster`: ``--webs`` web processes and
``--workers`` workers on a fresh temporary PostgreSQL database and a private Redis namespace, both
removed afterwards), replays ``--phones`` simulated phones, each sending one batch per ``--batch-s``
seconds for ``--minutes``, then waits until the processing backlog is drained and checks, per session:

- lost: batches acknowledged (HTTP 200/201) but not stored, or stored but not processed (``done``);
- duplicated: a stored batch id twice, or a track point emitted twice (a batch processed twice);
- p50/p95/p99 ingest latency (request sent to answer received), retries, throughput, drain time;
- ``/api/v1/health`` latency (polled every 0.1 s on the first web process) while one large log file
  (``--big-upload-mb``, a simulated walk as native JSON) is uploaded to that same process during the replay, and
  that upload's answer and duration.

The defaults are the issue's check (50 phones, 10 minutes); tests run a short version.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
import uuid
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from pdr.cli.progress import Progress
from server.client import Client, add_user


def simulated_uploads(phones: int, minutes: float, batch_s: float,
                      recordings: int) -> dict[str, list[tuple[str, bytes]]]:
    """``phones`` sessions of ``(batch_id, body)`` native batches from ``recordings`` distinct simulated walks."""
    from server.bench.server import simulated_phone, split_batches

    walks = [[(b["batch_id"], json.dumps(b).encode()) for b in split_batches(simulated_phone(minutes, seed=k), batch_s)]
             for k in range(max(1, min(recordings, phones)))]
    n = int(round(minutes * 60.0 / batch_s))
    return {f"phone-{p:03d}": walks[p % len(walks)][:n] for p in range(phones)}


def big_upload(megabytes: float) -> bytes:
    """A simulated pocket walk as one native JSON log file of at least ``megabytes`` MB (10^6 bytes; about 2.7 MB per
    minute of walk).
    """
    from pdr.io.native import batch_to_json
    from server.bench.server import simulated_phone

    minutes = max(0.5, megabytes / 2.7)
    while True:
        body = json.dumps(batch_to_json(simulated_phone(minutes, seed=99), session_id="big", batch_id="big")).encode()
        if len(body) >= megabytes * 1e6:
            return body
        minutes *= 1.05 * megabytes * 1e6 / len(body)


def multipart_file(payload: bytes, filename: str) -> tuple[bytes, str]:
    """A ``multipart/form-data`` body with one ``file`` field; returns (body, content type)."""
    boundary = uuid.uuid4().hex
    head = (f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="{filename}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n").encode()
    return head + payload + f"\r\n--{boundary}--\r\n".encode(), f"multipart/form-data; boundary={boundary}"


def health_during_upload(url: str, token: str, payload: bytes, delay_s: float, out: dict[str, Any]) -> None:
    """After ``delay_s`` s, upload ``payload`` as a log file to ``url`` and poll ``/api/v1/health`` there every 0.1 s
    until the upload is answered; fills ``out`` with the upload's status and seconds and the health latencies.
    """
    time.sleep(delay_s)
    body, ctype = multipart_file(payload, "big-walk.json")
    done = threading.Event()
    latencies: list[float] = []
    statuses: Counter[int] = Counter()

    def poll() -> None:
        c = Client(url, timeout_s=60.0)
        try:
            while not done.is_set():
                reply = c.request("GET", "/api/v1/health")
                latencies.append(reply.seconds)
                statuses[reply.status] += 1
                done.wait(0.1)
        finally:
            c.close()

    poller = threading.Thread(target=poll, daemon=True)
    uploader = Client(url, token, timeout_s=600.0)
    poller.start()
    try:
        reply = uploader.request("POST", "/api/v1/sessions", raw=body, content_type=ctype)
    finally:
        done.set()
        poller.join()
        uploader.close()
    out.update({"upload_mb": round(len(body) / 1e6, 1), "upload_status": reply.status,
                "upload_s": round(reply.seconds, 1), "health_polls": len(latencies),
                "health_statuses": {str(k): v for k, v in statuses.items()},
                "health_latency": percentiles_ms(latencies)})
    if reply.status == 201:
        out["session"] = str(reply.json()["id"])


def check_sessions(url: str, token: str, session_ids: dict[str, str],
                   acknowledged: dict[str, list[str]]) -> dict[str, Any]:
    """Lost and duplicated batches and track points of every session, from the API."""
    c = Client(url, token)
    lost = unprocessed = duplicated_ids = duplicated_points = points = 0
    statuses: Counter[str] = Counter()
    try:
        for name, sid in session_ids.items():
            detail = c.request("GET", f"/api/v1/sessions/{sid}").json()
            stored = [b["batch_id"] for b in detail["batch_list"]]
            statuses.update(b["status"] for b in detail["batch_list"])
            lost += len(set(acknowledged[name]) - set(stored))
            unprocessed += sum(b["status"] != "done" for b in detail["batch_list"])
            duplicated_ids += len(stored) - len(set(stored))
            track = c.request("GET", f"/api/v1/sessions/{sid}/track").json()["points"]
            keys = [(p["device"], p["t_s"]) for p in track if not p.get("provisional")]
            points += len(keys)
            duplicated_points += len(keys) - len(set(keys))
    finally:
        c.close()
    return {"lost": lost, "not_done": unprocessed, "duplicated_batches": duplicated_ids,
            "duplicated_track_points": duplicated_points, "track_points": points, "batch_status": dict(statuses)}


def percentiles_ms(latencies_s: list[float]) -> dict[str, float]:
    if not latencies_s:
        return {"p50_ms": float("nan"), "p95_ms": float("nan"), "p99_ms": float("nan"), "max_ms": float("nan")}
    a = np.asarray(latencies_s) * 1000.0
    return {"p50_ms": round(float(np.percentile(a, 50)), 1), "p95_ms": round(float(np.percentile(a, 95)), 1),
            "p99_ms": round(float(np.percentile(a, 99)), 1), "max_ms": round(float(a.max()), 1)}


def run_load(args: argparse.Namespace) -> dict[str, Any]:
    """Run the load check with the parsed command-line options; returns the figures."""
    with Progress(5, "bench load") as bar:   # simulate, start, upload in real time, drain, check
        return _run_load(args, bar)


def _run_load(args: argparse.Namespace, bar: Progress) -> dict[str, Any]:
    from server.bench.cluster import ensure_services, replay_phones, running_cluster, temporary_postgres, wait_drained
    from server.queue import purge_namespace, redis_client

    bar.set_note(f"simulating {min(args.recordings, args.phones)} walks of {args.minutes:g} min")
    t_sim = time.perf_counter()
    uploads = simulated_uploads(args.phones, args.minutes, args.batch_s, args.recordings)
    big = big_upload(args.big_upload_mb) if args.big_upload_mb > 0 else None
    sim_s = time.perf_counter() - t_sim
    bar.advance(note="starting PostgreSQL, web processes and workers")
    ensure_services(args.postgres_admin_url, args.redis_url)
    namespace = f"pdrbench-{uuid.uuid4().hex[:8]}"
    env = {"PDR_PROCESSOR": args.processor} if args.processor else {}
    result: dict[str, Any] = {"phones": args.phones, "minutes": args.minutes, "batch_s": args.batch_s,
                              "webs": args.webs, "workers": args.workers, "processor": args.processor or "built-in",
                              "simulation_s": round(sim_s, 1)}
    try:
        with tempfile.TemporaryDirectory(prefix="pdr-load-") as tmp, \
                temporary_postgres(args.postgres_admin_url) as db_url, \
                running_cluster(Path(tmp), db_url, args.redis_url, namespace, webs=args.webs, workers=args.workers,
                                extra_env=env) as cluster:
            token = add_user(cluster.env, "load")
            backlog: list[tuple[float, int]] = []
            stop = threading.Event()
            sampler = threading.Thread(target=_sample_backlog, args=(db_url, backlog, stop), daemon=True)
            sampler.start()
            probe: dict[str, Any] = {}
            prober = None
            if big is not None:  # a third of the way into the replay (its pace is real time unless flooding)
                delay_s = 0.0 if args.flood else args.minutes * 60.0 / 3.0
                prober = threading.Thread(target=health_during_upload, args=(cluster.urls[0], token, big, delay_s,
                                                                           probe), daemon=True)
                prober.start()
            bar.advance(note=f"{args.phones} phones uploading for {args.minutes:g} min")
            t0 = time.perf_counter()
            replay = replay_phones(cluster.urls, token, uploads, pace_s=0.0 if args.flood else args.batch_s)
            upload_s = time.perf_counter() - t0
            if prober is not None:
                prober.join()
                result["big_upload"] = probe
                if "session" in probe:  # the big log is a session too: wait for it and check it as well
                    replay.session_ids["big-upload"] = probe.pop("session")
                    replay.acknowledged["big-upload"] = []
            bar.advance(note="waiting for the processing backlog to drain")
            t1 = time.perf_counter()
            try:
                wait_drained(cluster.urls[0], token, list(replay.session_ids.values()),
                             timeout_s=args.drain_timeout_s)
                drained = True
            except TimeoutError:
                drained = False
            drain_s = time.perf_counter() - t1
            stop.set()
            sampler.join()
            bar.advance(note="checking every session's track")
            result["processing_batches_per_s"] = _processing_rate(db_url)
            sent = sum(len(v) for v in uploads.values())
            acked = sum(len(v) for v in replay.acknowledged.values())
            result.update({
                "batches_sent": sent, "batches_acknowledged": acked, "refused": len(replay.refused),
                "upload_s": round(upload_s, 1), "batches_per_s": round(acked / upload_s, 1),
                "latency": percentiles_ms(replay.latencies_s), "retries": replay.retries,
                "drained": drained, "drain_s_after_last_upload": round(drain_s, 1) if drained else None,
                "backlog_at_end": backlog[-1][1] if backlog else None,
                "max_backlog_batches": max((n for _, n in backlog), default=0),
                **check_sessions(cluster.urls[-1], token, replay.session_ids, replay.acknowledged),
            })
            if replay.refused:
                result["first_refusal"] = replay.refused[0]
            bar.advance()
    finally:  # after the processes stopped, so that none writes to the namespace again
        purge_namespace(redis_client(args.redis_url), namespace)
    return result


def _processing_rate(db_url: str) -> float:
    """Batches processed per second by the workers, from first to last processing time."""
    from sqlalchemy import func, select

    from server import db
    from server.config import _normalise_db_url

    engine = db.make_engine(_normalise_db_url(db_url))
    try:
        with engine.connect() as conn:
            n, t0, t1 = conn.execute(select(func.count(), func.min(db.batches.c.processed_at),
                                            func.max(db.batches.c.processed_at))
                                     .where(db.batches.c.status == "done")).one()
    finally:
        engine.dispose()
    return round(n / max((t1 - t0).total_seconds(), 1e-9), 1) if n and t0 and t1 else 0.0


def _sample_backlog(db_url: str, out: list[tuple[float, int]], stop: threading.Event) -> None:
    """Every second: how many batches are pending or processing (the processing backlog)."""
    from sqlalchemy import func, select

    from server import db
    from server.config import _normalise_db_url

    engine = db.make_engine(_normalise_db_url(db_url))
    t0 = time.perf_counter()
    try:
        while not stop.wait(1.0):
            try:
                with engine.connect() as conn:
                    n = conn.execute(select(func.count()).select_from(db.batches)
                                     .where(db.batches.c.status.in_(["pending", "processing"]))).scalar_one()
                out.append((time.perf_counter() - t0, int(n)))
            except Exception:  # noqa: S112  the database may be restarting; sample again next second
                continue
    finally:
        engine.dispose()


def print_result(result: dict[str, Any]) -> None:
    lat = result["latency"]
    print(f"{result['phones']} phones x {result['minutes']} min of {result['batch_s']} s batches against "
          f"{result['webs']} web processes + {result['workers']} workers (processor: {result['processor']})")
    print(f"  sent {result['batches_sent']}, acknowledged {result['batches_acknowledged']}, "
          f"refused {result['refused']}, retries {result['retries']}; "
          f"{result['batches_per_s']} batches/s over {result['upload_s']} s")
    print(f"  ingest latency p50 {lat['p50_ms']} ms, p95 {lat['p95_ms']} ms, p99 {lat['p99_ms']} ms, "
          f"max {lat['max_ms']} ms")
    drained = (f"drained {result['drain_s_after_last_upload']} s after the last upload" if result["drained"]
               else f"NOT drained {args_timeout(result)}: {result['backlog_at_end']} batches left")
    print(f"  backlog: at most {result['max_backlog_batches']} batches; {drained}; workers processed "
          f"{result['processing_batches_per_s']} batches/s")
    if "big_upload" in result:
        big = result["big_upload"]
        hl = big["health_latency"]
        print(f"  during a {big['upload_mb']} MB log upload (answered {big['upload_status']} after "
              f"{big['upload_s']} s): /health p50 {hl['p50_ms']} ms, p95 {hl['p95_ms']} ms, max {hl['max_ms']} ms over "
              f"{big['health_polls']} polls {big['health_statuses']}")
    print(f"  lost {result['lost']}, not processed {result['not_done']}, duplicated batches "
          f"{result['duplicated_batches']}, duplicated track points {result['duplicated_track_points']} "
          f"(of {result['track_points']}); batch status {result['batch_status']}")


def args_timeout(result: dict[str, Any]) -> str:
    return f"within {result['drain_timeout_s']:.0f} s"


def _run(args: argparse.Namespace) -> int:
    result = run_load(args)
    result["drain_timeout_s"] = args.drain_timeout_s
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print_result(result)
    ok = (result["drained"] and result["lost"] == 0 and result["duplicated_batches"] == 0
          and result["duplicated_track_points"] == 0 and result["refused"] == 0
          and result["batches_acknowledged"] == result["batches_sent"])
    return 0 if ok else 1


def add_deployment_options(p: argparse.ArgumentParser) -> None:
    """Options shared by ``pdr bench load`` and ``pdr bench faults``: where PostgreSQL and Redis are."""
    import os

    p.add_argument("--postgres-admin-url",
                   default=os.environ.get("PDR_BENCH_POSTGRES_URL", "postgresql://postgres@127.0.0.1:5432/test"),
                   help="PostgreSQL server on which a temporary database is created and dropped")
    p.add_argument("--redis-url", default=os.environ.get("REDIS_URL", "redis://127.0.0.1:6379/0"),
                   help="Redis (a private namespace is used and purged afterwards)")
    p.add_argument("--processor", help="PDR_PROCESSOR for the service (default: the built-in processors)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("load", help="N phones x M minutes of real-time 1 s batches against web processes + "
                                           "workers (PostgreSQL + Redis): lost/duplicated batches, p95 latency")
    p.add_argument("--phones", type=int, default=50, help="concurrent phones (50)")
    p.add_argument("--minutes", type=float, default=10.0, help="minutes of upload per phone (10)")
    p.add_argument("--batch-s", type=float, default=1.0, help="batch length and send period, s (1)")
    p.add_argument("--webs", type=int, default=2, help="web processes (2)")
    p.add_argument("--workers", type=int, default=2, help="workers (2)")
    p.add_argument("--recordings", type=int, default=5, help="distinct simulated walks shared by the phones (5)")
    p.add_argument("--flood", action="store_true", help="send as fast as answered instead of one batch per period")
    p.add_argument("--big-upload-mb", type=float, default=50.0,
                   help="size of the log file uploaded during the replay while /health is polled, MB; 0: none (50)")
    p.add_argument("--drain-timeout-s", type=float, default=1800.0, help="give up waiting for the backlog (1800)")
    add_deployment_options(p)
    p.set_defaults(func=_run)
