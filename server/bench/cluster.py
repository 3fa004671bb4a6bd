"""A local scale-out deployment for tests and benchmarks: N ``pdr serve`` + M ``pdr worker`` processes.

All processes share one database (PostgreSQL) and one Redis namespace, as on a production machine;
:class:`Cluster` starts, kills and restarts them, and :func:`push` uploads a batch the way a phone app
should (retrying refused connections, 503 and 5xx answers with backoff, as uploads are idempotent).
"""

from __future__ import annotations

import http.client
import json
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from server.client import Client, Reply, free_port, pdr_command, wait_healthy

#: Answers after which a phone retries the same upload (idempotent by batch id); 507 (storage full) is final.
RETRY_STATUSES = {500, 502, 503, 504}


@dataclass
class Cluster:
    """Handles of the running processes; ``urls`` of the web processes, ``env`` they share."""

    data_dir: Path
    env: dict[str, str]
    urls: list[str] = field(default_factory=list)
    web: list[subprocess.Popen[bytes]] = field(default_factory=list)
    workers: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)
    worker_args: list[str] = field(default_factory=list)

    def start_web(self, index: int) -> str:
        port = free_port()
        log_path = self.data_dir / f"web{index}.log"
        with log_path.open("ab") as log:
            proc = subprocess.Popen([*pdr_command(), "serve", "--port", str(port)], env=self.env,
                                    stdout=log, stderr=subprocess.STDOUT)
        url = f"http://127.0.0.1:{port}"
        self.web.append(proc)
        self.urls.append(url)
        return url

    def start_worker(self, name: str) -> subprocess.Popen[bytes]:
        log_path = self.data_dir / f"{name}.log"
        with log_path.open("ab") as log:
            proc = subprocess.Popen([*pdr_command(), "worker", "--name", name, *self.worker_args], env=self.env,
                                    stdout=log, stderr=subprocess.STDOUT)
        self.workers[name] = proc
        return proc

    def kill_worker(self, name: str) -> None:
        """SIGKILL a worker (a crash: no clean-up, its job and lease are left behind)."""
        proc = self.workers[name]
        proc.send_signal(signal.SIGKILL)
        proc.wait()

    def logs(self) -> str:
        return "\n".join(p.read_text(errors="replace") for p in sorted(self.data_dir.glob("*.log")))

    def stop(self) -> None:
        for proc in [*self.web, *self.workers.values()]:
            if proc.poll() is None:
                proc.terminate()
        for proc in [*self.web, *self.workers.values()]:
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@contextmanager
def running_cluster(data_dir: Path, database_url: str, redis_url: str, namespace: str, webs: int = 2,
                    workers: int = 2, extra_env: dict[str, str] | None = None,
                    worker_args: list[str] | None = None) -> Iterator[Cluster]:
    """Start ``webs`` web processes (``PDR_WORKER=redis``) and ``workers`` workers; stop them afterwards."""
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "PDR_DATABASE_URL")}
    env.update({"PDR_DATA_DIR": str(data_dir), "DATABASE_URL": database_url, "REDIS_URL": redis_url,
                "PDR_REDIS_NAMESPACE": namespace, "PDR_WORKER": "redis", **(extra_env or {})})
    data_dir.mkdir(parents=True, exist_ok=True)
    cluster = Cluster(data_dir, env, worker_args=list(worker_args or []))
    with ExitStack() as stack:
        stack.callback(cluster.stop)
        for i in range(webs):
            cluster.start_web(i)
        for i in range(workers):
            cluster.start_worker(f"{namespace}-w{i}")
        for i, (url, proc) in enumerate(zip(cluster.urls, cluster.web, strict=True)):
            wait_healthy(url, proc, log_path=data_dir / f"web{i}.log")
        yield cluster


def push(client: Client, path: str, body: bytes, give_up_s: float = 120.0) -> tuple[Reply, int, float]:
    """POST ``body`` until the service answers something other than 500/502/503/504 or a refused connection.

    Returns (final reply, number of retries, seconds from the first attempt to the final answer).
    """
    t0 = time.perf_counter()
    delay, retries = 0.1, 0
    while True:
        try:
            reply = client.request("POST", path, raw=body)
            if reply.status not in RETRY_STATUSES:
                return reply, retries, time.perf_counter() - t0
        except (OSError, http.client.HTTPException):
            reply = None
        if time.perf_counter() - t0 > give_up_s:
            if reply is None:
                raise TimeoutError(f"no answer for {path} within {give_up_s} s")
            return reply, retries, time.perf_counter() - t0
        retries += 1
        time.sleep(delay)
        delay = min(delay * 2.0, 2.0)


@dataclass
class ReplayResult:
    """What a replay of phones observed from the client side."""

    session_ids: dict[str, str]
    acknowledged: dict[str, list[str]]
    latencies_s: list[float]
    retries: int = 0
    longest_retry_s: float = 0.0
    refused: list[str] = field(default_factory=list)


