"""The fitted class densities of the Gaussian Bayes classifier (seed 004 Sec. 4.1, eqs. 23-25), evaluated with numpy
alone.

:class:`classifiers.bayes.GaussianBayesClassifier` fits them (scikit-learn's estimator protocol, for training and
cross-validation); a saved model is read back into :class:`GaussianDensities`, so that classifying a recording, in
``pdr classify`` or in the service, does not import scikit-learn (about 0.9 s of a one-shot process, most of it
scipy.stats and pandas, which scikit-learn loads). The estimator evaluates its own densities through the same class,
so both give the same numbers.

Features are standardised with the training mean and scale; each class ``j`` is ``z ~ N(mu_j, Sigma_j)`` in those
units (eq. 23), and the posterior follows from Bayes' theorem (eqs. 24-25) in the log domain.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class GaussianDensities:
    """Class densities and priors in standardised feature units.

    ``classes`` (r,) labels; ``mean``, ``scale`` (q,) the standardisation; ``means`` (r, q) and ``covariances``
    (r, q, q) the classes' normal densities; ``priors`` (r,) ``P(C=j)``; ``params`` the estimator's settings
    (covariance kind, shrinkage, regularisation) as saved.
    """

    classes: NDArray[Any]
    mean: FloatArray
    scale: FloatArray
    means: FloatArray
    covariances: FloatArray
    priors: FloatArray
    params: dict[str, Any]
    chol_inv: FloatArray
    log_det: FloatArray
    tied: bool

    @classmethod
    def of(cls, classes: ArrayLike, mean: ArrayLike, scale: ArrayLike, means: ArrayLike, covariances: ArrayLike,
           priors: ArrayLike, params: dict[str, Any]) -> GaussianDensities:
        """The densities with the inverse Cholesky factors and log-determinants that eq. 23 needs."""
        covs = np.asarray(covariances, dtype=np.float64)
        tied = bool(np.all(covs == covs[:1]))
        # A tied model's classes share one covariance: factor it once.
        chol = np.linalg.cholesky(covs[:1] if tied else covs)
        eye = np.eye(chol.shape[1])
        chol_inv = np.asarray(np.stack([np.linalg.solve(c, eye) for c in chol]) if chol.size else chol,
                              dtype=np.float64)
        log_det = np.asarray(2.0 * np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1), dtype=np.float64)
        if tied:
            chol_inv = np.repeat(chol_inv, covs.shape[0], axis=0)
            log_det = np.repeat(log_det, covs.shape[0])
        return cls(np.asarray(classes, dtype=object), np.asarray(mean, dtype=np.float64),
                   np.asarray(scale, dtype=np.float64), np.asarray(means, dtype=np.float64), covs,
                   np.asarray(priors, dtype=np.float64), dict(params), chol_inv, log_det, tied)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GaussianDensities:
        """The densities saved by :meth:`to_dict` (a tied model's one pooled covariance serves every class)."""
        classes = np.asarray(d["classes"], dtype=object)
        covs = np.asarray(d["covariances"], dtype=np.float64)
        return cls.of(classes, d["mean"], d["scale"], d["means"],
                      np.broadcast_to(covs, (classes.size, *covs.shape[1:])).copy(), d["priors"], d["params"])

    def to_dict(self) -> dict[str, Any]:
        """Parameters as JSON-serialisable lists (a tied model stores its single pooled covariance once)."""
        tied = self.params.get("covariance") == "tied"
        return {"params": dict(self.params), "classes": [str(c) for c in self.classes],
                "mean": self.mean.tolist(), "scale": self.scale.tolist(), "means": self.means.tolist(),
                "covariances": (self.covariances[:1] if tied else self.covariances).tolist(),
                "priors": self.priors.tolist(), "n_features_in": self.n_features_in}

    @property
    def n_features_in(self) -> int:
        return int(self.mean.size)

    # The estimator protocol's names, for the code that classifies with a loaded model.
    @property
    def classes_(self) -> NDArray[Any]:
        return self.classes

    @property
    def n_features_in_(self) -> int:
        return self.n_features_in

    def get_params(self) -> dict[str, Any]:
        """The settings of the estimator that fitted these densities (to fit another one alike)."""
        return dict(self.params)

    def log_likelihood(self, X: ArrayLike) -> FloatArray:
        """(n, r) log densities ``log p_j(z)`` of eq. 23 of (n, q) raw features."""
        Z = (self._checked(X) - self.mean) / self.scale
        q = Z.shape[1]
        r = self.classes.size
        if self.tied:
            # One whitening for all classes: |L^-1 (z - mu_j)|^2 = |w|^2 - 2 w.m_j + |m_j|^2.
            w = Z @ self.chol_inv[0].T
            m = self.means @ self.chol_inv[0].T
            maha = np.sum(w * w, axis=1)[:, None] - 2.0 * (w @ m.T) + np.sum(m * m, axis=1)[None, :]
        else:
            maha = np.empty((Z.shape[0], r))
            for j in range(r):
                w = (Z - self.means[j]) @ self.chol_inv[j].T
                maha[:, j] = np.sum(w * w, axis=1)
        return np.asarray(-0.5 * (maha + self.log_det[None, :] + q * np.log(2.0 * np.pi)))

    def predict_log_proba(self, X: ArrayLike) -> FloatArray:
        """(n, r) log posteriors ``log P(C=j | z)`` (eqs. 24-25)."""
        joint = self.log_likelihood(X) + np.log(np.maximum(self.priors, 1e-300))
        return np.asarray(joint - log_sum_exp_rows(joint))

    def predict_proba(self, X: ArrayLike) -> FloatArray:
        """(n, r) posteriors ``P(C=j | z)`` (eqs. 24-25)."""
        return np.exp(self.predict_log_proba(X))

    def predict(self, X: ArrayLike) -> NDArray[Any]:
        """The class of largest posterior for each row."""
        return np.asarray(self.classes[np.argmax(self.predict_log_proba(X), axis=1)])

    def _checked(self, X: ArrayLike) -> FloatArray:
        x = np.asarray(X, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.n_features_in:
            raise ValueError(f"expected (n, {self.n_features_in}) features, got shape {x.shape}")
        if not np.isfinite(x).all():
            raise ValueError("features contain NaN or infinity")
        return x


def log_sum_exp_rows(a: FloatArray) -> FloatArray:
    """(n, 1) ``log sum_j exp(a_ij)`` of finite (n, r) ``a``, computed as ``scipy.special.logsumexp(a, axis=1,
    keepdims=True)`` does (scipy 1.15 and later, real input): the row's maxima (``m`` of them) are taken out of the sum,
    ``log1p(s / m) + log(m) + max`` with ``s`` the sum of the other terms' ``exp(a - max)``.
    """
    a_max = np.max(a, axis=1, keepdims=True)
    at_max = a == a_max
    m = np.sum(at_max, axis=1, keepdims=True, dtype=a.dtype)
    s = np.sum(np.exp(np.where(at_max, -np.inf, a) - a_max), axis=1, keepdims=True, dtype=a.dtype)
    s = np.where(s == 0, s, s / m)
    return np.asarray(np.log1p(s) + np.log(m) + a_max)
