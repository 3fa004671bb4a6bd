"""``pdr bench faults``: inject faults during a replay and check that no accepted batch is lost.

Scenarios (``--scenarios``, default all):

``kill-worker``
    SIGKILL a worker while it holds a session (mid-job); a replacement starts ``--restart-after-s`` later,
    as a supervisor would. The session is taken over once its lease expires.
``restart-postgres``
    Restart the PostgreSQL server during the replay (``--postgres-restart-cmd``).
``restart-redis``
    Stop Redis without saving (its queue and flags are lost) and start it again ``--redis-down-s`` later.
``quota``
    Embedded default (SQLite, in-process worker) with a data-directory quota (``PDR_DATA_QUOTA_MB``):
    uploads are refused with 507 once it is reached; after the quota is raised, the refused batches are
    sent again.

The scale-out scenarios run a deployment of ``--webs`` web processes and ``--workers`` workers on a
temporary PostgreSQL database and a private Redis namespace, *and at the same time* the embedded default
as the reference; after the replay drains, every session must hold every acknowledged batch, processed
once (status ``done``), and its track must equal the reference's. Printed per scenario: acknowledged,
lost, duplicated, retries and the longest retry the phones saw (the degraded window), 503/507 answers,
recovery times. PostgreSQL and Redis are always left running.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from server.bench.cluster import (
    Cluster,
    ReplayResult,
    ensure_services,
    fetch_tracks,
    push,
    replay_phones,
    running_cluster,
    temporary_postgres,
    wait_drained,
)
from server.bench.load import add_deployment_options, check_sessions, simulated_uploads
from server.client import Client, add_user, running_server

PG_RESTART = "sh -c 'pg_ctlcluster --skip-systemctl-redirect $(ls /etc/postgresql) main restart'"
REDIS_STOP = "redis-cli shutdown nosave"
REDIS_START = ("redis-server --daemonize yes --bind '127.0.0.1 -::1' --port 6379 --save '' --appendonly no "
               "--dir /var/lib/redis --logfile /var/log/redis/ci.log")

Fault = Callable[[Cluster, str, dict[str, Any]], None]


def _sh(cmd: str, timeout_s: float = 120.0) -> float:
    """Run a shell command; returns its duration, s. Raises on failure."""
    t0 = time.perf_counter()
    subprocess.run(shlex.split(cmd), check=True, timeout=timeout_s, capture_output=True)
    return time.perf_counter() - t0


def _wait_redis(url: str, timeout_s: float = 30.0) -> None:
    import redis

    from server.queue import redis_client

    deadline = time.monotonic() + timeout_s
    while True:
        try:
            redis_client(url).ping()
            return
        except redis.exceptions.RedisError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def _engine(db_url: str) -> Any:
    from server import db
    from server.config import _normalise_db_url

    return db.make_engine(_normalise_db_url(db_url))


def _lease_owner(engine: Any, session_id: str | None = None) -> tuple[str, str] | None:
    """(session id, worker) of a live lease (of ``session_id`` if given), or None."""
    from sqlalchemy import select

    from server import db

    t = db.session_leases
    q = select(t.c.session_id, t.c.owner).where(t.c.expires_at > db.utcnow())
    if session_id is not None:
        q = q.where(t.c.session_id == session_id)
    with engine.connect() as conn:
        row = conn.execute(q).first()
    return (str(row.session_id), str(row.owner)) if row else None


def _when_progress(replay_done: threading.Event, acked: Callable[[], int], target: int) -> bool:
    """Wait until ``acked()`` reaches ``target`` (or the replay ended); True if reached."""
    while acked() < target:
        if replay_done.is_set():
            return False
        time.sleep(0.05)
    return True


def kill_worker(args: argparse.Namespace) -> Fault:
    def fault(cluster: Cluster, db_url: str, out: dict[str, Any]) -> None:
        engine = _engine(db_url)
        try:
            deadline = time.monotonic() + 60
            held = None
            while held is None and time.monotonic() < deadline:
                held = _lease_owner(engine)
                if held is None:
                    time.sleep(0.01)
            if held is None:
                raise RuntimeError("no worker ever held a session lease")
            session_id, owner = held
            cluster.kill_worker(owner)
            t_kill = time.perf_counter()
            out.update({"killed": owner, "killed_session": session_id})
            restarted = False
            while True:  # until the killed worker's session is held by another worker (or was finished)
                now = _lease_owner(engine, session_id)
                if now is None or now[1] != owner:
                    out["session_taken_over_s_after_kill"] = round(time.perf_counter() - t_kill, 2)
                    break
                if not restarted and time.perf_counter() - t_kill > args.restart_after_s:
                    cluster.start_worker(owner + "-restarted")  # as a supervisor would
                    restarted = True
                time.sleep(0.1)
            if not restarted:
                time.sleep(max(0.0, args.restart_after_s - (time.perf_counter() - t_kill)))
                cluster.start_worker(owner + "-restarted")
        finally:
            engine.dispose()
    return fault


def restart_postgres(args: argparse.Namespace) -> Fault:
    def fault(cluster: Cluster, db_url: str, out: dict[str, Any]) -> None:
        out["restart_command_s"] = round(_sh(args.postgres_restart_cmd), 2)
    return fault


def restart_redis(args: argparse.Namespace) -> Fault:
    def fault(cluster: Cluster, db_url: str, out: dict[str, Any]) -> None:
        try:
            _sh(args.redis_stop_cmd)
            time.sleep(args.redis_down_s)
        finally:
            _sh(args.redis_start_cmd)
            _wait_redis(args.redis_url)
        out["redis_down_s"] = args.redis_down_s
    return fault


def scale_out_scenario(args: argparse.Namespace, uploads: dict[str, list[tuple[str, bytes]]], fault: Fault,
                       processor_env: dict[str, str]) -> dict[str, Any]:
    """Replay ``uploads`` to a deployment (with ``fault`` injected at a third of the replay) and to the
    embedded reference at the same time; returns the figures.
    """
    from server.queue import purge_namespace, redis_client

    namespace = f"pdrfault-{uuid.uuid4().hex[:8]}"
    out: dict[str, Any] = {}
    total = sum(len(v) for v in uploads.values())
    with tempfile.TemporaryDirectory(prefix="pdr-faults-") as tmp, ExitStack() as stack:
        db_url = stack.enter_context(temporary_postgres(args.postgres_admin_url))
        stack.callback(lambda: _purge_quietly(purge_namespace, redis_client, args.redis_url, namespace))
        ref_url, ref_env, _ = stack.enter_context(running_server(Path(tmp) / "embedded", extra_env=processor_env))
        cluster = stack.enter_context(running_cluster(
            Path(tmp) / "cluster", db_url, args.redis_url, namespace, webs=args.webs, workers=args.workers,
            extra_env=processor_env, worker_args=["--lease-s", str(args.lease_s), "--reconcile-s",
                                                  str(args.reconcile_s)]))
        ref_token, token = add_user(ref_env, "ref"), add_user(cluster.env, "faults")
        replays = {"ref": ReplayResult({}, {}, []), "got": ReplayResult({}, {}, [])}
        threads = [threading.Thread(target=replay_phones, args=(urls, tok, uploads),
                                    kwargs={"pace_s": args.pace_s, "progress": replays[key]})
                   for key, urls, tok in (("ref", [ref_url], ref_token), ("got", cluster.urls, token))]
        for t in threads:
            t.start()
        done = threading.Event()

        def watch() -> None:
            threads[1].join()
            done.set()

        threading.Thread(target=watch, daemon=True).start()
        fault_error: list[BaseException] = []
        t_fault = None
        if _when_progress(done, lambda: sum(len(v) for v in replays["got"].acknowledged.values()), total // 3):
            t_fault = time.perf_counter()
            try:
                fault(cluster, db_url, out)
            except BaseException as exc:  # report after the replay ended
                fault_error.append(exc)
        for t in threads:
            t.join()
        upload_end = time.perf_counter()
        if fault_error:
            raise fault_error[0]
        got, ref = replays["got"], replays["ref"]
        wait_drained(ref_url, ref_token, list(ref.session_ids.values()), timeout_s=args.drain_timeout_s)
        wait_drained(cluster.urls[0], token, list(got.session_ids.values()), timeout_s=args.drain_timeout_s)
        out["drained_s_after_last_upload"] = round(time.perf_counter() - upload_end, 1)
        if t_fault is not None:
            out["drained_s_after_fault"] = round(time.perf_counter() - t_fault, 1)
        out["workers_exited"] = [name for name, proc in cluster.workers.items()
                                 if proc.poll() is not None and name != out.get("killed")]
        expected = fetch_tracks(ref_url, ref_token, ref.session_ids)
        tracks = fetch_tracks(cluster.urls[-1], token, got.session_ids)
        out.update({"batches_sent": total, "acknowledged": sum(len(v) for v in got.acknowledged.values()),
                    "refused": len(got.refused), "retries": got.retries,
                    "longest_retry_s": round(got.longest_retry_s, 2),
                    **check_sessions(cluster.urls[-1], token, got.session_ids, got.acknowledged),
                    "tracks_equal_reference": tracks == expected,
                    "token_in_logs": token in cluster.logs()})
        if got.refused:
            out["first_refusal"] = got.refused[0]
    return out


def _purge_quietly(purge: Any, client: Any, url: str, namespace: str) -> None:
    try:
        _wait_redis(url)
        purge(client(url), namespace)
    except Exception:  # noqa: S110  best effort: Redis may have lost it all anyway
        pass


def quota_scenario(args: argparse.Namespace, uploads: dict[str, list[tuple[str, bytes]]],
                   processor_env: dict[str, str]) -> dict[str, Any]:
    """Embedded default with a data quota: 507 once full, nothing accepted lost, refused ones accepted later."""
    out: dict[str, Any] = {"quota_mb": args.quota_mb}
    with tempfile.TemporaryDirectory(prefix="pdr-quota-") as tmp:
        data_dir = Path(tmp)
        env = {**processor_env, "PDR_DATA_QUOTA_MB": str(args.quota_mb)}
        with running_server(data_dir, extra_env=env) as (url, server_env, _):
            token = add_user(server_env, "quota")
            first = replay_phones([url], token, uploads)
            statuses = [r.split(": ", 1)[1][:3] for r in first.refused]
            out.update({"acknowledged_under_quota": sum(len(v) for v in first.acknowledged.values()),
                        "refused_507": statuses.count("507"), "refused_other": len(statuses) - statuses.count("507")})
            if first.refused:  # what a phone is told
                name, batch_id = first.refused[0].split(":", 1)[0].split("/")
                body = dict(uploads[name])[batch_id]
                c = Client(url, token)
                reply = c.request("POST", f"/api/v1/sessions/{first.session_ids[name]}/batches", raw=body)
                out["refusal"] = f"{reply.status} {reply.json()['error']['message']}"
                c.close()
            wait_drained(url, token, list(first.session_ids.values()), timeout_s=args.drain_timeout_s)
            out["after_refusals"] = check_sessions(url, token, first.session_ids, first.acknowledged)
            c = Client(url, token)
            out["reads_while_full"] = c.request("GET", "/api/v1/sessions").status
            c.close()
        with running_server(data_dir, extra_env=processor_env) as (url, _, _):  # the operator raised the quota
            c = Client(url, token)
            resent = 0
            for name, batches in uploads.items():
                sid = first.session_ids[name]
                for batch_id, body in batches:
                    if batch_id not in set(first.acknowledged[name]):
                        reply, _, _ = push(c, f"/api/v1/sessions/{sid}/batches", body)
                        resent += reply.status == 201
                        first.acknowledged[name].append(batch_id)
            c.close()
            wait_drained(url, token, list(first.session_ids.values()), timeout_s=args.drain_timeout_s)
            out["resent_after_quota_raised"] = resent
            out["final"] = check_sessions(url, token, first.session_ids, first.acknowledged)
    return out


def _ok(result: dict[str, Any]) -> bool:
    if "final" in result:  # quota
        return (result["after_refusals"]["lost"] == 0 and result["final"]["lost"] == 0
                and result["final"]["not_done"] == 0 and result["refused_other"] == 0)
    return (result["lost"] == 0 and result["not_done"] == 0 and result["duplicated_batches"] == 0
            and result["duplicated_track_points"] == 0 and result["refused"] == 0 and result["tracks_equal_reference"]
            and not result["token_in_logs"] and not result["workers_exited"])


SCENARIOS = ("kill-worker", "restart-postgres", "restart-redis", "quota")


def run_faults(args: argparse.Namespace) -> dict[str, Any]:
    scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    unknown = set(scenarios) - set(SCENARIOS)
    if unknown:
        raise ValueError(f"unknown scenario(s) {sorted(unknown)}; choose from {', '.join(SCENARIOS)}")
    uploads = simulated_uploads(args.phones, args.minutes, 1.0, args.phones)
    processor_env = {"PDR_PROCESSOR": args.processor} if args.processor else {}
    if any(s != "quota" for s in scenarios):
        ensure_services(args.postgres_admin_url, args.redis_url)
    faults = {"kill-worker": kill_worker, "restart-postgres": restart_postgres, "restart-redis": restart_redis}
    results: dict[str, Any] = {}
    for name in scenarios:
        t0 = time.perf_counter()
        if name == "quota":
            results[name] = quota_scenario(args, uploads, processor_env)
        else:
            results[name] = scale_out_scenario(args, uploads, faults[name](args), processor_env)
        results[name]["ok"] = _ok(results[name])
        results[name]["scenario_s"] = round(time.perf_counter() - t0, 1)
    return results


def _run(args: argparse.Namespace) -> int:
    try:
        results = run_faults(args)
    except (RuntimeError, ValueError) as exc:
        print(f"error: {exc}")
        return 2
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        for name, r in results.items():
            print(f"{name}: {'OK' if r['ok'] else 'FAILED'}  " + ", ".join(
                f"{k}={v}" for k, v in r.items() if k not in ("ok",)))
    return 0 if all(r["ok"] for r in results.values()) else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("faults", help="kill a worker, restart PostgreSQL/Redis, fill the data quota during "
                                             "a replay: no accepted batch lost, processing resumes")
    p.add_argument("--scenarios", default=",".join(SCENARIOS), help=f"comma-separated ({','.join(SCENARIOS)})")
    p.add_argument("--phones", type=int, default=4, help="concurrent phones (4)")
    p.add_argument("--minutes", type=float, default=1.0, help="minutes of data per phone (1)")
    p.add_argument("--pace-s", type=float, default=0.1, help="seconds between a phone's uploads (0.1)")
    p.add_argument("--webs", type=int, default=2, help="web processes (2)")
    p.add_argument("--workers", type=int, default=2, help="workers (2)")
    p.add_argument("--lease-s", type=float, default=5.0, help="workers' session lease TTL, s (5)")
    p.add_argument("--reconcile-s", type=float, default=2.0, help="workers' reconciler period, s (2)")
    p.add_argument("--restart-after-s", type=float, default=3.0, help="kill-worker: replacement delay, s (3)")
    p.add_argument("--redis-down-s", type=float, default=3.0, help="restart-redis: downtime, s (3)")
    p.add_argument("--quota-mb", type=float, default=2.0, help="quota: PDR_DATA_QUOTA_MB of the embedded run (2)")
    p.add_argument("--drain-timeout-s", type=float, default=300.0, help="give up waiting for the backlog (300)")
    p.add_argument("--postgres-restart-cmd", default=PG_RESTART, help="command restarting PostgreSQL")
    p.add_argument("--redis-stop-cmd", default=REDIS_STOP, help="command stopping Redis without saving")
    p.add_argument("--redis-start-cmd", default=REDIS_START, help="command starting Redis again")
    add_deployment_options(p)
    p.set_defaults(func=_run)
