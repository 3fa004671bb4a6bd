"""Landmark identification decision tree of seed 003 Sec. 3 (Fig. 2, Table 1) with thresholds learned from data.

The seed's tree separates five motion states -- elevator, escalator, stairs, walking, standing -- in three
levels; every split is a threshold on one feature:

* intensity (seed level 2): the acceleration variance separates {stairs, walking} from the low-intensity
  {escalator, standing} and the elevator ride;
* escalator (seed level 3): among low-intensity windows, the variance of the magnetic field (moving
  escalator), together with the pressure slope around the window;
* elevator vs standing (seed level 1): the seed decides per ride, with context -- the magnetic magnitude
  change of the cabin against the corridor outside it, the hyper-/hypo-gravity impulse pair seconds apart,
  the pressure change of the ride; here these are the context features (:mod:`classifiers.context`) of a
  span around the window, so a window of standing in the cabin before it moves is an elevator window. The
  seed tests the elevator first on all windows; here it is tested after the escalator because both rides
  change the pressure and only the magnetic field tells them apart;
* stairs vs walking (seed level 3): the leg-pitch pattern of eqs. 1-3 (opening angle and extreme pitch
  values), or the pressure slope over a flight (the seed avoids the barometer; we keep it as a candidate
  because hand-held phones show no leg pitch, and a slope over 7.68 s is far less noisy than over one
  window).

Each split is a rule over a list of candidate features (``SPLIT_CANDIDATES``), learned by maximising
balanced accuracy: a decision stump on one feature, or a stump combined with a second cue on another
feature, kept when the combination costs at most ``COMBINE_TOLERANCE`` balanced accuracy on the training
windows (against the first stump and against the best single stump); ``SPLIT_COMBINE`` says which
combination each split may use:

* ``any`` (union): one event is recognised by any of its independent cues -- an elevator by the magnetic
  change of the cabin *or* by the pressure change of the ride -- so a building whose cabin hardly changes
  the field, or a recording without a magnetometer, is still covered. The cue's threshold lies beyond the
  ``SPECIFIC_QUANTILE`` of the negatives the first stump leaves, and it must flag at least ``MIN_CUE_SHARE``
  of the positives on its own.
* ``all`` (intersection): a necessary condition -- an escalator moves the magnetic field *and* the
  pressure, so a step of the field at a cabin door is not an escalator. The cue's threshold keeps all but
  ``1 - SPECIFIC_QUANTILE`` of the positives the first stump flags, and it must reject at least
  ``MIN_CUE_SHARE`` of the negatives on its own.

The cue's direction is the one that separates the classes on its own: it describes the cue, not the few
windows the first stump happens to get wrong in the training data. All rules with data are ranked
(combined rules first, then single stumps, each by balanced accuracy), and at prediction the best-ranked
rule whose features are all present in the window is used, so a recording without a barometer or
magnetometer still goes through the tree. ``predict_proba`` returns the (Laplace-smoothed) class frequencies
of the training windows in the leaf, so the output can be Markov-smoothed like any other classifier; the
seed's neighbour-step correction is that smoothing's special case.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from classifiers.features import feature_names

FloatArray = NDArray[np.float64]

#: Feature groups the tree reads by default (the column layout when ``columns`` is None).
LANDMARK_GROUPS: tuple[str, ...] = ("acc", "gait", "gyro", "gyro_pitch", "coning", "pitch", "elevator", "mag", "baro",
                                    "ctx_acc", "ctx_mag", "ctx_baro")

#: Split -> candidate features; ``abs:`` uses the magnitude, ``neg:`` the negated value.
SPLIT_CANDIDATES: dict[str, tuple[str, ...]] = {
    "intensity": ("anorm_std", "ahor_std", "anorm_mad", "gnorm_mean"),
    "elevator": ("neg:ctx_mag_log_ratio_max", "abs:ctx_baro_slope_hpa_s", "abs:ctx_baro_slope_long_hpa_s",
                 "ctx_avert_lp_max", "neg:ctx_avert_lp_min", "abs:baro_slope_hpa_s", "avert_lp_max",
                 "neg:avert_lp_min"),
    "escalator": ("mag_var", "mag_comp_var", "abs:ctx_baro_slope_hpa_s", "abs:baro_slope_hpa_s"),
    "stairs": ("abs:ctx_baro_slope_hpa_s", "abs:baro_slope_hpa_s", "gpitch_opening_rad", "pitch_opening_rad",
               "pitch_max_rad", "pitch_min_neg_rad", "avert_skew", "gnorm_mean"),
}
#: Split -> how a second cue may combine with the first (module docstring): an elevator or a flight of stairs
#: shows any of its cues, an escalator must show all of them (moving field and vertical motion); the
#: intensity split is one stump.
SPLIT_COMBINE: dict[str, tuple[str, ...]] = {"intensity": (), "escalator": ("all",), "elevator": ("any",),
                                             "stairs": ("any",)}
#: Split -> (classes on its positive side, classes on its negative side).
SPLIT_SIDES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "intensity": (("stairs", "walking"), ("elevator", "escalator", "standing")),
    "escalator": (("escalator",), ("elevator", "standing")),
    "elevator": (("elevator",), ("standing",)),
    "stairs": (("stairs",), ("walking",)),
}
LEAVES: tuple[str, ...] = ("stairs", "walking", "elevator", "escalator", "standing")
#: Largest loss of training balanced accuracy accepted for adding a second cue to a split (module docstring).
COMBINE_TOLERANCE = 0.005
#: Share of the windows a second cue's threshold is set beyond (module docstring).
SPECIFIC_QUANTILE = 0.995
#: Smallest share of the positives (union) or negatives (intersection) a second cue must decide on its own.
MIN_CUE_SHARE = 0.2

#: A stump: (candidate feature, threshold, direction +1/-1); positive when ``direction * (x - threshold) > 0``.
Stump = tuple[str, float, float]
#: A split rule: how its stumps combine (``any``/``all``), the stumps, and its training balanced accuracy.
Rule = tuple[str, tuple[Stump, ...], float]


def balanced_accuracy(pred: NDArray[np.bool_], positive: NDArray[np.bool_]) -> float:
    """Mean of the true-positive and true-negative rates (0.5 each when a side is empty)."""
    n_pos, n_neg = int(positive.sum()), int((~positive).sum())
    tpr = float((pred & positive).sum()) / n_pos if n_pos else 0.5
    tnr = float((~pred & ~positive).sum()) / n_neg if n_neg else 0.5
    return 0.5 * (tpr + tnr)


def fit_stump(x: FloatArray, positive: NDArray[np.bool_]) -> tuple[float, float, float]:
    """Threshold ``thr`` and direction ``s`` (+1: ``x > thr`` is positive, -1: ``x < thr``) of best balanced
    accuracy; returns ``(thr, s, balanced_accuracy)``. NaN values are ignored.
    """
    ok = np.isfinite(x)
    x, pos = x[ok], positive[ok]
    n_pos, n_neg = int(pos.sum()), int((~pos).sum())
    if n_pos == 0 or n_neg == 0:
        return float("nan"), 1.0, 0.0
    order = np.argsort(x, kind="stable")
    xs, ps = x[order], pos[order]
    # Threshold between sorted i and i+1: below = first i+1 values.
    pos_below = np.cumsum(ps)[:-1]
    neg_below = np.cumsum(~ps)[:-1]
    distinct = xs[1:] > xs[:-1]
    if not distinct.any():
        return float("nan"), 1.0, 0.5
    bacc_up = 0.5 * ((n_pos - pos_below) / n_pos + neg_below / n_neg)  # x > thr -> positive
    bacc_down = 1.0 - bacc_up                                            # x < thr -> positive
    bacc_up = np.where(distinct, bacc_up, -1.0)
    bacc_down = np.where(distinct, bacc_down, -1.0)
    i_up, i_down = int(np.argmax(bacc_up)), int(np.argmax(bacc_down))
    if bacc_up[i_up] >= bacc_down[i_down]:
        i, s, b = i_up, 1.0, float(bacc_up[i_up])
    else:
        i, s, b = i_down, -1.0, float(bacc_down[i_down])
    return float(0.5 * (xs[i] + xs[i + 1])), s, b


class LandmarkTreeClassifier(ClassifierMixin, BaseEstimator):
    """The seed 003 landmark decision tree (module docstring) as a scikit-learn classifier.

    Parameters
    ----------
    columns
        Feature name of each input column; None means ``feature_names(LANDMARK_GROUPS)``.
    min_samples
        Fewest windows of each side needed to fit a split on a candidate feature.

    Attributes
    ----------
    classes_ : the tree's classes present in the training labels.
    splits_ : split name -> list of rules ``(combine, stumps, balanced_accuracy)``, each stump
        ``(feature, threshold, direction)``; in order of use (combined rules first, then single stumps).
    leaf_proba_ : leaf name -> (r,) class distribution of the training windows reaching it.
    """

    def __init__(self, columns: Sequence[str] | None = None, min_samples: int = 5) -> None:
        self.columns = columns
        self.min_samples = min_samples

    def _columns(self, n_features: int) -> list[str]:
        cols = list(feature_names(LANDMARK_GROUPS)) if self.columns is None else list(self.columns)
        if len(cols) != n_features:
            raise ValueError(f"X has {n_features} columns but the tree was given {len(cols)} column names")
        return cols

    def _value(self, X: FloatArray, cols: list[str], name: str) -> FloatArray | None:
        base = name.split(":", 1)[-1]
        if base not in cols:
            return None
        v = X[:, cols.index(base)]
        if name.startswith("abs:"):
            return np.abs(v)
        if name.startswith("neg:"):
            return -v
        return v

    def fit(self, X: Any, y: Any) -> LandmarkTreeClassifier:
        """Learn every split's thresholds and the leaf distributions from (n, q) features and labels."""
        X, y = validate_data(self, X, y, dtype=np.float64, ensure_all_finite="allow-nan")
        check_classification_targets(y)
        y = np.asarray(y).astype(str)
        unknown = sorted(set(y) - set(LEAVES))
        if unknown:
            raise ValueError(f"labels {unknown} are not landmark classes {LEAVES}")
        cols = self._columns(X.shape[1])
        self.classes_ = np.array([c for c in LEAVES if c in set(y)], dtype=object)
        self.splits_: dict[str, list[Rule]] = {}
        for split, (pos_cls, neg_cls) in SPLIT_SIDES.items():
            rows = np.isin(y, pos_cls + neg_cls)
            self.splits_[split] = self._fit_split(X[rows], cols, np.isin(y[rows], pos_cls), split)
        leaf = self._route(X, cols)
        r = self.classes_.size
        self.leaf_proba_: dict[str, list[float]] = {}
        for name in LEAVES:
            counts = np.array([np.sum((leaf[:, LEAVES.index(name)] > 0.5) & (y == c)) for c in self.classes_], float)
            self.leaf_proba_[name] = ((counts + 1.0) / (counts.sum() + r)).tolist()
        return self

    def _fit_split(self, X: FloatArray, cols: list[str], pos: NDArray[np.bool_], split: str) -> list[Rule]:
        """The ranked rules of one split (module docstring) from the rows of its classes."""
        if pos.sum() < self.min_samples or (~pos).sum() < self.min_samples:
            return []
        singles: list[tuple[str, FloatArray, Stump, float]] = []
        for cand in SPLIT_CANDIDATES[split]:
            v = self._value(X, cols, cand)
            if v is None:
                continue
            ok = np.isfinite(v)
            if pos[ok].sum() < self.min_samples or (~pos[ok]).sum() < self.min_samples:
                continue
            thr, s, bacc = fit_stump(v, pos)
            if np.isfinite(thr):
                singles.append((cand, v, (cand, thr, s), bacc))
        top = max((b for *_, b in singles), default=0.0)
        combined: list[Rule] = []
        for cand, v, first, _ in singles:
            says = first[2] * (v - first[1]) > 0
            best: Rule | None = None
            for cand2, v2, _, _ in singles:
                if cand2.split(":")[-1] == cand.split(":")[-1]:
                    continue
                ok = np.isfinite(v) & np.isfinite(v2)
                if pos[ok].sum() < self.min_samples or (~pos[ok]).sum() < self.min_samples:
                    continue
                _, s2, _ = fit_stump(v2[ok], pos[ok])
                floor = max(top, balanced_accuracy(says[ok], pos[ok])) - COMBINE_TOLERANCE
                for combine, rows, q in (("any", ok & ~pos & ~says, SPECIFIC_QUANTILE),
                                         ("all", ok & pos & says, 1.0 - SPECIFIC_QUANTILE)):
                    if combine not in SPLIT_COMBINE[split] or rows.sum() < self.min_samples:
                        continue
                    thr2 = float(s2 * np.quantile(s2 * v2[rows], q))
                    cue = s2 * (v2[ok] - thr2) > 0
                    if combine == "any":
                        decided, rule = cue[pos[ok]].mean(), says[ok] | cue
                    else:
                        decided, rule = (~cue[~pos[ok]]).mean(), says[ok] & cue
                    b2 = balanced_accuracy(rule, pos[ok])
                    if decided >= MIN_CUE_SHARE and b2 >= floor and (best is None or b2 > best[2]):
                        best = (combine, (first, (cand2, thr2, s2)), b2)
            if best is not None:
                combined.append(best)
        combined.sort(key=lambda r: -r[2])
        ranked_singles: list[Rule] = sorted((("any", (st,), b) for _, _, st, b in singles), key=lambda r: -r[2])
        return combined + ranked_singles

    def _decide(self, X: FloatArray, cols: list[str], split: str) -> FloatArray:
        """(n,) probability of the positive side: 1/0 from the first rule with data, 0.5 when none applies."""
        out = np.full(X.shape[0], 0.5)
        todo = np.ones(X.shape[0], dtype=bool)
        for combine, stumps, _ in self.splits_.get(split, []):
            values = [self._value(X, cols, cand) for cand, _, _ in stumps]
            present = [v for v in values if v is not None]
            if len(present) < len(stumps):
                continue
            ok = todo & np.all(np.isfinite(np.stack(present)), axis=0)
            with np.errstate(invalid="ignore"):
                votes = np.stack([s * (v - thr) > 0 for v, (_, thr, s) in zip(present, stumps, strict=True)])
            says: NDArray[np.bool_] = np.asarray(votes.any(axis=0) if combine == "any" else votes.all(axis=0))
            out[ok] = says[ok].astype(float)
            todo &= ~ok
            if not todo.any():
                break
        if not self.splits_.get(split):
            # Split not learnable (one side absent in training): all mass to the side with classes.
            pos_cls, _ = SPLIT_SIDES[split]
            out[:] = 1.0 if any(c in set(self.classes_) for c in pos_cls) else 0.0
        return out

    def _route(self, X: FloatArray, cols: list[str]) -> FloatArray:
        """(n, 5) probability of reaching each leaf of ``LEAVES``."""
        hi = self._decide(X, cols, "intensity")
        elev = self._decide(X, cols, "elevator")
        esc = self._decide(X, cols, "escalator")
        st = self._decide(X, cols, "stairs")
        lo = 1.0 - hi
        return np.column_stack([hi * st, hi * (1 - st), lo * (1 - esc) * elev, lo * esc,
                                lo * (1 - esc) * (1 - elev)])

    def predict_proba(self, X: Any) -> FloatArray:
        """(n, r) class probabilities: the leaf distributions weighted by the routing."""
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, ensure_all_finite="allow-nan", reset=False)
        route = self._route(X, self._columns(X.shape[1]))
        leaf = np.array([self.leaf_proba_[name] for name in LEAVES])
        p = route @ leaf
        return np.asarray(p / p.sum(axis=1, keepdims=True))

    def predict(self, X: Any) -> NDArray[Any]:
        """The most probable class of each row."""
        check_is_fitted(self)
        return np.asarray(self.classes_[np.argmax(self.predict_proba(X), axis=1)])

    def to_dict(self) -> dict[str, Any]:
        """Fitted state as JSON-serialisable values."""
        check_is_fitted(self)
        return {"params": {"columns": None if self.columns is None else list(self.columns),
                           "min_samples": int(self.min_samples)},
                "classes": [str(c) for c in self.classes_],
                "splits": {k: [{"combine": comb, "stumps": [[c, float(t), float(s)] for c, t, s in stumps],
                                "balanced_accuracy": float(b)} for comb, stumps, b in v]
                           for k, v in self.splits_.items()},
                "leaf_proba": self.leaf_proba_, "n_features_in": int(self.n_features_in_)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LandmarkTreeClassifier:
        """Inverse of :meth:`to_dict`."""
        m = cls(**d["params"])
        m.classes_ = np.asarray(d["classes"], dtype=object)
        m.splits_ = {k: [(str(r["combine"]), tuple((str(c), float(t), float(s)) for c, t, s in r["stumps"]),
                          float(r["balanced_accuracy"])) for r in v] for k, v in d["splits"].items()}
        m.leaf_proba_ = {k: [float(x) for x in v] for k, v in d["leaf_proba"].items()}
        m.n_features_in_ = int(d["n_features_in"])
        return m
