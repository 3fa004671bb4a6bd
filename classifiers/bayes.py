"""Gaussian Bayes classifier of seed 004 Sec. 4.1 (eqs. 23-25), scikit-learn compatible.

Each class ``j`` models the feature vector as ``z ~ N(mu_j, Sigma_j)`` (eq. 23); the posterior is
Bayes' theorem ``P(C=j | z) = p_j(z) P(C=j) / p(z)`` (eq. 24) with ``p(z) = sum_i p_i(z) P(C=i)``
(eq. 25), evaluated in the log domain. Because the means and covariances are estimates from a limited
training set (the seed stresses this), the covariance can be

* ``"full"``: one per class (the seed's ``Sigma_j``),
* ``"tied"``: pooled over classes (linear discriminant), or
* ``"diag"``: per class, diagonal (naive Bayes),

each shrunk towards a scaled identity by ``shrinkage`` (a float in [0, 1], or ``"auto"`` for the
Ledoit-Wolf estimate). Features are standardised with the training mean and standard deviation first.
Rows with NaN are rejected with an error: decide upstream (see :mod:`classifiers.model`) whether a missing
sensor means ``unknown``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.covariance import ledoit_wolf_shrinkage
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from classifiers.gaussian_densities import GaussianDensities

FloatArray = NDArray[np.float64]

_COVARIANCES = ("full", "tied", "diag")


class GaussianBayesClassifier(ClassifierMixin, BaseEstimator):
    """Multivariate-normal class models with Bayes' rule (seed 004 eqs. 23-25).

    Parameters
    ----------
    covariance
        ``"full"`` (per class), ``"tied"`` (pooled) or ``"diag"``.
    shrinkage
        Weight of the scaled identity in the covariance estimate, in [0, 1], or ``"auto"``
        (Ledoit-Wolf).
    priors
        Class priors ``P(C=j)`` in the order of ``classes_``; None uses the training frequencies,
        ``"uniform"`` equal priors.
    reg
        Added to the covariance diagonal (standardised units) for numerical safety.

    Attributes
    ----------
    classes_ : (r,) class labels.
    mean_, scale_ : (q,) standardisation of the features.
    means_ : (r, q) class means in standardised units.
    covariances_ : (r, q, q) class covariances in standardised units (equal for ``"tied"``).
    priors_ : (r,) class priors.
    """

    def __init__(self, covariance: str = "tied", shrinkage: float | str | None = "auto",
                 priors: ArrayLike | str | None = None, reg: float = 1e-6) -> None:
        self.covariance = covariance
        self.shrinkage = shrinkage
        self.priors = priors
        self.reg = reg

    def _shrink(self, cov: FloatArray, centred: FloatArray) -> FloatArray:
        q = cov.shape[0]
        if self.shrinkage is None:
            alpha = 0.0
        elif isinstance(self.shrinkage, str):
            if self.shrinkage != "auto":
                raise ValueError(f"shrinkage must be a float in [0, 1], 'auto' or None, got {self.shrinkage!r}")
            alpha = float(ledoit_wolf_shrinkage(centred, assume_centered=True)) if centred.shape[0] > 1 else 1.0
        else:
            alpha = float(self.shrinkage)
            if not 0.0 <= alpha <= 1.0:
                raise ValueError(f"shrinkage must be in [0, 1], got {alpha}")
        mu = np.trace(cov) / q
        return (1.0 - alpha) * cov + alpha * mu * np.eye(q) + self.reg * np.eye(q)

    def fit(self, X: Any, y: Any) -> GaussianBayesClassifier:
        """Estimate the class means, covariances and priors from (n, q) features and (n,) labels."""
        if self.covariance not in _COVARIANCES:
            raise ValueError(f"covariance must be one of {_COVARIANCES}, got {self.covariance!r}")
        X, y = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(y)
        self.classes_, yi = np.unique(y, return_inverse=True)
        r, q = self.classes_.size, X.shape[1]
        self.mean_ = X.mean(axis=0)
        scale = X.std(axis=0)
        self.scale_ = np.where(scale > 1e-12, scale, 1.0)
        Z = (X - self.mean_) / self.scale_
        self.means_ = np.stack([Z[yi == j].mean(axis=0) for j in range(r)])
        centred = Z - self.means_[yi]
        if self.covariance == "tied":
            cov = self._shrink(centred.T @ centred / max(1, Z.shape[0] - r), centred)
            covs = np.broadcast_to(cov, (r, q, q)).copy()
        else:
            covs = np.empty((r, q, q))
            for j in range(r):
                c = centred[yi == j]
                emp = c.T @ c / max(1, c.shape[0] - 1)
                if self.covariance == "diag":
                    emp = np.diag(np.diag(emp))
                covs[j] = self._shrink(emp, c)
        self.covariances_ = covs
        counts = np.bincount(yi, minlength=r).astype(np.float64)
        if self.priors is None:
            self.priors_ = counts / counts.sum()
        elif isinstance(self.priors, str):
            if self.priors != "uniform":
                raise ValueError(f"priors must be None, 'uniform' or an array, got {self.priors!r}")
            self.priors_ = np.full(r, 1.0 / r)
        else:
            p = np.asarray(self.priors, dtype=np.float64)
            if p.shape != (r,) or np.any(p < 0) or not np.isclose(p.sum(), 1.0):
                raise ValueError(f"priors must be {r} non-negative numbers summing to 1")
            self.priors_ = p
        self._prepare()
        return self

    def _prepare(self) -> None:
        """The fitted densities (:class:`classifiers.gaussian_densities.GaussianDensities`) that eqs. 23-25 use."""
        self.densities_ = GaussianDensities.of(self.classes_, self.mean_, self.scale_, self.means_, self.covariances_,
                                               self.priors_, self._params())

    def _params(self) -> dict[str, Any]:
        return {"covariance": self.covariance,
                "shrinkage": self.shrinkage if not isinstance(self.shrinkage, np.generic) else float(self.shrinkage),
                "reg": float(self.reg)}

    def log_likelihood(self, X: Any) -> FloatArray:
        """(n, r) log densities ``log p_j(z)`` of eq. 23 (in standardised feature units)."""
        check_is_fitted(self)
        return self.densities_.log_likelihood(validate_data(self, X, dtype=np.float64, reset=False))

    def predict_log_proba(self, X: Any) -> FloatArray:
        """(n, r) log posteriors ``log P(C=j | z)`` (eqs. 24-25)."""
        check_is_fitted(self)
        return self.densities_.predict_log_proba(validate_data(self, X, dtype=np.float64, reset=False))

    def predict_proba(self, X: Any) -> FloatArray:
        """(n, r) posteriors ``P(C=j | z)`` (eqs. 24-25)."""
        return np.exp(self.predict_log_proba(X))

    def predict(self, X: Any) -> NDArray[Any]:
        """The class of largest posterior for each row."""
        check_is_fitted(self)
        return np.asarray(self.classes_[np.argmax(self.predict_log_proba(X), axis=1)])

    # -- serialisation (plain JSON-able numbers, no pickles) --
    def to_dict(self) -> dict[str, Any]:
        """Parameters and fitted state as JSON-serialisable lists."""
        check_is_fitted(self)
        return self.densities_.to_dict()

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GaussianBayesClassifier:
        """Inverse of :meth:`to_dict`."""
        return cls.from_densities(GaussianDensities.from_dict(d))

    @classmethod
    def from_densities(cls, g: GaussianDensities) -> GaussianBayesClassifier:
        """The fitted estimator of saved densities."""
        m = cls(**g.params)
        m.classes_, m.mean_, m.scale_, m.means_ = g.classes, g.mean, g.scale, g.means
        m.covariances_, m.priors_, m.n_features_in_ = g.covariances, g.priors, g.n_features_in
        m.densities_ = g
        return m
