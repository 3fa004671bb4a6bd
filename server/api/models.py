"""Classifier models: list, model card, and classification of an uploaded window (``POST /api/v1/classify``)."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from flask import Blueprint, Response, jsonify, send_file

from pdr.errors import InputError
from server import plausibility
from server.api import current_user, json_body, no_query_parameters, services
from server.api.sessions import time_span_ns
from server.errors import APIError
from server.schemas import CLASSIFY_WINDOW, validate

bp = Blueprint("models", __name__, url_prefix="/api/v1")

#: Model used by ``/classify`` when the request names none.
DEFAULT_MODEL = "motion_mode"
#: Longest time span of a batch to classify, s: more than an 8 MB body holds at phone rates. The windows cover the
#: whole span, gaps included (about 40 kB per second of it): a batch of two samples days apart took gigabytes.
MAX_CLASSIFY_SPAN_S = 1800.0


def _model_dirs() -> dict[str, Path]:
    root = services().settings.models_dir
    if not root.is_dir():
        return {}
    return {d.name: d for d in sorted(root.iterdir()) if (d / "model.json").is_file()}


#: Scalar metrics a model card shows per evaluation (the per-class table and confusion matrix are in the download).
CARD_METRICS = ("macro_f1", "macro_f1_target_classes", "accuracy", "balanced_accuracy", "coverage", "ece",
                "n_windows", "n_groups", "n_recordings")


def _card(name: str, d: Path) -> dict[str, Any]:
    """The model card of one artifact: what a user needs to judge the model, without its fitted internals.

    Task, classes, the metrics of every recorded evaluation with its title, protocol and command, the
    training data, the feature list, the library versions and the date of the artifact (its file's
    modification time, UTC: the artifact records none). The raw ``model.json`` is served by
    ``GET /models/NAME/model.json``.
    """
    path = d / "model.json"
    doc = json.loads(path.read_text(encoding="utf-8"))
    info: dict[str, Any] = doc["info"] if isinstance(doc.get("info"), dict) else {}
    training: dict[str, Any] = info["training_data"] if isinstance(info.get("training_data"), dict) else {}
    groups = training.get("groups")
    evaluations = []
    for ev in info.get("evaluations") or []:
        if not isinstance(ev, dict):
            continue
        metrics: dict[str, Any] = ev["metrics"] if isinstance(ev.get("metrics"), dict) else {}
        scalars = {k: metrics[k] for k in CARD_METRICS if isinstance(metrics.get(k), int | float)}
        # The protocol as the evaluation states it (newer artifacts), else its title.
        evaluations.append({"title": ev.get("title"), "protocol": ev.get("protocol") or ev.get("title"),
                            "command": ev.get("command"),
                            "target_classes": metrics.get("target_classes"), "metrics": scalars})
    names = doc.get("feature_names") if isinstance(doc.get("feature_names"), list) else []
    card: dict[str, Any] = {
        "name": name, "task": doc.get("task"), "estimator": doc.get("estimator_kind") or doc.get("estimator"),
        "classes": doc.get("classes"), "evaluations": evaluations,
        "training": {k: v for k, v in training.items() if k != "groups"}
        | ({"groups": len(groups)} if isinstance(groups, list) else {}),
        "train_command": info.get("train_command"), "window": doc.get("window"),
        "features": {"set_version": doc.get("feature_set_version"), "groups": doc.get("feature_groups"),
                     "count": len(names), "names": names, "required_streams": doc.get("required_streams")},
        "versions": doc.get("versions"),
        "date": datetime.fromtimestamp(path.stat().st_mtime, tz=UTC).isoformat(timespec="seconds"),
        "raw_bytes": path.stat().st_size,
    }
    if isinstance(doc.get("estimator"), str):  # an older artifact naming its estimator here
        card["estimator"] = doc["estimator"]
    return {k: v for k, v in card.items() if v is not None}


@bp.get("/models")
def list_models() -> Response:
    current_user()
    no_query_parameters()
    return jsonify({"models": [_card(n, d) for n, d in _model_dirs().items()]})


def _model_dir(name: str) -> Path:
    """The signed-in user's view of one installed model's folder; 404 when there is none of that name."""
    current_user()
    d = _model_dirs().get(name)
    if d is None:
        raise APIError(404, f"no model '{name[:64]}'")
    return d


@bp.get("/models/<name>")
def model_card(name: str) -> Response:
    d = _model_dir(name)
    card = d / "MODEL_CARD.md"
    return jsonify(_card(name, d) | {"card_markdown": card.read_text(encoding="utf-8") if card.is_file() else ""})


@bp.get("/models/<name>/model.json")
def model_artifact(name: str) -> Response:
    """The raw artifact (fitted estimator internals included), as a download."""
    return send_file(_model_dir(name) / "model.json", mimetype="application/json", as_attachment=True,
                     download_name=f"{name}.model.json")


@bp.post("/classify")
def classify() -> Response:
    """Classify the windows of a native batch with a shipped model; one decision per window."""
    from classifiers.artifacts import load_model
    from pdr.io.native import batch_from_json

    current_user(scope="read")  # computes an answer, stores nothing
    body = json_body("classification request")
    validate(body, CLASSIFY_WINDOW, "classification request")
    name = body.get("model", DEFAULT_MODEL)
    d = _model_dirs().get(name)
    if d is None:
        raise APIError(404, f"no model '{name[:64]}'")
    try:
        recording = batch_from_json(body["batch"], source="batch")
    except InputError as exc:
        raise APIError(422, str(exc), details=exc.details()) from None
    try:  # the windows cover the batch's whole span, gaps too: its size is bounded as an ingest route bounds it
        plausibility.check_span(*time_span_ns(recording, "streams"), MAX_CLASSIFY_SPAN_S)
        plausibility.check_units(recording)
    except APIError as exc:  # the request's field: the batch's, within 'batch'
        raise APIError(exc.status, exc.message, details=exc.details | {"field": f"batch.{exc.details['field']}"}
                       ) from None
    try:
        model = load_model(d)
        result = model.classify(recording)
    except InputError as exc:
        raise APIError(422, str(exc), details=exc.details()) from None
    rows = result.rows(recording.origin_ns / 1e9)
    if not rows:
        raise APIError(422, f"the batch is shorter than one window of the model ({model.window.length_s} s) "
                            "or has too few samples", details={"field": "batch"})
    return jsonify({"model": name, "windows": rows})
