"""Flask application factory: configuration, storage (migrated on start), worker, blueprints, JSON errors."""

from __future__ import annotations

import logging
import os
from typing import Any

from flask import Flask
from werkzeug.middleware.proxy_fix import ProxyFix

from server import migrations, reliability, scaleout
from server.access_log import AccessLogMiddleware
from server.api import Services, refuse_nul_in_url
from server.config import Settings, load_settings
from server.db import make_engine
from server.errors import register_error_handlers
from server.jobs import InProcessWorker, NoWorker, RetentionSweeper
from server.limits import BodyLimit, BodyLimitMiddleware, make_body_limit
from server.processing import ProcessorFactory, SessionProcessing
from server.report_jobs import ReportRunner
from server.store import Store

log = logging.getLogger(__name__)


def body_limit_of(settings: Settings) -> BodyLimit:
    """The per-route body limit of a service with these settings (WSGI middleware and waitress parser)."""
    return make_body_limit(settings.max_upload_bytes, settings.max_batch_bytes)


def create_app(test_config: dict[str, Any] | None = None) -> Flask:
    """Create the service.

    ``test_config`` overrides settings (``data_dir``, ``database_url``, ``worker``, ``max_upload_mb``,
    ``auth_failures_per_minute``, ``models_dir``, ``redis_url``, ``redis_namespace``, ``data_quota_mb``,
    ``processor``), and may inject ``processor_factory`` and ``settle_s``.
    """
    cfg = dict(test_config or {})
    settings = load_settings(overrides=cfg)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrations.upgrade(settings.database_url)
    store = Store(make_engine(settings.database_url))

    factory: ProcessorFactory
    if cfg.get("processor_factory") is not None:
        factory = cfg["processor_factory"]
    else:
        factory = scaleout.load_processor_factory(settings.processor)
    processing = SessionProcessing(store, factory)
    worker: InProcessWorker | NoWorker = (
        InProcessWorker(processing, settle_s=float(cfg.get("settle_s", 0.2)),
                        max_attempts=int(cfg.get("max_attempts") or os.environ.get("PDR_MAX_ATTEMPTS") or 5))
        if settings.worker == "inprocess" else scaleout.external_worker(settings))

    app = Flask(__name__)
    # One byte over the largest route limit: Werkzeug reads an unsized body (chunked, or a gzip body as inflated) only
    # up to this maximum and stops there silently, so it must ask server.limits' streams for the byte past a route's
    # limit, which they refuse with 413 (else a body of the largest limit or more was cut there: 'not valid JSON').
    app.config["MAX_CONTENT_LENGTH"] = max(settings.max_upload_bytes, settings.max_batch_bytes) + 1
    # A non-file form field (e.g. ``processing`` with a site description) may be as large as a batch.
    app.config["MAX_FORM_MEMORY_SIZE"] = settings.max_batch_bytes
    app.config["JSON_SORT_KEYS"] = False
    # Reports run where sessions are processed: on this process's thread, or as RQ jobs of ``pdr worker``.
    report_runner = ReportRunner(store, enqueue=getattr(worker, "submit_report", None))
    app.extensions["pdr"] = Services(settings, store, processing, worker,
                                     scaleout.failure_limiter(settings), report_runner)
    register_error_handlers(app)
    app.before_request(refuse_nul_in_url)   # before any view compares it with the database's text

    # Outermost first: the real client address (trusted proxies), the access log, then the body limits.
    app.wsgi_app = BodyLimitMiddleware(app.wsgi_app, body_limit_of(settings))  # type: ignore[method-assign]
    app.wsgi_app = AccessLogMiddleware(app.wsgi_app)  # type: ignore[method-assign]
    if settings.trusted_proxies:
        app.wsgi_app = ProxyFix(app.wsgi_app, x_for=settings.trusted_proxies,  # type: ignore[method-assign]
                                x_proto=settings.trusted_proxies, x_host=settings.trusted_proxies)
    reliability.install(app, settings)  # data quota (507) after the size check; database down -> 503

    from server import web
    from server.api import (
        foot,
        groups,
        ingest,
        meta,
        models,
        reports,
        results,
        sessions,
        sites,
        track_columns,
        truth,
    )
    for module in (meta, sessions, results, ingest, truth, track_columns, models, reports, groups, foot, sites, web):
        app.register_blueprint(module.bp)

    worker.start()
    worker.recover()
    if report_runner.runs_here:  # embedded: the only process, so every started report was interrupted
        report_runner.recover(every_interrupted=settings.worker == "inprocess")
    if settings.retention_days > 0:
        sweeper = RetentionSweeper(store, settings.retention_days)
        sweeper.start()
        app.extensions["pdr_retention"] = sweeper
    return app