def replay_phones(urls: list[str], token: str, phones: dict[str, list[tuple[str, bytes]]], pace_s: float = 0.0,
                  progress: ReplayResult | None = None) -> ReplayResult:
    """Upload each phone's ``(batch_id, body)`` batches concurrently, one thread per phone.

    Consecutive batches of a phone go to different web processes in turn (so ordering across processes
    is exercised); ``pace_s`` > 0 sends one batch per ``pace_s`` seconds per phone (real time), else as
    fast as answered. Failed uploads (4xx after retries) are listed in ``refused``. ``progress``, if given,
    is filled while the replay runs (and returned).
    """
    admin = Client(urls[0], token)
    result = progress if progress is not None else ReplayResult({}, {}, [])
    result.acknowledged.update({name: [] for name in phones})
    for name in phones:
        reply, _, _ = push(admin, "/api/v1/sessions", json_bytes({"session_id": name}))
        result.session_ids[name] = reply.json()["id"]
    admin.close()
    lock = threading.Lock()

    def run(k: int, name: str) -> None:
        clients = [Client(u, token, timeout_s=60.0) for u in urls]
        sid = result.session_ids[name]
        t_next = time.perf_counter()
        for i, (batch_id, body) in enumerate(phones[name]):
            if pace_s > 0:
                t_next += pace_s
                time.sleep(max(0.0, t_next - time.perf_counter()))
            reply, retries, seconds = push(clients[(k + i) % len(clients)], f"/api/v1/sessions/{sid}/batches", body)
            with lock:
                result.retries += retries
                if retries:
                    result.longest_retry_s = max(result.longest_retry_s, seconds)
                if reply.status in (200, 201):
                    result.acknowledged[name].append(batch_id)
                    result.latencies_s.append(reply.seconds)
                else:
                    result.refused.append(f"{name}/{batch_id}: {reply.status} {reply.body[:200]!r}")
        for c in clients:
            c.close()

    threads = [threading.Thread(target=run, args=(k, name)) for k, name in enumerate(phones)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return result


def json_bytes(obj: Any) -> bytes:
    return json.dumps(obj).encode()


def wait_drained(url: str, token: str, session_ids: list[str], timeout_s: float = 300.0) -> dict[str, Any]:
    """Poll until no batch of the sessions is pending or processing; returns each session's detail."""
    c = Client(url, token)
    deadline = time.monotonic() + timeout_s
    try:
        while True:
            details: dict[str, Any] = {}
            for sid in session_ids:
                try:
                    reply = c.request("GET", f"/api/v1/sessions/{sid}")
                except (OSError, http.client.HTTPException):
                    break
                if reply.status != 200:
                    break
                details[sid] = reply.json()
            if len(details) == len(session_ids) and all(
                    d["batches"].get("pending", 0) == 0 and d["batches"].get("processing", 0) == 0
                    for d in details.values()):
                return details
            if time.monotonic() > deadline:
                raise TimeoutError(f"backlog not drained in {timeout_s} s: "
                                   f"{[d['batches'] for d in details.values()]}")
            time.sleep(0.5)
    finally:
        c.close()


def fetch_tracks(url: str, token: str, session_ids: dict[str, str]) -> dict[str, list[dict[str, Any]]]:
    """Each named session's track points (JSON rows)."""
    c = Client(url, token)
    try:
        return {name: c.request("GET", f"/api/v1/sessions/{sid}/track").json()["points"]
                for name, sid in session_ids.items()}
    finally:
        c.close()


def ensure_services(postgres_admin_url: str, redis_url: str) -> None:
    """Raise :class:`RuntimeError` saying what is missing when PostgreSQL or Redis cannot be reached."""
    import redis

    from server.queue import redis_client

    try:
        import psycopg

        psycopg.connect(postgres_admin_url, connect_timeout=3).close()
    except Exception as exc:
        raise RuntimeError(f"PostgreSQL not reachable at {postgres_admin_url}: {exc}") from None
    try:
        redis_client(redis_url).ping()
    except redis.exceptions.RedisError as exc:
        raise RuntimeError(f"Redis not reachable at {redis_url}: {exc}") from None


@contextmanager
def temporary_postgres(admin_url: str) -> Iterator[str]:
    """A new PostgreSQL database on the server of ``admin_url``; yields its URL, drops it afterwards."""
    import uuid

    import psycopg

    name = f"pdr_tmp_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(admin_url, autocommit=True, connect_timeout=5) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    try:
        yield f"{admin_url.rsplit('/', 1)[0]}/{name}"
    finally:
        deadline = time.monotonic() + 60
        while True:  # the server may be coming back from a fault-injection restart
            try:
                with psycopg.connect(admin_url, autocommit=True, connect_timeout=5) as admin:
                    admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
                break
            except psycopg.OperationalError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(1.0)
