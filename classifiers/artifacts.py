"""Saving and loading trained models: library-native files plus a model card, with compatibility checks.

A model is a folder ``models/<name>/``:

``model.json``
    Everything but the trees: format version, task, window settings, feature-set version and feature names,
    classes, smoothing and reject settings, library versions, training data and metrics, and the fitted
    parameters of Gaussian Bayes / landmark-tree estimators as plain numbers.
``booster.json``
    XGBoost's own JSON model (boosted-tree estimators only).
``MODEL_CARD.md``
    The human-readable card (generated from ``model.json``).

:func:`load_model` refuses, with an :class:`IncompatibleModelError` saying why, a model whose format,
feature set, feature names, window settings (when the caller requires specific ones) or library versions
do not fit this installation. No pickles: nothing in a model folder can execute code when loaded.
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np

from classifiers.features import FEATURE_GROUPS, FEATURE_SET_VERSION, feature_names
from classifiers.gaussian_densities import GaussianDensities
from classifiers.installed import resolve_model_dir
from classifiers.model import ContextModel
from classifiers.windows import WindowConfig
from pdr.errors import InputError

MODEL_FORMAT = "pdr-context-model"
MODEL_FORMAT_VERSION = 1
class IncompatibleModelError(InputError):
    """A saved model that this installation must not use (format, features, settings or versions differ)."""

    code = "incompatible_model"


def library_versions() -> dict[str, str]:
    """Versions of the libraries a model depends on."""
    out = {}
    for dist in ("pdr-backend", "numpy", "scipy", "scikit-learn", "xgboost-cpu", "xgboost"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            continue
    import xgboost

    out["xgboost"] = xgboost.__version__
    return out


def _major_minor(v: str) -> tuple[int, int]:
    parts = (v.split("+")[0].split(".") + ["0", "0"])[:2]
    try:
        return int(parts[0]), int("".join(ch for ch in parts[1] if ch.isdigit()) or 0)
    except ValueError:
        return (0, 0)


def save_model(model: ContextModel, out_dir: str | Path, name: str | None = None) -> Path:
    """Write ``model`` into ``out_dir`` (created); returns the folder."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = name or out.name
    est: dict[str, Any]
    if model.estimator_kind == "xgboost":
        est = model.estimator.save(str(out / "booster.json"))
    elif model.estimator_kind in ("bayes", "landmark_tree"):
        est = model.estimator.to_dict()
        stale = out / "booster.json"
        if stale.exists():
            stale.unlink()
    else:
        raise InputError(f"unknown estimator kind '{model.estimator_kind}'")
    doc = {
        "format": MODEL_FORMAT,
        "format_version": MODEL_FORMAT_VERSION,
        "name": name,
        "task": model.task,
        "estimator_kind": model.estimator_kind,
        "window": model.window.to_dict(),
        "feature_set_version": FEATURE_SET_VERSION,
        "feature_groups": list(model.feature_groups),
        "feature_names": model.feature_names,
        "required_streams": list(model.required_streams),
        "classes": list(model.classes),
        "train_priors": [float(p) for p in model.train_priors],
        "mean_dwell_s": float(model.mean_dwell_s),
        "reject_threshold": float(model.reject_threshold),
        "versions": library_versions(),
        "estimator": est,
        "stairs_direction": model.stairs_direction,
        "info": model.info,
    }
    (out / "model.json").write_text(json.dumps(doc, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    (out / "MODEL_CARD.md").write_text(model_card(doc), encoding="utf-8")
    return out


def load_model(name_or_path: str | Path, window: WindowConfig | None = None) -> ContextModel:
    """Load a saved model; :class:`IncompatibleModelError` if it does not fit this installation.

    Parameters
    ----------
    name_or_path
        Model folder or the name of a shipped model.
    window
        When given, the window settings the caller needs; a model trained with others is refused.
    """
    d = resolve_model_dir(name_or_path)
    src = str(d / "model.json")
    try:
        doc = json.loads((d / "model.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise IncompatibleModelError(f"cannot read model.json ({exc})", source=src) from None
    if doc.get("format") != MODEL_FORMAT or doc.get("format_version") != MODEL_FORMAT_VERSION:
        raise IncompatibleModelError(
            f"model format {doc.get('format')!r} version {doc.get('format_version')!r}; this installation reads "
            f"{MODEL_FORMAT!r} version {MODEL_FORMAT_VERSION}", source=src)
    if doc.get("feature_set_version") != FEATURE_SET_VERSION:
        raise IncompatibleModelError(
            f"model was trained with feature set version {doc.get('feature_set_version')}, this installation "
            f"computes version {FEATURE_SET_VERSION}; retrain it with 'pdr train'", source=src)
    groups = tuple(doc.get("feature_groups", ()))
    unknown = [g for g in groups if g not in FEATURE_GROUPS]
    if unknown or doc.get("feature_names") != feature_names(groups):
        raise IncompatibleModelError("the model's feature names differ from this installation's features "
                                     f"(unknown groups: {unknown}); retrain it", source=src)
    cfg = WindowConfig.from_dict(doc["window"])
    if window is not None and cfg != window:
        raise IncompatibleModelError(f"model window settings {cfg.to_dict()} differ from the required "
                                     f"{window.to_dict()}", source=src)
    kind = doc.get("estimator_kind")
    versions = doc.get("versions", {})
    if kind == "xgboost":
        booster = d / "booster.json"
        if not booster.is_file():
            raise IncompatibleModelError("booster.json is missing", source=str(d))
        import xgboost

        from classifiers.boosting import BoostedTreeClassifier, booster_json_version

        saved = versions.get("xgboost", ".".join(str(v) for v in booster_json_version(str(booster))))
        if _major_minor(xgboost.__version__) < _major_minor(saved):
            raise IncompatibleModelError(f"model was saved by xgboost {saved}; installed xgboost "
                                         f"{xgboost.__version__} is older and cannot read it", source=src)
        if _major_minor(saved)[0] < 2:
            raise IncompatibleModelError(f"model was saved by xgboost {saved} (< 2.0); retrain it", source=src)
        estimator: Any = BoostedTreeClassifier.load(str(booster), doc["estimator"])
    elif kind == "bayes":
        # The densities alone: classifying needs neither scikit-learn nor the estimator (module doc of
        # classifiers.gaussian_densities).
        estimator = GaussianDensities.from_dict(doc["estimator"])
    elif kind == "landmark_tree":
        from classifiers.landmark_tree import LandmarkTreeClassifier

        estimator = LandmarkTreeClassifier.from_dict(doc["estimator"])
    else:
        raise IncompatibleModelError(f"unknown estimator kind {kind!r}", source=src)
    classes = [str(c) for c in estimator.classes_]
    if classes != doc.get("classes"):
        raise IncompatibleModelError("the estimator's classes differ from the model's class list", source=src)
    if estimator.n_features_in_ != len(doc["feature_names"]):
        raise IncompatibleModelError("the estimator's input size differs from the feature list", source=src)
    info = dict(doc.get("info", {}))
    info["name"] = doc.get("name", d.name)
    info["versions"] = versions
    return ContextModel(task=doc["task"], window=cfg, feature_groups=groups, estimator_kind=kind,
                        estimator=estimator, train_priors=np.asarray(doc["train_priors"], dtype=np.float64),
                        mean_dwell_s=float(doc["mean_dwell_s"]), reject_threshold=float(doc["reject_threshold"]),
                        info=info, stairs_direction=doc.get("stairs_direction"))


def _fmt_metrics(metrics: dict[str, Any]) -> list[str]:
    lines = []
    for key in ("macro_f1", "macro_f1_target_classes", "accuracy", "ece", "n_windows", "n_groups",
                "windows_per_s", "classifier_windows_per_s", "features_and_classifier_windows_per_s",
                "end_to_end_windows_per_s"):
        if key in metrics:
            v = metrics[key]
            lines.append(f"- {key}: {v:.4f}" if isinstance(v, float) else f"- {key}: {v}")
    if "target_classes" in metrics:
        lines.append(f"- target classes: {', '.join(metrics['target_classes'])}")
    per = metrics.get("per_class", {})
    if per:
        lines += ["", "| class | precision | recall | F1 | support |", "|---|---|---|---|---|"]
        for c, m in per.items():
            lines.append(f"| {c} | {m['precision']:.3f} | {m['recall']:.3f} | {m['f1']:.3f} | {m['support']} |")
    for place, sub in metrics.get("per_placement", {}).items():
        head = f"Placement **{place}**: {sub['n_windows']} windows, macro-F1 {sub['macro_f1']:.4f}"
        if "macro_f1_target_classes" in sub:
            head += f", over the target classes present {sub['macro_f1_target_classes']:.4f}"
        lines += ["", head, "", "| class | precision | recall | F1 | support |", "|---|---|---|---|---|"]
        for c, m in sub["per_class"].items():
            lines.append(f"| {c} | {m['precision']:.3f} | {m['recall']:.3f} | {m['f1']:.3f} | {m['support']} |")
    return lines


def model_card(doc: dict[str, Any]) -> str:
    """The Markdown model card of a ``model.json`` document."""
    info = doc.get("info", {})
    w = doc["window"]
    lines = [
        f"# Model card: {doc['name']}",
        "",
        f"Task: **{doc['task']}**. Estimator: **{doc['estimator_kind']}**"
        + (f" ({info['estimator_params']})" if info.get("estimator_params") else "") + ".",
        "",
        "## Classes",
        ", ".join(doc["classes"]) + f" (and `unknown` below a smoothed posterior of {doc['reject_threshold']}).",
        "",
        "## Training data",
    ]
    td = info.get("training_data", {})
    for key, val in td.items():
        lines.append(f"- {key}: {val}")
    if info.get("train_command"):
        lines += ["", f"Trained with: `{info['train_command']}`"]
    lines += [
        "",
        "## Window settings",
        f"{w['length_s']} s windows every {w['hop_s']} s on a {w['rate_hz']} Hz grid "
        f"(usable when at least {w['min_valid_fraction']:.0%} of accelerometer samples are present). "
        f"Markov smoothing with a mean dwell time of {doc['mean_dwell_s']} s.",
        "",
        "## Features",
        f"Feature set version {doc['feature_set_version']}, groups {', '.join(doc['feature_groups'])} "
        f"({len(doc['feature_names'])} features; names in model.json). Required streams: "
        f"{', '.join(doc['required_streams'])}.",
        "",
        "## Library versions",
        ", ".join(f"{k} {v}" for k, v in doc["versions"].items()),
        "",
        "## Metrics",
    ]
    evals = info.get("evaluations", [])
    if not evals:
        lines.append("Not evaluated yet.")
    for ev in evals:
        lines += ["", f"### {ev.get('title', 'evaluation')}", "", f"Command: `{ev.get('command', '')}`", ""]
        if ev.get("protocol"):
            lines += [f"Protocol: {ev['protocol']}.", ""]
        lines += _fmt_metrics(ev.get("metrics", {}))
    if info.get("notes"):
        lines += ["", "## Notes", str(info["notes"])]
    return "\n".join(lines) + "\n"
