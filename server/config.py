"""Service configuration from ``PDR_*`` environment variables, shared by ``pdr serve``, ``pdr users`` and workers.

| variable | meaning | default |
|---|---|---|
| ``PDR_DATA_DIR`` | data directory of the embedded default (SQLite file, report files) | ``./var`` |
| ``DATABASE_URL`` | SQLAlchemy URL; ``postgresql://...`` to scale out (``PDR_DATABASE_URL`` wins) | SQLite |
| ``PDR_MAX_UPLOAD_MB`` | largest accepted file upload (multipart log file, Allan report), MB | 64 |
| ``PDR_MAX_BATCH_MB`` | largest body of every other write (ingest, native batches, steps, JSON), MB | 8 |
| ``PDR_TRUSTED_PROXIES`` | number of reverse proxies in front of the service whose ``X-Forwarded-*`` is trusted | 0 |
| ``PDR_RETENTION_DAYS`` | delete raw batches of finished sessions this many days after their last batch; 0 = keep | 0 |
| ``PDR_WORKER`` | ``inprocess`` (a web-process thread), ``redis`` (``pdr worker`` jobs), ``none`` | ``inprocess`` |
| ``PDR_AUTH_FAILURES_PER_MINUTE`` | failed authentications per client address before 429 | 30 |
| ``PDR_MODELS_DIR`` | folder of trained classifier models | ``models/`` of the checkout |
| ``REDIS_URL`` | Redis of the job queue and shared rate limits (``PDR_WORKER=redis``) | ``redis://127.0.0.1:6379/0`` |
| ``PDR_REDIS_NAMESPACE`` | queue name and key prefix in Redis (several deployments can share one Redis) | ``pdr`` |
| ``PDR_DATA_QUOTA_MB`` | refuse uploads (507) once the data directory holds this much; 0 = no quota | 0 |
| ``PDR_PROCESSOR`` | ``module:callable`` processor factory (``server.processing.ProcessorFactory``) | built-in |
| ``PDR_NATIVE_THREADS`` | threads of the BLAS/OpenMP libraries in ``pdr serve`` and ``pdr worker`` processes | 1 |
| ``PDR_MAP_TILE_URL`` | tiles under geo-referenced sessions on the web page: ``https://HOST/{z}/{x}/{y}.png`` | none |
| ``PDR_MAP_TILE_ATTRIBUTION`` | the tiles' attribution text shown on the map (the tile provider's terms) | none |
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

REPO_ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Settings:
    """Resolved configuration of one service instance."""

    data_dir: Path
    database_url: str
    max_upload_bytes: int
    worker: str
    auth_failures_per_minute: int
    models_dir: Path
    redis_url: str = "redis://127.0.0.1:6379/0"
    redis_namespace: str = "pdr"
    data_quota_bytes: int = 0
    processor: str = "server.processors:make_processor"
    max_batch_bytes: int = 8 * 1024 * 1024
    trusted_proxies: int = 0
    retention_days: float = 0.0
    map_tile_url: str = ""
    map_tile_attribution: str = ""

    @property
    def is_sqlite(self) -> bool:
        return self.database_url.startswith("sqlite")


def _normalise_db_url(url: str) -> str:
    # Plain postgres:// or postgresql:// URLs (as most hosts hand them out) use the psycopg 3 driver.
    for prefix in ("postgres://", "postgresql://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url[len(prefix):]
    return url


def load_settings(environ: Mapping[str, str] | None = None, overrides: Mapping[str, object] | None = None) -> Settings:
    """Settings from the environment (``os.environ`` by default), with explicit overrides (tests)."""
    env = os.environ if environ is None else environ
    o = dict(overrides or {})
    data_dir = Path(str(o.get("data_dir") or env.get("PDR_DATA_DIR") or "var")).resolve()
    url = str(o.get("database_url") or env.get("PDR_DATABASE_URL") or env.get("DATABASE_URL")
              or f"sqlite:///{data_dir / 'pdr.sqlite3'}")
    worker = str(o.get("worker") or env.get("PDR_WORKER") or "inprocess")
    if worker not in ("inprocess", "none", "redis"):
        raise ValueError(f"PDR_WORKER must be 'inprocess', 'redis' or 'none', got {worker!r}")
    return Settings(
        data_dir=data_dir,
        database_url=_normalise_db_url(url),
        max_upload_bytes=int(float(str(o.get("max_upload_mb") or env.get("PDR_MAX_UPLOAD_MB") or 64)) * 1024 * 1024),
        worker=worker,
        auth_failures_per_minute=int(str(o.get("auth_failures_per_minute")
                                         or env.get("PDR_AUTH_FAILURES_PER_MINUTE") or 30)),
        models_dir=Path(str(o.get("models_dir") or env.get("PDR_MODELS_DIR") or REPO_ROOT / "models")),
        redis_url=str(o.get("redis_url") or env.get("REDIS_URL") or "redis://127.0.0.1:6379/0"),
        redis_namespace=str(o.get("redis_namespace") or env.get("PDR_REDIS_NAMESPACE") or "pdr"),
        data_quota_bytes=int(float(str(o.get("data_quota_mb") or env.get("PDR_DATA_QUOTA_MB") or 0)) * 1024 * 1024),
        processor=str(o.get("processor") or env.get("PDR_PROCESSOR") or "server.processors:make_processor"),
        max_batch_bytes=int(float(str(o.get("max_batch_mb") or env.get("PDR_MAX_BATCH_MB") or 8)) * 1024 * 1024),
        trusted_proxies=_non_negative_int("PDR_TRUSTED_PROXIES",
                                          o.get("trusted_proxies") or env.get("PDR_TRUSTED_PROXIES") or 0),
        retention_days=float(str(o.get("retention_days") or env.get("PDR_RETENTION_DAYS") or 0)),
        map_tile_url=tile_url(str(o.get("map_tile_url") or env.get("PDR_MAP_TILE_URL") or "")),
        map_tile_attribution=str(o.get("map_tile_attribution") or env.get("PDR_MAP_TILE_ATTRIBUTION") or ""),
    )


def tile_url(url: str) -> str:
    """A map tile URL template (``https://HOST/.../{z}/{x}/{y}.png``, ``{s}`` for subdomains allowed), or ""."""
    if not url:
        return ""
    parts = urlsplit(url.replace("{s}", "a"))
    if parts.scheme not in ("https", "http") or not parts.netloc or not all(k in url for k in ("{z}", "{x}", "{y}")):
        raise ValueError(f"PDR_MAP_TILE_URL must be an http(s) URL template with {{z}}, {{x}} and {{y}}, got {url!r}")
    return url


def tile_origins(url: str) -> list[str]:
    """The origins (``scheme://host``) the page loads tiles from, for its Content-Security-Policy."""
    if not url:
        return []
    parts = urlsplit(url)
    host = parts.netloc.replace("{s}", "*")   # subdomains a, b, c: one wildcard source
    return [f"{parts.scheme}://{host}"]


def _non_negative_int(name: str, raw: object) -> int:
    try:
        n = int(str(raw))
    except ValueError:
        raise ValueError(f"{name} must be a non-negative integer, got {raw!r}") from None
    if n < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {raw!r}")
    return n


def limit_native_threads(env: Mapping[str, str] | None = None) -> int:
    """Cap the BLAS/OpenMP thread pools of this process at ``PDR_NATIVE_THREADS`` (default 1); returns the cap.

    The service scales with processes (web processes, workers), and processing does many small matrix
    operations: a multi-threaded BLAS in each process only makes threads of several processes spin against
    each other. On this project's 2-core test machine under load, one thread halved a worker's time per
    live phone batch (``pdr bench processor``: 16.7 -> 8.3 ms).
    """
    from threadpoolctl import threadpool_limits

    raw = (env if env is not None else os.environ).get("PDR_NATIVE_THREADS", "1")
    try:
        n = int(raw)
    except ValueError:
        raise ValueError(f"PDR_NATIVE_THREADS must be a positive integer, got {raw!r}") from None
    if n < 1:
        raise ValueError(f"PDR_NATIVE_THREADS must be a positive integer, got {raw!r}")
    threadpool_limits(limits=n)
    return n


def safe_url(url: str) -> str:
    """``url`` without its password (never print credentials)."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:
        return url.split("@")[-1]
