"""Fixtures for the real PostgreSQL and Redis servers of the machine (skipped cleanly when absent).

PostgreSQL: a fresh database per test on ``PDR_TEST_POSTGRES_URL`` (default the CI server
``postgresql://postgres@127.0.0.1:5432/test``), dropped afterwards. Redis: ``PDR_TEST_REDIS_URL``
(default database 13 of ``127.0.0.1:6379``, away from the default 0) with a unique namespace per test;
only that namespace's keys are deleted afterwards.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

POSTGRES_ADMIN_URL = os.environ.get("PDR_TEST_POSTGRES_URL", "postgresql://postgres@127.0.0.1:5432/test")
REDIS_TEST_URL = os.environ.get("PDR_TEST_REDIS_URL", "redis://127.0.0.1:6379/13")


@pytest.fixture
def pg_database() -> Iterator[str]:
    """URL of a new, empty PostgreSQL database (dropped after the test)."""
    psycopg = pytest.importorskip("psycopg")
    try:
        admin = psycopg.connect(POSTGRES_ADMIN_URL, autocommit=True, connect_timeout=3)
    except psycopg.OperationalError as exc:
        pytest.skip(f"no PostgreSQL server reachable at {POSTGRES_ADMIN_URL}: {exc}")
    name = f"pdr_test_{uuid.uuid4().hex[:12]}"
    admin.execute(f'CREATE DATABASE "{name}"')
    try:
        yield f"{POSTGRES_ADMIN_URL.rsplit('/', 1)[0]}/{name}"
    finally:
        try:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        except psycopg.OperationalError:  # the server was restarted by a fault test: reconnect once
            admin = psycopg.connect(POSTGRES_ADMIN_URL, autocommit=True, connect_timeout=10)
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.close()


@pytest.fixture(params=["sqlite", "postgresql"])
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """SQLAlchemy URL of an empty database, in turn a SQLite file and a fresh PostgreSQL database (migration tests)."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'legacy.db'}"
    else:
        yield "postgresql+psycopg://" + request.getfixturevalue("pg_database").split("://", 1)[1]


@pytest.fixture
def redis_namespace() -> Iterator[tuple[str, str]]:
    """(Redis URL, unique namespace); the namespace's keys are purged after the test."""
    redis = pytest.importorskip("redis")
    from server.queue import purge_namespace, redis_client

    conn = redis_client(REDIS_TEST_URL)
    try:
        conn.ping()
    except redis.exceptions.RedisError as exc:
        pytest.skip(f"no Redis server reachable at {REDIS_TEST_URL}: {exc}")
    namespace = f"pdrtest-{uuid.uuid4().hex[:10]}"
    try:
        yield REDIS_TEST_URL, namespace
    finally:
        try:
            purge_namespace(conn, namespace)
        except redis.exceptions.RedisError:
            pass
        conn.close()
