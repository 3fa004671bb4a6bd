"""Stairs direction stage: up or down from a few dimensionless per-stride cues of a thigh-carried phone.

The main estimator decides *stairs or not* well, but its up-against-down split leans on many subject-specific
features (spectral band ratios set by cadence, leg-pitch amplitudes set by the pocket and the leg): with five
subjects, a new subject's descents can look like the training subjects' ascents (MobiFall subject 2). Seed 003
(eqs. 2-3) compares the leg pitch of a stair stride with *the same pedestrian's* level walking, so absolute
amplitudes do not transfer between people. This stage decides the direction from cues whose sign follows
from the mechanics of a stride, not from the size of the person or the pocket
(:mod:`classifiers.stride_features`):

``stride_vz_skew``
    Skewness of the vertical velocity over the window (integrated from the vertical specific force in the
    gyro-carried frame, m/s): a climb lifts the body in short strong pushes (positive skew); a descent lowers
    it slowly and drops onto the step (negative or near zero).
``stride_vz_rate_corr``
    Correlation of the vertical velocity with the leg-pitch rate (seed 003 eq. 1's axis): climbing raises the
    body while the stance thigh extends; descending lowers it while the stance thigh flexes.
``stride_pitch_asym``
    Flexion against extension of the signed leg pitch (eqs. 2-3: a climb's high knee lift, a descent's thigh
    that does not extend behind the body).

A two-class Gaussian with a shared covariance (equal priors) is fitted on the stairs windows of the training
data. At prediction, the main estimator's stairs mass ``p_up + p_down`` is kept and split by this stage's
posterior, so the stage changes the direction only, never stairs against other classes. Windows without
the cues (no gyro) keep the main estimator's split.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

UP, DOWN = "stairs_up", "stairs_down"
DIRECTION_FEATURES: tuple[str, ...] = ("stride_vz_skew", "stride_vz_rate_corr", "stride_pitch_asym")
#: Relative ridge added to the shared covariance's diagonal (a few hundred windows, three features).
_RIDGE = 1e-3


def fit(X: FloatArray, y: ArrayLike, columns: Sequence[str]) -> dict[str, Any] | None:
    """The stage's parameters from training rows ``X`` (W, F) with columns ``columns`` and labels ``y``;
    ``None`` when a cue column is missing or either direction has fewer than two complete windows.
    """
    if any(c not in columns for c in DIRECTION_FEATURES):
        return None
    cols = [list(columns).index(c) for c in DIRECTION_FEATURES]
    lab = np.asarray(y).astype(str)
    Z = np.asarray(X, dtype=np.float64)[:, cols]
    ok = np.isfinite(Z).all(axis=1)
    up, down = Z[ok & (lab == UP)], Z[ok & (lab == DOWN)]
    if len(up) < 2 or len(down) < 2:
        return None
    mu_up, mu_down = up.mean(axis=0), down.mean(axis=0)
    resid = np.vstack([up - mu_up, down - mu_down])
    cov = resid.T @ resid / (len(resid) - 2)
    cov += _RIDGE * np.mean(np.diag(cov)) * np.eye(len(cols))
    w = np.linalg.solve(cov, mu_up - mu_down)
    return {"features": list(DIRECTION_FEATURES), "weights": w.tolist(),
            "bias": float(-0.5 * w @ (mu_up + mu_down)), "n_windows": [int(len(up)), int(len(down))]}


def apply(proba: FloatArray, X: FloatArray, columns: Sequence[str], classes: Sequence[str],
          params: dict[str, Any] | None) -> FloatArray:
    """Posteriors (W, r) with the stairs mass of each window split by the stage's up/down posterior."""
    if params is None or UP not in classes or DOWN not in classes:
        return proba
    cols = [list(columns).index(c) for c in params["features"]]
    Z = np.asarray(X, dtype=np.float64)[:, cols]
    ok = np.isfinite(Z).all(axis=1)
    if not ok.any():
        return proba
    out = proba.copy()
    iu, idn = list(classes).index(UP), list(classes).index(DOWN)
    logit = Z[ok] @ np.asarray(params["weights"], dtype=np.float64) + float(params["bias"])
    logit = np.clip(logit, -50.0, 50.0)
    mass = proba[ok, iu] + proba[ok, idn]
    out[ok, iu] = mass / (1.0 + np.exp(-logit))
    out[ok, idn] = mass / (1.0 + np.exp(logit))
    return out
