"""The Gaussian Bayes classifier's densities without scikit-learn: the same numbers as the estimator, and a loaded
model classifies without importing scikit-learn.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.special import logsumexp

from classifiers.bayes import GaussianBayesClassifier
from classifiers.gaussian_densities import GaussianDensities, log_sum_exp_rows
from tests.fresh_process import python_json


@pytest.mark.parametrize("covariance", ["tied", "full", "diag"])
def test_saved_densities_give_the_estimators_posteriors_exactly(covariance: str) -> None:
    rng = np.random.default_rng(3)
    X = np.vstack([rng.normal(m, 1.0, (80, 3)) for m in (0.0, 1.5, 3.0)])
    y = np.repeat(["still", "walk", "run"], 80)
    est = GaussianBayesClassifier(covariance=covariance).fit(X, y)
    g = GaussianDensities.from_dict(json.loads(json.dumps(est.to_dict())))
    assert np.array_equal(g.predict_log_proba(X), est.predict_log_proba(X))
    assert list(g.predict(X)) == list(est.predict(X))
    assert g.to_dict() == est.to_dict()
    assert g.get_params() == {k: v for k, v in est.get_params().items() if k != "priors"}


def test_densities_refuse_bad_features_naming_the_problem() -> None:
    est = GaussianBayesClassifier().fit(np.random.default_rng(0).normal(size=(40, 2)), np.repeat(["a", "b"], 20))
    g = GaussianDensities.from_dict(est.to_dict())
    with pytest.raises(ValueError, match="NaN"):
        g.predict_proba(np.array([[np.nan, 0.0]]))
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        g.predict_proba(np.zeros((3, 5)))


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 20), st.integers(1, 8)),
              elements=st.floats(-700.0, 700.0, allow_nan=False)), st.booleans())
def test_log_sum_exp_rows_is_scipys_logsumexp_bit_for_bit(a: np.ndarray, tie: bool) -> None:
    if tie and a.shape[1] > 1:
        a[:, 1] = a[:, 0]                  # rows with two maxima
    assert np.array_equal(log_sum_exp_rows(a), logsumexp(a, axis=1, keepdims=True))


def test_a_shipped_bayes_model_classifies_a_recording_without_scikit_learn_or_scipys_heavy_parts() -> None:
    """Loading and classifying (features, context, smoothing) imports neither the training libraries nor scipy's
    fft, ndimage or stats: 0.3-0.5 s of imports each in a one-shot ``pdr classify``."""
    code = ("import json, sys; import numpy as np; from classifiers.artifacts import load_model; "
            "from pdr.recording import Recording, SensorStream; "
            "t = np.arange(60 * 50) * 20_000_000; rng = np.random.default_rng(0); "
            "s = {k: SensorStream(k, t, rng.normal(size=(t.size, 3)) + [0, 0, 9.8]) for k in ('acc', 'gyro', 'mag')}; "
            "s['baro'] = SensorStream('baro', t[::5], 1000 + rng.normal(size=(t[::5].size, 1))); "
            "rec = Recording(s, t0_ns=0, source='noise', format='synthetic'); "
            "m = load_model('motion_mode'); w = m.classify(rec); "
            "print(json.dumps({'windows': len(w.label), 'heavy': [k for k in ('sklearn', 'xgboost', 'scipy.stats', "
            "'scipy.fft', 'scipy.ndimage') if k in sys.modules]}))")
    out = python_json(code)
    assert out["windows"] > 20 and out["heavy"] == []
