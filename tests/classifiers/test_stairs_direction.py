"""The stairs direction stage: fitted on the dimensionless stride cues, it splits only the stairs mass, and the
shipped pocket model carries it."""

from __future__ import annotations

import numpy as np

from classifiers import stairs_direction
from classifiers.artifacts import load_model, save_model
from classifiers.bayes import GaussianBayesClassifier
from classifiers.model import ContextModel
from classifiers.stairs_direction import DIRECTION_FEATURES
from classifiers.stride_features import STRIDE_FEATURES
from classifiers.windows import WindowConfig

CLASSES = ("stairs_down", "stairs_up", "walking")
COLUMNS = ("acc_energy", *DIRECTION_FEATURES)


def _rows(rng: np.random.Generator, n: int, up: bool) -> np.ndarray:
    """Rows of COLUMNS: a direction-free first column; climbs with positive vertical-velocity skew and
    velocity/pitch-rate correlation, descents near zero."""
    sign = 1.0 if up else -1.0
    return np.column_stack([rng.normal(0.0, 1.0, n), 0.3 + 0.3 * sign + rng.normal(0, 0.15, n),
                            0.4 + 0.35 * sign + rng.normal(0, 0.15, n), rng.normal(0.0, 0.1, n)])


def _fitted() -> dict:
    rng = np.random.default_rng(3)
    X = np.vstack([_rows(rng, 80, True), _rows(rng, 80, False), rng.normal(0, 1, (40, 4))])
    y = ["stairs_up"] * 80 + ["stairs_down"] * 80 + ["walking"] * 40
    params = stairs_direction.fit(X, y, COLUMNS)
    assert params is not None
    return params


def test_fit_needs_the_cues_and_both_directions() -> None:
    rng = np.random.default_rng(0)
    X = _rows(rng, 10, True)
    assert stairs_direction.fit(X, ["stairs_up"] * 10, COLUMNS) is None
    assert stairs_direction.fit(X[:, :2], ["stairs_up"] * 5 + ["stairs_down"] * 5, COLUMNS[:2]) is None


def test_split_follows_the_cues_and_keeps_the_stairs_mass() -> None:
    params = _fitted()
    rng = np.random.default_rng(9)
    X = np.vstack([_rows(rng, 50, True), _rows(rng, 50, False)])
    # The main estimator is confidently wrong about the direction: up for descents, down for climbs.
    proba = np.tile([0.0, 0.0, 0.2], (100, 1))
    proba[:50, 0], proba[50:, 1] = 0.8, 0.8
    out = stairs_direction.apply(proba, X, COLUMNS, CLASSES, params)
    assert np.mean(out[:50, 1] > out[:50, 0]) > 0.95
    assert np.mean(out[50:, 0] > out[50:, 1]) > 0.95
    np.testing.assert_allclose(out[:, 0] + out[:, 1], 0.8)
    np.testing.assert_array_equal(out[:, 2], proba[:, 2])
    # Without the cues (no gyro: NaN stride features) the main estimator's split stands.
    X[:10, 2] = np.nan
    np.testing.assert_array_equal(stairs_direction.apply(proba, X, COLUMNS, CLASSES, params)[:10], proba[:10])
    # A task without both stairs classes is untouched.
    np.testing.assert_array_equal(stairs_direction.apply(proba, X, COLUMNS, ("a", "b", "c"), params), proba)


def test_stage_round_trips_and_is_used(tmp_path) -> None:
    params = _fitted()
    rng = np.random.default_rng(5)
    est = GaussianBayesClassifier().fit(rng.normal(0, 1, (60, len(STRIDE_FEATURES))), np.repeat(list(CLASSES), 20))
    model = ContextModel(task="motion_mode", window=WindowConfig(), feature_groups=("stride",), estimator_kind="bayes",
                         estimator=est, train_priors=np.full(3, 1 / 3), stairs_direction=params)
    save_model(model, tmp_path / "m")
    assert load_model(tmp_path / "m").stairs_direction == params


def test_shipped_pocket_model_has_the_stage() -> None:
    model = load_model("motion_mode")
    assert model.stairs_direction is not None
    assert tuple(model.stairs_direction["features"]) == DIRECTION_FEATURES
    # Climbs are more likely than descents where the vertical velocity skews up and follows the thigh's rate.
    w = np.asarray(model.stairs_direction["weights"])
    assert w[0] > 0 and w[1] > 0
