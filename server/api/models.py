"""Classifier models: list, model card, and classification of an uploaded window (``POST /api/v1/classify``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, jsonify

from pdr.errors import InputError
from server.api import current_user, json_body, services
from server.errors import APIError
from server.schemas import CLASSIFY_WINDOW, validate

bp = Blueprint("models", __name__, url_prefix="/api/v1")

#: Model used by ``/classify`` when the request names none.
DEFAULT_MODEL = "motion_mode"


def _model_dirs() -> dict[str, Path]:
    root = services().settings.models_dir
    if not root.is_dir():
        return {}
    return {d.name: d for d in sorted(root.iterdir()) if (d / "model.json").is_file()}


def _summary(name: str, d: Path) -> dict[str, Any]:
    doc = json.loads((d / "model.json").read_text(encoding="utf-8"))
    info = doc.get("info", {}) if isinstance(doc.get("info"), dict) else {}
    keys = ("task", "estimator", "classes", "created", "metrics", "window", "versions", "training")
    return {"name": name, **{k: doc.get(k, info.get(k)) for k in keys if doc.get(k, info.get(k)) is not None}}


@bp.get("/models")
def list_models() -> Response:
    current_user()
    return jsonify({"models": [_summary(n, d) for n, d in _model_dirs().items()]})


@bp.get("/models/<name>")
def model_card(name: str) -> Response:
    current_user()
    d = _model_dirs().get(name)
    if d is None:
        raise APIError(404, f"no model '{name}'")
    card = d / "MODEL_CARD.md"
    return jsonify(_summary(name, d) | {"card_markdown": card.read_text(encoding="utf-8") if card.is_file() else ""})


@bp.post("/classify")
def classify() -> Response:
    """Classify the windows of a native batch with a shipped model; one decision per window."""
    from classifiers.artifacts import load_model
    from pdr.io.native import batch_from_json

    current_user(scope="read")  # computes an answer, stores nothing
    body = json_body()
    validate(body, CLASSIFY_WINDOW, "classification request")
    name = body.get("model", DEFAULT_MODEL)
    d = _model_dirs().get(name)
    if d is None:
        raise APIError(404, f"no model '{name}'")
    try:
        recording = batch_from_json(body["batch"], source="batch")
        model = load_model(d)
        result = model.classify(recording)
    except InputError as exc:
        raise APIError(422, str(exc), details=exc.details()) from None
    rows = result.rows(recording.origin_ns / 1e9)
    if not rows:
        raise APIError(422, f"the batch is shorter than one window of the model ({model.window.length_s} s) "
                            "or has too few samples", details={"field": "batch"})
    return jsonify({"model": name, "windows": rows})
