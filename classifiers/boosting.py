"""Gradient tree boosting (XGBoost, seed 004 Sec. 4.1 ref. [10]) with the scikit-learn contract.

A thin estimator around :class:`xgboost.XGBClassifier` that accepts any class labels (XGBoost wants
0..r-1), balances classes by sample weights when asked, handles NaN features natively (missing sensor),
and saves to / loads from XGBoost's own JSON model format (no pickles).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import xgboost
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

FloatArray = NDArray[np.float64]


class BoostedTreeClassifier(ClassifierMixin, BaseEstimator):
    """XGBoost multi-class trees.

    Parameters
    ----------
    n_estimators, max_depth, learning_rate, subsample, colsample_bytree, min_child_weight, reg_lambda
        XGBoost hyperparameters (rounds, tree depth, shrinkage, row and column subsampling, leaf weight
        and L2 regularisation).
    class_weight
        ``"balanced"`` weights each sample by ``n / (r * n_class)``; a dict maps class -> weight; None
        leaves them equal.
    n_jobs
        Threads for training and inference (1: the shared machine has two cores).
    random_state
        Seed of the row/column subsampling.

    Attributes
    ----------
    classes_ : (r,) labels. booster_ : the fitted :class:`xgboost.Booster`.
    """

    def __init__(self, n_estimators: int = 200, max_depth: int = 4, learning_rate: float = 0.1,
                 subsample: float = 0.8, colsample_bytree: float = 0.5, min_child_weight: float = 1.0,
                 reg_lambda: float = 1.0, class_weight: str | dict[Any, float] | None = "balanced", n_jobs: int = 1,
                 random_state: int = 0) -> None:
        self.n_estimators = n_estimators
        self.max_depth = max_depth
        self.learning_rate = learning_rate
        self.subsample = subsample
        self.colsample_bytree = colsample_bytree
        self.min_child_weight = min_child_weight
        self.reg_lambda = reg_lambda
        self.class_weight = class_weight
        self.n_jobs = n_jobs
        self.random_state = random_state

    def fit(self, X: Any, y: Any, sample_weight: ArrayLike | None = None) -> BoostedTreeClassifier:
        """Fit on (n, q) features (NaN = missing) and (n,) labels."""
        X, y = validate_data(self, X, y, dtype=np.float64, ensure_all_finite="allow-nan")
        check_classification_targets(y)
        self.classes_, yi = np.unique(y, return_inverse=True)
        w = np.ones(yi.size) if sample_weight is None else np.asarray(sample_weight, dtype=np.float64)
        if self.class_weight == "balanced":
            counts = np.bincount(yi)
            w = w * (yi.size / (counts.size * counts))[yi]
        elif isinstance(self.class_weight, dict):
            w = w * np.array([float(self.class_weight.get(c, 1.0)) for c in self.classes_])[yi]
        elif self.class_weight is not None:
            raise ValueError(f"class_weight must be 'balanced', a dict or None, got {self.class_weight!r}")
        if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ValueError("sample weights must be non-negative, finite and not all zero")
        r = self.classes_.size
        params: dict[str, Any] = {
            "max_depth": self.max_depth, "eta": self.learning_rate, "subsample": self.subsample,
            "colsample_bytree": self.colsample_bytree, "min_child_weight": self.min_child_weight,
            "lambda": self.reg_lambda, "nthread": self.n_jobs, "seed": self.random_state,
            "tree_method": "hist", "verbosity": 0,
        }
        if r > 2:
            params.update(objective="multi:softprob", num_class=r)
        else:
            params.update(objective="binary:logistic")
        dtrain = xgboost.DMatrix(X, label=yi, weight=w, missing=np.nan, nthread=self.n_jobs)
        self.booster_ = xgboost.train(params, dtrain, num_boost_round=self.n_estimators)
        return self

    def predict_proba(self, X: Any) -> FloatArray:
        """(n, r) class probabilities."""
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, ensure_all_finite="allow-nan", reset=False)
        if X.shape[0] == 0:
            return np.zeros((0, self.classes_.size))
        p = np.asarray(self.booster_.inplace_predict(X, missing=np.nan), dtype=np.float64)
        if self.classes_.size == 1:
            return np.ones((X.shape[0], 1))
        if p.ndim == 1:
            p = np.column_stack([1.0 - p, p])
        return p

    def predict(self, X: Any) -> NDArray[Any]:
        """The most probable class of each row."""
        check_is_fitted(self)
        return np.asarray(self.classes_[np.argmax(self.predict_proba(X), axis=1)])

    # -- serialisation: XGBoost JSON for the trees, plain JSON for the rest --
    def save(self, booster_path: str) -> dict[str, Any]:
        """Write the trees as XGBoost JSON to ``booster_path``; returns the rest as a JSON-able dict."""
        check_is_fitted(self)
        self.booster_.save_model(booster_path)
        return {"params": self.get_params(), "classes": [str(c) for c in self.classes_],
                "n_features_in": int(self.n_features_in_)}

    @classmethod
    def load(cls, booster_path: str, meta: dict[str, Any]) -> BoostedTreeClassifier:
        """Inverse of :meth:`save`."""
        m = cls(**meta["params"])
        booster = xgboost.Booster()
        booster.load_model(booster_path)
        booster.set_param({"nthread": int(meta["params"].get("n_jobs", 1))})
        m.booster_ = booster
        m.classes_ = np.asarray(meta["classes"], dtype=object)
        m.n_features_in_ = int(meta["n_features_in"])
        return m


def booster_json_version(booster_path: str) -> list[int]:
    """The XGBoost version recorded in a saved JSON model (``[major, minor, patch]``)."""
    with open(booster_path, encoding="utf-8") as f:
        return [int(v) for v in json.load(f)["version"]]
