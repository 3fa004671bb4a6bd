"""Fitting context models and grouped (leave-one-group-out) cross-validation.

Feature groups whose sensor is missing from any training recording are left out of the model (a model
must not learn "has a magnetometer" as a proxy for a class), and the model then requires exactly the
streams of the groups it kept. Cross-validation leaves out one group -- a subject, or a recording when
the source names no subject -- at a time, fits on the rest and predicts the held-out windows recording by
recording, with the same Markov smoothing and reject option as in use. Windows are never shuffled
across groups.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from numpy.typing import NDArray

from classifiers import stairs_direction
from classifiers.bayes import GaussianBayesClassifier
from classifiers.boosting import BoostedTreeClassifier
from classifiers.datasets import LabelledWindows
from classifiers.features import FEATURE_GROUPS, feature_names
from classifiers.landmark_tree import LandmarkTreeClassifier
from classifiers.model import ContextModel, WindowResults
from classifiers.sequence import forward_backward
from classifiers.tasks import Task
from classifiers.windows import WindowConfig
from pdr.errors import InputError
from pdr.recording import Recording

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

ESTIMATOR_KINDS = ("bayes", "xgboost", "landmark_tree")


def available_groups(recordings: list[Recording], task: Task) -> tuple[str, ...]:
    """The task's feature groups whose sensor stream every recording has."""
    return tuple(g for g in task.feature_groups if all(r.has(FEATURE_GROUPS[g][0]) for r in recordings))


def make_estimator(kind: str, columns: list[str], params: dict[str, Any] | None = None) -> Any:
    """A fresh estimator of ``kind`` with default hyperparameters updated by ``params``."""
    params = dict(params or {})
    if kind == "bayes":
        return GaussianBayesClassifier(**{"covariance": "tied", "shrinkage": "auto", **params})
    if kind == "xgboost":
        return BoostedTreeClassifier(**{"n_jobs": 1, **params})
    if kind == "landmark_tree":
        return LandmarkTreeClassifier(columns=columns, **params)
    raise InputError(f"unknown estimator '{kind}'; expected one of {ESTIMATOR_KINDS}", field="estimator")


def fit_model(data: LabelledWindows, task: Task, cfg: WindowConfig, groups: tuple[str, ...], kind: str,
              params: dict[str, Any] | None = None, reject_threshold: float = 0.5,
              mean_dwell_s: float | None = None) -> ContextModel:
    """Fit a :class:`ContextModel` of ``kind`` on labelled windows whose features are ``groups``."""
    X, y = data.X, data.y.astype(str)
    if kind == "bayes":
        ok = np.isfinite(X).all(axis=1)
        if (~ok).any():
            log.info("bayes: %d of %d training windows have missing features and are not used",
                     int((~ok).sum()), ok.size)
        X, y = X[ok], y[ok]
    if np.unique(y).size < 2:
        raise InputError(f"training needs at least two classes, got {sorted(set(y))}")
    est = make_estimator(kind, feature_names(groups), params)
    est.fit(X, y)
    if kind == "bayes":
        priors = np.asarray(est.priors_, dtype=np.float64)
    elif kind == "xgboost" and est.class_weight != "balanced":
        priors = np.array([np.mean(y == c) for c in est.classes_])
    else:
        priors = np.full(len(est.classes_), 1.0 / len(est.classes_))
    return ContextModel(task=task.name, window=cfg, feature_groups=groups, estimator_kind=kind, estimator=est,
                        train_priors=priors, stairs_direction=stairs_direction.fit(X, y, feature_names(groups)),
                        mean_dwell_s=task.mean_dwell_s if mean_dwell_s is None else mean_dwell_s,
                        reject_threshold=reject_threshold)


def predict_sequences(model: ContextModel, data: LabelledWindows) -> WindowResults:
    """Decisions for labelled windows, smoothed recording by recording (offline forward-backward), with the
    barometric stage where the windows have pressure data (:meth:`ContextModel.emissions`).
    """
    raw, usable = model.window_proba(data.X)
    smoothed = raw.copy()
    if model.mean_dwell_s > 0:
        r = len(model.classes)
        for rec in np.unique(data.recording):
            rows = np.flatnonzero(data.recording == rec)
            rows = rows[np.argsort(data.t_start_s[rows], kind="stable")]
            speed = None if data.baro is None else (data.baro[rows, 0], data.baro[rows, 1])
            ll = model.emissions(raw[rows], usable[rows], speed)
            smoothed[rows] = forward_backward(ll, model.transitions(), np.full(r, 1.0 / r))
    return model.decide(smoothed, raw, usable, data.t_start_s, data.t_end_s)


def cross_validate(data: LabelledWindows, task: Task, cfg: WindowConfig, groups: tuple[str, ...], kind: str,
                   params: dict[str, Any] | None = None, reject_threshold: float = 0.5,
                   mean_dwell_s: float | None = None) -> tuple[WindowResults, list[str]]:
    """Leave-one-group-out predictions for every window, and the class list (union over folds).

    Returns results whose ``proba``/``raw_proba`` columns follow the returned class list.
    """
    classes = sorted(set(data.y.astype(str)))
    n = len(data)
    labels = np.empty(n, dtype=object)
    conf = np.zeros(n)
    proba = np.zeros((n, len(classes)))
    raw = np.zeros((n, len(classes)))
    names = np.unique(data.groups.astype(str))
    if names.size < 2:
        raise InputError("grouped cross-validation needs at least two groups (subjects or recordings)")
    for g in names:
        test = data.groups.astype(str) == g
        train = data.select(~test)
        if np.unique(train.y.astype(str)).size < 2:
            continue
        model = fit_model(train, task, cfg, groups, kind, params, reject_threshold, mean_dwell_s)
        res = predict_sequences(model, data.select(test))
        cols = np.array([classes.index(c) for c in res.classes], dtype=np.int64)
        idx = np.flatnonzero(test)
        labels[idx] = np.asarray(res.label, dtype=object)
        conf[idx] = res.confidence
        proba[np.ix_(idx, cols)] = res.proba
        raw[np.ix_(idx, cols)] = res.raw_proba
        log.info("fold %s: %d windows", g, idx.size)
    return WindowResults(data.t_start_s, data.t_end_s, tuple(str(v) for v in labels), conf, proba, raw,
                         tuple(classes)), classes
