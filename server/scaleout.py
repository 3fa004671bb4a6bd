"""Choosing the scale-out pieces from the settings: processor factory, job submitter, failure limiter.

The embedded default (``PDR_WORKER=inprocess``, SQLite) uses none of Redis; ``PDR_WORKER=redis`` makes
web processes enqueue jobs for ``pdr worker`` (:mod:`server.queue`) and share the brute-force limit
(:mod:`server.shared_limits`).
"""

from __future__ import annotations

import importlib

from server.auth import FailureLimiter
from server.config import Settings
from server.jobs import NoWorker
from server.processing import ProcessorFactory


def load_processor_factory(spec: str) -> ProcessorFactory:
    """The processor factory named ``module:attribute`` (``PDR_PROCESSOR``)."""
    module_name, _, attr = spec.partition(":")
    if not module_name or not attr:
        raise ValueError(f"PDR_PROCESSOR must be 'module:callable', got {spec!r}")
    factory = getattr(importlib.import_module(module_name), attr)
    if not callable(factory):
        raise ValueError(f"PDR_PROCESSOR {spec!r} is not callable")
    return factory


def external_worker(settings: Settings) -> NoWorker:
    """The job submitter of a web process whose processing runs elsewhere (``PDR_WORKER`` redis or none)."""
    if settings.worker == "redis":
        from server.queue import RedisEnqueuer
        return RedisEnqueuer(settings)
    return NoWorker()


def failure_limiter(settings: Settings) -> FailureLimiter:
    """Per-process limiter in the embedded default; shared through Redis with ``PDR_WORKER=redis``."""
    if settings.worker == "redis":
        from server.queue import redis_client
        from server.shared_limits import RedisFailureLimiter
        return RedisFailureLimiter(settings.auth_failures_per_minute, redis_client(settings.redis_url),
                                   settings.redis_namespace)
    return FailureLimiter(settings.auth_failures_per_minute)
