"""Windows, features, estimators, smoothing, model round trip and streaming on synthetic data."""

from __future__ import annotations

import json

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError
from sklearn.utils.estimator_checks import parametrize_with_checks
from sklearn.utils.validation import check_is_fitted

from classifiers.artifacts import IncompatibleModelError, load_model, save_model
from classifiers.bayes import GaussianBayesClassifier
from classifiers.boosting import BoostedTreeClassifier
from classifiers.datasets import labelled_windows, window_labels
from classifiers.features import FEATURE_GROUPS, coning_features, extract_features, feature_names, signal_features
from classifiers.landmark_tree import LandmarkTreeClassifier, fit_stump
from classifiers.sequence import ForwardFilter, dwell_transitions, forward_backward
from classifiers.streaming import WAIT_FOR_STREAM_S, StreamingClassifier
from classifiers.tasks import get_task
from classifiers.training import cross_validate, fit_model
from classifiers.windows import WindowConfig, make_windows, resample_box
from pdr import quaternion as quat
from pdr import state_codec
from pdr.errors import InputError
from pdr.recording import GroundTruth, Labels, Recording, SensorStream

RATE = 100.0


def _rec(mode_segments: list[tuple[str, float]], seed: int = 0, gyro: bool = True, subject: int = 1) -> Recording:
    """Synthetic pocket-like recording: 'still' (noise), 'walk' (2 Hz bounce) and 'run' (3 Hz, strong)."""
    rng = np.random.default_rng(seed)
    t_parts, a_parts, g_parts, starts, ends, labels = [], [], [], [], [], []
    t0 = 0.0
    for mode, dur in mode_segments:
        t = t0 + np.arange(int(dur * RATE)) / RATE
        f, amp, wamp = {"still": (0.0, 0.0, 0.0), "walk": (2.0, 2.5, 1.0), "run": (2.8, 7.0, 3.0)}[mode]
        a = np.zeros((t.size, 3))
        a[:, 1] = 9.81 + amp * np.sin(2 * np.pi * f * t)
        a[:, 0] = 0.4 * amp * np.sin(2 * np.pi * f / 2 * t)
        a += rng.normal(0, 0.05, a.shape)
        g = np.column_stack([wamp * np.sin(2 * np.pi * f / 2 * t), 0.3 * wamp * np.cos(2 * np.pi * f * t),
                             0.2 * wamp * np.sin(2 * np.pi * f / 2 * t + 1)]) + rng.normal(0, 0.01, (t.size, 3))
        t_parts.append(t)
        a_parts.append(a)
        g_parts.append(g)
        starts.append(t0)
        ends.append(t0 + dur)
        labels.append({"still": "stationary", "walk": "walking", "run": "running"}[mode])
        t0 += dur
    t = np.concatenate(t_parts)
    t_ns = (1_000_000_000 + t * 1e9).astype(np.int64)
    streams = {"acc": SensorStream("acc", t_ns, np.vstack(a_parts))}
    if gyro:
        streams["gyro"] = SensorStream("gyro", t_ns, np.vstack(g_parts))
    return Recording(streams, t0_ns=int(t_ns[0]), source=f"synthetic{seed}", format="synthetic",
                     truth=GroundTruth(modes=Labels(np.array(starts), np.array(ends), tuple(labels))),
                     meta={"subject": subject})


# ------------------------------------------------------------------ windows
def test_window_config_validation() -> None:
    cfg = WindowConfig()
    assert cfg.n_samples == 128 and cfg.n_hop == 64
    with pytest.raises(InputError, match="hop_s"):
        WindowConfig(hop_s=0.013)
    with pytest.raises(InputError, match="positive"):
        WindowConfig(length_s=float("nan"))
    with pytest.raises(InputError, match="at least 16 samples"):
        WindowConfig(length_s=0.1, hop_s=0.1)


