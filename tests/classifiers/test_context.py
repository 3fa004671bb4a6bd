"""Context features (spans longer than one window), the landmark tree's combined rules, and online equality."""

from __future__ import annotations

import json

import numpy as np
import pytest

from classifiers.context import moving_average, span_extrema, span_slope, span_sums
from classifiers.datasets import ipin_mode_labels, labelled_windows
from classifiers.features import CONTEXT_SPAN_S, context_margin_s, extract_features, feature_names
from classifiers.landmark_tree import LandmarkTreeClassifier
from classifiers.streaming import StreamingClassifier
from classifiers.tasks import Task
from classifiers.training import fit_model
from classifiers.windows import WindowConfig, make_windows
from pdr import state_codec
from pdr.io import read_recording
from pdr.recording import GroundTruth, Labels, Recording, SensorStream
from tests.conftest import data_path

RATE = 50.0
CTX = ("ctx_acc", "ctx_mag", "ctx_baro")


def _ride(duration_s: float = 120.0, seed: int = 0) -> Recording:
    """Still phone; from 50 to 72 s in a 'cabin': field x0.5, pressure falling 0.1 hPa/s from 56 to 66 s,
    vertical acceleration +0.5 m/s^2 over 54-56 s and -0.5 m/s^2 over 66-68 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * RATE)) / RATE
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 9.81 + 0.5 * ((t >= 54) & (t < 56)) - 0.5 * ((t >= 66) & (t < 68))
    acc += rng.normal(0, 0.02, acc.shape)
    cabin = (t >= 50) & (t < 72)
    mag = np.tile([20.0, 0.0, -40.0], (t.size, 1)) * np.where(cabin, 0.5, 1.0)[:, None]
    mag += rng.normal(0, 0.2, mag.shape)
    p = 1000.0 - 0.1 * np.clip(t - 56.0, 0.0, 10.0) + rng.normal(0, 0.005, t.size)
    t_ns = (5_000_000_000 + t * 1e9).astype(np.int64)
    labels = Labels(np.array([0.0, 50.0, 72.0]), np.array([50.0, 72.0, max(duration_s, 72.0)]),
                    ("standing", "elevator_down", "standing"))
    return Recording({"acc": SensorStream("acc", t_ns, acc), "mag": SensorStream("mag", t_ns, mag),
                      "baro": SensorStream("baro", t_ns[::5], p[::5, None])}, t0_ns=int(t_ns[0]),
                     source=f"ride{seed}", format="synthetic", truth=GroundTruth(modes=labels))


def test_span_statistics_match_brute_force() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=300)
    x[rng.random(300) < 0.1] = np.nan
    lo = np.array([-20, 0, 37, 150, 280])
    span = 40
    s, c = span_sums(x, lo, lo + span)
    mx, mn = span_extrema(x, lo, span)
    slope = span_slope(x, lo, span, 2.0)
    for i, a in enumerate(lo):
        seg = x[max(a, 0): a + span]
        t = np.arange(max(a, 0), min(a + span, 300))[np.isfinite(seg)] / 2.0
        v = seg[np.isfinite(seg)]
        assert s[i] == pytest.approx(v.sum()) and c[i] == v.size
        assert mx[i] == pytest.approx(v.max()) and mn[i] == pytest.approx(v.min())
        if v.size >= span / 2:
            assert slope[i] == pytest.approx(np.polyfit(t, v, 1)[0], rel=1e-6, abs=1e-9)
        else:
            assert np.isnan(slope[i])
    ma = moving_average(np.arange(10.0), 3)
    np.testing.assert_allclose(ma[1:-1], np.arange(1.0, 9.0))


def test_context_features_see_the_ride_from_inside_the_cabin() -> None:
    rec = _ride()
    cfg = WindowConfig()
    win = make_windows(rec, cfg, margin_s=context_margin_s(CTX, cfg.length_s))
    X = extract_features(win, CTX)
    names = feature_names(CTX)
    col = {n: X[:, i] for i, n in enumerate(names)}
    mid = 0.5 * (win.t_start_s + win.t_end_s)
    moving = (mid > 59.9) & (mid < 62.1)
    np.testing.assert_allclose(col["ctx_baro_slope_hpa_s"][moving], -0.1, atol=0.01)
    far = np.abs(mid - 61) > 25
    assert np.all(np.abs(col["ctx_baro_slope_hpa_s"][far]) < 0.005)
    # Standing in the cabin before it moves: the window itself is still, the context sees the cabin field.
    waiting = (win.t_start_s > 50.5) & (win.t_end_s < 54)
    assert waiting.any()
    np.testing.assert_allclose(col["ctx_mag_log_ratio_max"][waiting], np.log(0.5), atol=0.05)
    assert np.all(col["ctx_avert_lp_max"][waiting] > 0.4)  # the start impulse is in the span
    after = (win.t_start_s > 68) & (win.t_end_s < 72)
    assert after.any() and np.all(col["ctx_avert_lp_min"][after] < -0.4)  # the stop impulse
    np.testing.assert_allclose(col["ctx_mag_log_ratio_max"][after], np.log(0.5), atol=0.05)
    outside = np.abs(mid - 61) > 0.5 * CONTEXT_SPAN_S + 13
    assert np.all(np.abs(col["ctx_mag_log_ratio_max"][outside]) < 0.05)
    assert np.all(np.abs(col["ctx_avert_lp_max"][outside]) < 0.1)
    # Without the grid (windows built by hand) or without a sensor, the context is missing, not invented.
    no_baro = Recording({k: rec.stream(k) for k in ("acc", "mag")}, t0_ns=rec.t0_ns, source="no_baro")
    Xn = extract_features(make_windows(no_baro, cfg, margin_s=context_margin_s(CTX, cfg.length_s)), CTX)
    assert np.isnan(Xn[:, names.index("ctx_baro_slope_hpa_s")]).all()
    assert np.isfinite(Xn[:, names.index("ctx_mag_log_ratio_max")]).all()


def test_streaming_with_context_equals_offline() -> None:
    recs = [_ride(seed=s) for s in range(3)]
    task = Task("ride", ("standing", "elevator"), {"elevator_down": "elevator"}, "modes", ("acc", *CTX), 10.0)
    cfg = WindowConfig()
    groups = ("acc", *CTX)
    data = labelled_windows(recs, task, cfg, groups)
    model = fit_model(data, task, cfg, groups, "xgboost", {"n_estimators": 10})
    rec = _ride(seed=7)
    offline = model.classify(rec)
    clf = StreamingClassifier(model)
    out = []
    span = rec.time_span_s()
    edges = np.arange(span[0], span[1] + 3.1, 3.1)
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=False)):
        out += clf.update(rec.slice_time(a, b))
        if i == 9:
            clf = StreamingClassifier.from_state(state_codec.loads(state_codec.dumps(clf.state())), model=model)
    # Decisions lag by the context margin; the last windows wait for data that never comes.
    lag = int(np.ceil(model.margin_s / cfg.hop_s)) + 1
    assert len(offline) - lag <= len(out) < len(offline)
    # At the end of the session the waiting windows are decided with the context there is, as offline.
    out += clf.finish()
    assert len(offline) - 1 <= len(out) <= len(offline)
    assert clf.finish() == []
    t0 = rec.origin_ns / 1e9
    np.testing.assert_allclose([r.t_start_s for r in out], offline.t_start_s[: len(out)] + t0, atol=1e-6)
    cls = list(offline.classes)
    online_raw = np.array([[r.proba[c] for c in cls] for r in out])
    assert online_raw.shape == offline.raw_proba[: len(out)].shape
    assert [r.window_mode for r in out] == [cls[int(np.argmax(p))] for p in offline.raw_proba[: len(out)]]


def test_tree_combines_cues() -> None:
    """An elevator shows either cue (union); an escalator needs both (intersection)."""
    rng = np.random.default_rng(5)
    cols = ["anorm_std", "ctx_mag_log_ratio_max", "ctx_baro_slope_hpa_s", "mag_var"]
    n = 80

    def block(label: str, std: float, mag_ratio: float, baro: float, mag_var: float) -> tuple[np.ndarray, list[str]]:
        x = np.column_stack([rng.normal(std, 0.05 * std + 0.01, n), rng.normal(mag_ratio, 0.03, n),
                             rng.normal(baro, 0.002, n), np.abs(rng.normal(mag_var, 0.1 * mag_var + 0.05, n))])
        return x, [label] * n

    parts = [block("walking", 2.0, 0.0, 0.0, 2.0), block("stairs", 2.0, 0.0, 0.03, 2.0),
             block("standing", 0.05, 0.0, 0.0, 0.1), block("elevator", 0.05, -0.6, 0.0, 0.1),  # waiting in cabin
             block("elevator", 0.05, -0.6, 0.1, 0.1), block("escalator", 0.05, 0.0, 0.03, 20.0),
             block("standing", 0.05, 0.0, 0.0, 20.0)]  # a field step at a door: not an escalator
    X = np.vstack([p[0] for p in parts])
    y = np.array([lab for p in parts for lab in p[1]])
    tree = LandmarkTreeClassifier(columns=cols).fit(X, y)
    assert tree.splits_["elevator"][0][0] == "any" and len(tree.splits_["elevator"][0][1]) == 2
    assert tree.splits_["escalator"][0][0] == "all"
    assert np.mean(tree.predict(X) == y) > 0.98
    # A real ride whose cabin barely changes the field: the pressure cue alone finds it.
    ride = np.array([[0.05, -0.05, 0.05, 0.1]])
    assert tree.predict(ride)[0] == "elevator"
    t2 = LandmarkTreeClassifier.from_dict(json.loads(json.dumps(tree.to_dict())))
    np.testing.assert_allclose(t2.predict_proba(X), tree.predict_proba(X))


@pytest.mark.data
def test_ipin_switchback_stairs_are_not_an_elevator() -> None:
    rec = read_recording(data_path("ipin2023_t3", "mat", "IPIN2023_T3_TrainingTrial51_repetition01.mat"))
    lab = ipin_mode_labels(rec)
    assert lab is not None
    assert any(name.startswith("stairs") for name in lab.label)
    assert not any(name.startswith("elevator") for name in lab.label)


def test_recording_shorter_than_a_window_gives_no_rows() -> None:
    rec = _ride(duration_s=2.0)
    groups = ("acc", "gyro", "gait", "coning", "pitch", "mag", "baro", *CTX)
    win = make_windows(rec, WindowConfig(), margin_s=context_margin_s(groups, 2.56))
    assert len(win) == 0
    assert extract_features(win, groups).shape == (0, len(feature_names(groups)))


def test_accelerometer_of_one_sample_gives_no_rows() -> None:
    """A log whose accelerometer file holds one sample (cut after its first line) made `pdr classify` fail with
    "ValueError: attempt to get argmax of an empty sequence" (the gait features of a one-sample placeholder)."""
    rec = _ride(duration_s=30.0)
    acc = rec.streams["acc"]
    one = Recording({**rec.streams, "acc": SensorStream("acc", acc.t_ns[:1], acc.values[:1])}, t0_ns=rec.t0_ns)
    groups = ("acc", "gyro", "gait", "coning", "pitch", "mag", "baro", *CTX)
    win = make_windows(one, WindowConfig(), margin_s=context_margin_s(groups, 2.56))
    assert len(win) == 0
    assert extract_features(win, groups).shape == (0, len(feature_names(groups)))
