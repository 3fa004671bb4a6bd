"""Flask application factory: configuration, storage (migrated on start), worker, blueprints, JSON errors."""

from __future__ import annotations

import logging
from typing import Any

from flask import Flask, request
from werkzeug.exceptions import RequestEntityTooLarge

from server import migrations, reliability, scaleout
from server.api import Services
from server.config import load_settings
from server.db import make_engine
from server.errors import register_error_handlers
from server.jobs import InProcessWorker, NoWorker
from server.processing import ProcessorFactory, SessionProcessing
from server.store import Store

log = logging.getLogger(__name__)


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
        InProcessWorker(processing, settle_s=float(cfg.get("settle_s", 0.2)))
        if settings.worker == "inprocess" else scaleout.external_worker(settings))

    app = Flask(__name__)
    app.config["MAX_CONTENT_LENGTH"] = settings.max_upload_bytes
    app.config["JSON_SORT_KEYS"] = False
    app.extensions["pdr"] = Services(settings, store, processing, worker,
                                     scaleout.failure_limiter(settings))
    register_error_handlers(app)

    @app.before_request
    def _reject_oversized() -> None:
        # Refuse a declared oversized body before authentication or parsing reads any of it.
        if request.content_length is not None and request.content_length > settings.max_upload_bytes:
            raise RequestEntityTooLarge()

    reliability.install(app, settings)  # data quota (507) after the size check; database down -> 503

    from server import web
    from server.api import foot, groups, ingest, meta, models, reports, results, sessions, track_columns, truth
    for module in (meta, sessions, results, ingest, truth, track_columns, models, reports, groups, foot, web):
        app.register_blueprint(module.bp)

    worker.start()
    worker.recover()
    return app
