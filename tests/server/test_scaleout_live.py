"""The scale-out deployment for real: 2 web processes + 2 workers on PostgreSQL and Redis give the same
tracks as the embedded default (one process, SQLite, in-process worker) for the same uploads.

The processor is the service's phone PDR processor once ``server/phone_processor.py`` exists, until then
the deterministic counting processor of the test suite (order-sensitive: a batch processed twice, lost or
out of time order changes the track).
"""

from __future__ import annotations

import importlib.util
import json
import random
import threading

import pytest

from server.bench.cluster import ReplayResult, fetch_tracks, replay_phones, running_cluster, wait_drained
from server.bench.server import simulated_phone, split_batches
from server.client import add_user, running_server
from server.config import REPO_ROOT
from tests.server.realservers import pg_database, redis_namespace  # noqa: F401  (fixtures)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]

REAL_PROCESSOR = importlib.util.find_spec("server.phone_processor") is not None
PROCESSOR = "server.processors:make_processor" if REAL_PROCESSOR else "tests.server.conftest:CountingProcessor"
ENV = {"PDR_PROCESSOR": PROCESSOR, "PYTHONPATH": str(REPO_ROOT)}


def phones(n: int, minutes: float) -> dict[str, list[tuple[str, bytes]]]:
    """``n`` simulated pocket walks as 1 s native batches; each phone sends a few batches late."""
    out = {}
    for k in range(n):
        batches = [(b["batch_id"], json.dumps(b).encode()) for b in split_batches(simulated_phone(minutes, seed=k),
                                                                                 1.0)]
        rng = random.Random(k)
        for i in rng.sample(range(1, len(batches) - 1), 3):  # swap neighbours: out-of-order uploads
            batches[i], batches[i + 1] = batches[i + 1], batches[i]
        out[f"phone-{k}"] = batches
    return out


def test_two_web_processes_and_two_workers_match_the_embedded_default(tmp_path, pg_database,  # noqa: F811
                                                                      redis_namespace):  # noqa: F811
    # Both deployments run at the same time, so that they run the same code even while the checkout changes.
    uploads = phones(3, 1.0)
    redis_url, ns = redis_namespace
    with running_server(tmp_path / "embedded", extra_env=ENV) as (url, env, _), \
            running_cluster(tmp_path / "cluster", pg_database, redis_url, ns, webs=2, workers=2, extra_env=ENV,
                            worker_args=["--lease-s", "5", "--reconcile-s", "2", "-v"]) as cluster:
        ref_token, token = add_user(env, "ref"), add_user(cluster.env, "scale")
        replays: dict[str, ReplayResult] = {}
        threads = [threading.Thread(target=lambda k, u, t: replays.__setitem__(k, replay_phones(u, t, uploads)),
                                    args=args) for args in (("ref", [url], ref_token), ("got", cluster.urls, token))]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        ref, got = replays["ref"], replays["got"]
        wait_drained(url, ref_token, list(ref.session_ids.values()))
        expected = fetch_tracks(url, ref_token, ref.session_ids)
        details = wait_drained(cluster.urls[1], token, list(got.session_ids.values()))
        tracks = fetch_tracks(cluster.urls[1], token, got.session_ids)
        logs = cluster.logs()

    assert got.refused == [] and got.retries == 0
    for name, batches in uploads.items():
        assert sorted(got.acknowledged[name]) == sorted(b for b, _ in batches)
    assert {sid: d["batches"] for sid, d in details.items()} == {
        sid: {"done": len(uploads[name])} for name, sid in got.session_ids.items()}
    assert all(len(t) > 0 for t in tracks.values())
    assert tracks == expected
    for i in range(2):  # both workers compiled (or loaded) the kernels before their first job, then took jobs
        assert f"pdr worker {ns}-w{i}: compiled kernels ready in " in logs
        assert f"{ns}-w{i}" in logs
    assert logs.count("Job OK") > 0
    assert token not in logs and ref_token not in logs


def test_short_load_loses_and_duplicates_nothing_and_drains():
    """``pdr bench load`` in small: 10 phones x 30 s of real-time 1 s batches, 2 web processes + 2 workers, and a
    3 MB log file uploaded meanwhile while ``/health`` is polled."""
    import argparse

    from server.bench.cluster import ensure_services
    from server.bench.load import run_load
    from tests.server.realservers import POSTGRES_ADMIN_URL, REDIS_TEST_URL

    try:
        ensure_services(POSTGRES_ADMIN_URL, REDIS_TEST_URL)
    except RuntimeError as exc:
        pytest.skip(str(exc))
    args = argparse.Namespace(phones=10, minutes=0.5, batch_s=1.0, webs=2, workers=2, recordings=2, flood=False,
                              big_upload_mb=3.0, drain_timeout_s=300.0, postgres_admin_url=POSTGRES_ADMIN_URL,
                              redis_url=REDIS_TEST_URL, processor=PROCESSOR)
    r = run_load(args)
    assert r["batches_acknowledged"] == r["batches_sent"] == 300 and r["refused"] == 0
    assert r["drained"] and r["lost"] == 0 and r["not_done"] == 0
    assert r["duplicated_batches"] == 0 and r["duplicated_track_points"] == 0
    # Latency is a figure of `pdr bench load`, not asserted here: a wall-clock bound flakes on a loaded machine.
    assert r["latency"]["p95_ms"] > 0.0
    big = r["big_upload"]  # a log file uploaded during the replay is a session, and /health answered meanwhile
    assert big["upload_status"] == 201 and big["upload_mb"] >= 3.0, big
    assert big["health_polls"] > 0 and big["health_statuses"] == {"200": big["health_polls"]}, big