def test_resample_box_constant_and_linear_and_gap() -> None:
    t = np.arange(0, 10, 0.005)
    v = np.column_stack([np.full(t.size, 3.0), 2.0 * t])
    grid = np.arange(1, 9, 0.02)
    out = resample_box(t, v, grid, 0.1)
    np.testing.assert_allclose(out[:, 0], 3.0)
    np.testing.assert_allclose(out[:, 1], 2.0 * grid, atol=1e-9)  # box mean of a line is its centre value
    t_gap = np.concatenate([t[t < 4], t[t > 5]])
    out = resample_box(t_gap, np.ones((t_gap.size, 1)), grid, 0.1)
    assert np.isnan(out[(grid > 4.05) & (grid < 4.95)]).all()
    assert np.isfinite(out[grid < 3.9]).all()


def test_make_windows_times_and_missing_acc() -> None:
    rec = _rec([("walk", 20.0)])
    win = make_windows(rec)
    # Grid from the first sample at 50 Hz: the last window must end by the last sample (19.99 s).
    assert len(win) == int((19.99 - 2.56) // 1.28) + 1
    np.testing.assert_allclose(np.diff(win.t_start_s), 1.28)
    np.testing.assert_allclose(win.t_end_s - win.t_start_s, 2.56)
    assert win.streams["acc"].shape[1:] == (128, 3)
    only_gyro = Recording({"gyro": rec.stream("gyro")})
    with pytest.raises(InputError, match="accelerometer"):
        make_windows(only_gyro)


# ------------------------------------------------------------------ features
def test_signal_features_analytic_sine() -> None:
    rate = 50.0
    t = np.arange(128) / rate
    x = np.vstack([2.0 * np.sin(2 * np.pi * 3.125 * t), np.zeros(128)])
    f = signal_features(x, rate)
    names = feature_names(("acc",))[: f.shape[1]]
    col = {n.split("anorm_")[1]: i for i, n in enumerate(names)}
    assert f[0, col["var"]] == pytest.approx(2.0, rel=0.02)  # A^2 / 2
    assert f[0, col["peak_hz"]] == pytest.approx(3.125, abs=0.2)
    assert f[0, col["zcr"]] == pytest.approx(2 * 3.125, rel=0.05)
    assert f[0, col["skew"]] == pytest.approx(0.0, abs=0.05)
    assert f[0, col["entropy"]] < 0.5
    assert f[1, col["var"]] == 0.0 and f[1, col["entropy"]] == 0.0


def test_coning_zero_for_fixed_axis_and_positive_for_coning_motion() -> None:
    rate, n = 50.0, 128
    t = np.arange(n) / rate
    fixed = np.zeros((1, n, 3))
    fixed[0, :, 2] = 1.0 + 0.5 * np.sin(2 * np.pi * t)  # one axis, varying rate: rotations commute
    w = 2 * np.pi * 1.0
    cone = np.zeros((1, n, 3))
    cone[0, :, 0] = 0.5 * np.cos(w * t)
    cone[0, :, 1] = 0.5 * np.sin(w * t)
    c = coning_features(np.vstack([fixed, cone]), rate)
    assert c[0, 0] < 1e-9
    assert c[1, 0] > 0.05


def test_compiled_kernels_match_numpy_and_quaternion_reference() -> None:
    rng = np.random.default_rng(8)
    x = rng.normal(size=(20, 128)).cumsum(axis=1)
    x[3] = 1.5  # constant row
    f = signal_features(x, 50.0)
    names = [n.split("anorm_")[1] for n in feature_names(("acc",))[: f.shape[1]]]
    col = {n: f[:, i] for i, n in enumerate(names)}
    xc = x - x.mean(axis=1, keepdims=True)
    var = (xc**2).mean(axis=1)
    np.testing.assert_allclose(col["mean"], x.mean(axis=1))
    np.testing.assert_allclose(col["var"], var)
    np.testing.assert_allclose(col["mad"], np.abs(xc).mean(axis=1))
    std = np.sqrt(var)
    skew = np.where(std > 1e-12, (xc**3).mean(axis=1) / np.where(std > 1e-12, std, 1.0) ** 3, 0.0)
    np.testing.assert_allclose(col["skew"], skew, atol=1e-12)
    sign = np.signbit(xc)
    np.testing.assert_allclose(col["zcr"], np.count_nonzero(sign[:, 1:] != sign[:, :-1], axis=1) * 50.0 / 127)
    # Coning: the compiled integration equals the sequential quaternion products of pdr.quaternion.
    g = rng.normal(size=(5, 128, 3))
    dt, m = 1.0 / 50.0, 128 // 4
    q_full = np.tile(quat.IDENTITY, (5, 1))
    q_avg = np.tile(quat.IDENTITY, (5, 1))
    worst = np.zeros(5)
    for b in range(4):
        for k in range(b * m, (b + 1) * m):
            q_full = quat.multiply(q_full, quat.from_rotvec(g[:, k] * dt))
        q_avg = quat.multiply(q_avg, quat.from_rotvec(g[:, b * m:(b + 1) * m].mean(axis=1) * m * dt))
        worst = np.maximum(worst, quat.angle_between(q_full, q_avg))
    c = coning_features(g, 50.0)
    np.testing.assert_allclose(c[:, 0], worst, atol=1e-10)
    np.testing.assert_allclose(c[:, 1], quat.angle_between(q_full, quat.IDENTITY), atol=1e-10)


def test_features_degrade_without_gyro_and_orientation_invariance() -> None:
    rec = _rec([("walk", 15.0)], gyro=False)
    win = make_windows(rec)
    x = extract_features(win)
    names = feature_names()
    gyro_cols = [names.index(n) for n in FEATURE_GROUPS["gyro"][1]]
    assert np.isnan(x[:, gyro_cols]).all()
    acc_cols = [names.index(n) for n in FEATURE_GROUPS["acc"][1]]
    assert np.isfinite(x[:, acc_cols]).all()
    # Rotating the device frame leaves the acc features unchanged.
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    a = rec.stream("acc")
    rec2 = Recording({"acc": SensorStream("acc", a.t_ns, a.values @ rot.T)}, t0_ns=rec.t0_ns)
    x2 = extract_features(make_windows(rec2))
    np.testing.assert_allclose(x2[:, acc_cols], x[:, acc_cols], rtol=1e-6, atol=1e-6)


# ------------------------------------------------------------------ estimators: sklearn conformance
_XGB_EXPECTED_FAILURES = {
    "check_estimators_nan_inf": "NaN features mean a missing sensor and are handled by the trees, by design",
    "check_sample_weight_equivalence_on_dense_data":
        "histogram binning and row subsampling make weights and repeated rows differ slightly",
}


def _expected_failures(est):
    return _XGB_EXPECTED_FAILURES if isinstance(est, BoostedTreeClassifier) else {}


@parametrize_with_checks([GaussianBayesClassifier(), BoostedTreeClassifier(n_estimators=5, max_depth=2)],
                         expected_failed_checks=_expected_failures)
def test_sklearn_conformance(estimator, check) -> None:
    check(estimator)


def test_bayes_matches_analytic_posterior() -> None:
    rng = np.random.default_rng(1)
    X = np.vstack([rng.normal(0, 1, (4000, 2)), rng.normal(3, 1, (4000, 2))])
    y = np.array(["a"] * 4000 + ["b"] * 4000)
    m = GaussianBayesClassifier(covariance="full", shrinkage=0.0).fit(X, y)
    # Equal priors and unit covariances: P(b | z) = sigmoid(3 (z1 + z2) - 9) on the diagonal.
    z = np.array([[1.5, 1.5], [0.0, 0.0], [3.0, 3.0]])
    p = m.predict_proba(z)[:, 1]
    expect = 1 / (1 + np.exp(-(3 * z.sum(axis=1) - 9)))
    np.testing.assert_allclose(p, expect, atol=0.05)
    with pytest.raises(NotFittedError):
        check_is_fitted(GaussianBayesClassifier())
    with pytest.raises(ValueError, match="NaN"):
        m.predict_proba(np.array([[np.nan, 0.0]]))


def test_bayes_and_booster_round_trip(tmp_path) -> None:
    rng = np.random.default_rng(2)
    X = rng.normal(size=(200, 4))
    y = np.where(X[:, 0] + X[:, 1] > 0, "up", "down")
    b = GaussianBayesClassifier().fit(X, y)
    b2 = GaussianBayesClassifier.from_dict(json.loads(json.dumps(b.to_dict())))
    np.testing.assert_allclose(b2.predict_proba(X), b.predict_proba(X))
    x = BoostedTreeClassifier(n_estimators=10).fit(X, y)
    meta = x.save(str(tmp_path / "b.json"))
    x2 = BoostedTreeClassifier.load(str(tmp_path / "b.json"), json.loads(json.dumps(meta)))
    np.testing.assert_allclose(x2.predict_proba(X), x.predict_proba(X), rtol=1e-6)


def test_fit_stump_and_landmark_tree() -> None:
    x = np.array([0.1, 0.2, 0.3, 1.0, 1.1, 1.2, np.nan])
    thr, s, bacc = fit_stump(x, np.array([0, 0, 0, 1, 1, 1, 1], bool))
    assert 0.3 < thr < 1.0 and s == 1.0 and bacc == 1.0
    rng = np.random.default_rng(3)
    cols = ["anorm_std", "abs_dummy", "baro_slope_hpa_s", "mag_var"]
    n = 60
    rows, labels = [], []
    for lab, std, baro, mag in [("walking", 2.0, 0.0, 1.0), ("stairs", 2.0, 0.04, 1.0), ("standing", 0.05, 0.0, 1.0),
                                ("elevator", 0.05, 0.12, 1.0), ("escalator", 0.05, 0.0, 40.0)]:
        rows.append(np.column_stack([rng.normal(std, 0.1 * std, n), rng.normal(0, 1, n),
                                     rng.normal(baro, 0.005, n), rng.normal(mag, 0.1 * mag, n)]))
        labels += [lab] * n
    X, y = np.vstack(rows), np.array(labels)
    tree = LandmarkTreeClassifier(columns=cols).fit(X, y)
    assert np.mean(tree.predict(X) == y) > 0.97
    # Without the barometer, stairs vs walking is undecidable -> the leaf mass is split, not a silent guess.
    Xn = X.copy()
    Xn[:, 2] = np.nan
    p = tree.predict_proba(Xn[y == "walking"])
    assert np.all(p.max(axis=1) < 0.6)
    t2 = LandmarkTreeClassifier.from_dict(json.loads(json.dumps(tree.to_dict())))
    np.testing.assert_allclose(t2.predict_proba(X), tree.predict_proba(X))


# ------------------------------------------------------------------ smoothing
def test_forward_backward_matches_brute_force_and_filter() -> None:
    rng = np.random.default_rng(4)
    a = dwell_transitions(3, 1.0, 4.0)
    pi = np.array([0.5, 0.3, 0.2])
    ll = np.log(rng.dirichlet([1, 1, 1], size=5))
    post = forward_backward(ll, a, pi)
    # Brute force over all 3^5 paths.
    import itertools

    brute = np.zeros((5, 3))
    for path in itertools.product(range(3), repeat=5):
        p = pi[path[0]] * np.exp(ll[0, path[0]])
        for t in range(1, 5):
            p *= a[path[t - 1], path[t]] * np.exp(ll[t, path[t]])
        for t in range(5):
            brute[t, path[t]] += p
    np.testing.assert_allclose(post, brute / brute.sum(axis=1, keepdims=True), atol=1e-12)
    f = ForwardFilter(a, pi)
    filt = np.vstack([f.update(ll[:2]), f.update(ll[2:])])
    np.testing.assert_allclose(filt[-1], post[-1], atol=1e-12)
    with pytest.raises(InputError, match="mean_dwell_s"):
        dwell_transitions(3, 1.28, 1.0)


# ------------------------------------------------------------------ model, artifacts, streaming
@pytest.fixture(scope="module")
def trained():
    recs = [_rec([("still", 20.0), ("walk", 30.0), ("run", 20.0)], seed=s, subject=s) for s in range(3)]
    task = get_task("motion_mode")
    cfg = WindowConfig()
    groups = ("acc", "gait", "gyro", "coning", "pitch")
    data = labelled_windows(recs, task, cfg, groups)
    return recs, task, cfg, groups, data


def test_window_labels_need_coverage() -> None:
    lab = Labels(np.array([0.0, 10.0]), np.array([10.0, 20.0]), ("a", "b"))
    out = window_labels(lab, np.array([0.0, 8.9, 9.5, 18.0]), np.array([2.56, 11.46, 12.06, 20.56]))
    assert out == ["a", None, "b", None]


def test_grouped_cv_and_model_round_trip(trained, tmp_path) -> None:
    recs, task, cfg, groups, data = trained
    res, classes = cross_validate(data, task, cfg, groups, "bayes")
    assert classes == ["running", "stationary", "walking"]
    assert np.mean(np.asarray(res.label) == data.y) > 0.9
    model = fit_model(data, task, cfg, groups, "xgboost", {"n_estimators": 20})
    out = save_model(model, tmp_path / "m")
    assert (out / "booster.json").is_file() and (out / "MODEL_CARD.md").is_file()
    loaded = load_model(out)
    a, b = model.classify(recs[0]), loaded.classify(recs[0])
    np.testing.assert_allclose(a.proba, b.proba, rtol=1e-6)
    # Incompatible settings and versions are refused with a clear error.
    with pytest.raises(IncompatibleModelError, match="window settings"):
        load_model(out, window=WindowConfig(length_s=5.12, hop_s=2.56))
    doc = json.loads((out / "model.json").read_text())
    doc["feature_set_version"] = 0
    (out / "model.json").write_text(json.dumps(doc))
    with pytest.raises(IncompatibleModelError, match="feature set version"):
        load_model(out)
    save_model(model, tmp_path / "m2")
    doc2 = json.loads((tmp_path / "m2" / "model.json").read_text())
    doc2["versions"]["xgboost"] = "99.0.0"
    (tmp_path / "m2" / "model.json").write_text(json.dumps(doc2))
    with pytest.raises(IncompatibleModelError, match="older"):
        load_model(tmp_path / "m2")


def test_missing_sensor_is_an_error_and_gap_is_unknown(trained) -> None:
    recs, task, cfg, groups, data = trained
    model = fit_model(data, task, cfg, groups, "bayes")
    no_gyro = Recording({"acc": recs[0].stream("acc")}, t0_ns=recs[0].t0_ns, source="nogyro.csv")
    with pytest.raises(InputError, match="gyro"):
        model.classify(no_gyro)
    g = recs[0].stream("gyro")
    keep = (g.t_s(recs[0].origin_ns) < 30) | (g.t_s(recs[0].origin_ns) > 36)
    gappy = recs[0].with_streams({"gyro": g.select(keep)})
    res = model.classify(gappy)
    mid = (res.t_start_s > 30) & (res.t_end_s < 36)
    assert mid.any() and all(res.label[i] == "unknown" for i in np.flatnonzero(mid))


def test_streaming_waits_for_a_stream_that_starts_late_or_skips_a_batch(trained) -> None:
    # A phone whose gyroscope starts one batch (3.7 s) after its accelerometer, and later sends a batch without the
    # gyroscope (its samples come in the next batch): the windows wait for it. Before, the first batch stopped the
    # classifier ("needs the gyro stream(s)"), and the service turned it off for the whole session.
    recs, task, cfg, groups, data = trained
    model = fit_model(data, task, cfg, groups, "bayes")
    rec = recs[1]
    offline = model.classify(rec)
    span = rec.time_span_s()
    edges = np.arange(span[0], span[1] + 3.7, 3.7)
    parts = [rec.slice_time(a, b) for a, b in zip(edges[:-1], edges[1:], strict=False)]
    parts[0] = Recording({"acc": parts[0].stream("acc")}, t0_ns=rec.t0_ns)
    parts[4], parts[5] = (Recording({"acc": parts[4].stream("acc")}, t0_ns=rec.t0_ns),
                          parts[5].with_streams({"gyro": rec.slice_time(edges[4], edges[6]).stream("gyro")}))
    clf = StreamingClassifier(model)
    out = clf.update(parts[0])
    assert out == [] and clf.waiting == ["gyro"]
    for part in parts[1:]:
        out += clf.update(part)
        clf = StreamingClassifier.from_state(state_codec.loads(state_codec.dumps(clf.state())), model=model)
    out += clf.finish()
    gyro_from = float(rec.slice_time(edges[1], edges[2]).t_s("gyro")[0])
    later = offline.t_start_s >= gyro_from - 1e-9
    assert out and out[0].t_start_s - rec.origin_ns / 1e9 >= gyro_from
    np.testing.assert_allclose([r.t_start_s for r in out], offline.t_start_s[later][: len(out)] + rec.origin_ns / 1e9,
                               atol=1e-6)
    assert len(out) >= later.sum() - 1
    # A session that never sends the gyroscope is told so once it has waited WAIT_FOR_STREAM_S.
    clf = StreamingClassifier(model)
    acc_only = Recording({"acc": rec.stream("acc")}, t0_ns=rec.t0_ns)
    assert clf.update(acc_only.slice_time(span[0], span[0] + 5.0)) == []
    with pytest.raises(InputError, match="needs the gyro stream"):
        clf.update(acc_only.slice_time(span[0] + 5.0, span[0] + WAIT_FOR_STREAM_S + 1.0))
    # Nor does one whose gyroscope stops keep the windows waiting to its end.
    clf = StreamingClassifier(model)
    clf.update(rec.slice_time(span[0], span[0] + 8.0))
    stop = span[0] + 8.0
    clf.update(acc_only.slice_time(stop, stop + WAIT_FOR_STREAM_S - 1.0))
    with pytest.raises(InputError, match="needs the gyro stream.*stopped"):
        clf.update(acc_only.slice_time(stop + WAIT_FOR_STREAM_S - 1.0, stop + WAIT_FOR_STREAM_S + 1.0))
    # Nor one whose accelerometer stops while the gyroscope goes on (its buffer would grow to the end).
    clf = StreamingClassifier(model)
    clf.update(rec.slice_time(span[0], span[0] + 8.0))
    gyro_only = Recording({"gyro": rec.stream("gyro")}, t0_ns=rec.t0_ns)
    clf.update(gyro_only.slice_time(stop, stop + WAIT_FOR_STREAM_S - 1.0))
    with pytest.raises(InputError, match="needs the acc stream.*stopped"):
        clf.update(gyro_only.slice_time(stop + WAIT_FOR_STREAM_S - 1.0, stop + WAIT_FOR_STREAM_S + 1.0))


def test_streaming_equals_offline_and_resumes(trained) -> None:
    recs, task, cfg, groups, data = trained
    model = fit_model(data, task, cfg, groups, "bayes")
    rec = recs[1]
    offline = model.classify(rec)
    clf = StreamingClassifier(model)
    out = []
    span = rec.time_span_s()
    edges = np.arange(span[0], span[1] + 3.7, 3.7)
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=False)):
        out += clf.update(rec.slice_time(a, b))
        if i == 5:  # serialise and resume mid-session
            clf = StreamingClassifier.from_state(state_codec.loads(state_codec.dumps(clf.state())), model=model)
    assert len(out) == len(offline) - 1 or len(out) == len(offline)
    t0 = rec.origin_ns / 1e9
    np.testing.assert_allclose([r.t_start_s for r in out], offline.t_start_s[: len(out)] + t0, atol=1e-6)
    raw_modes = [offline.classes[int(np.argmax(p))] for p in offline.raw_proba[: len(out)]]
    assert [r.window_mode for r in out] == raw_modes
    with pytest.raises(InputError, match="state"):
        StreamingClassifier.from_state({"version": 1}, model=model)
