"""The barometric second stage: a simulated climb's speed recovered with an honest error, and its evidence."""

from __future__ import annotations

import numpy as np
import pytest

from classifiers.baro_stage import STAIRS_SPEED_MPS, log_likelihood, vertical_speed
from classifiers.bayes import GaussianBayesClassifier
from classifiers.model import ContextModel
from classifiers.windows import WindowConfig, make_windows
from pdr.frames import altitude_to_pressure_hpa
from pdr.recording import Recording, SensorStream


def _speed(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    out = vertical_speed(make_windows(rec))
    assert out is not None
    return out


CLASSES = ("running", "stairs_down", "stairs_up", "stationary", "walking")


def _recording(speed_mps: float, noise_m: float, baro_hz: float, seed: int, duration_s: float = 300.0,
               with_baro: bool = True) -> Recording:
    rng = np.random.default_rng(seed)
    t_acc = np.arange(int(duration_s * 50)) / 50.0
    acc = np.tile([0.0, 0.0, 9.81], (t_acc.size, 1)) + rng.normal(0, 0.05, (t_acc.size, 3))
    streams = {"acc": SensorStream("acc", (1e9 + t_acc * 1e9).astype(np.int64), acc)}
    if with_baro:
        t_b = np.arange(int(duration_s * baro_hz)) / baro_hz
        h = 30.0 + speed_mps * t_b + rng.normal(0, noise_m, t_b.size)
        streams["baro"] = SensorStream("baro", (1e9 + t_b * 1e9).astype(np.int64),
                                       altitude_to_pressure_hpa(h)[:, None])
    return Recording(streams, t0_ns=1_000_000_000)


@pytest.mark.parametrize("baro_hz", [5.0, 25.0])
def test_climb_speed_is_recovered_with_a_calibrated_standard_error(baro_hz: float) -> None:
    speed = 0.25
    v, se = _speed(_recording(speed, 0.15, baro_hz, seed=1))
    ok = np.isfinite(v)
    assert ok.mean() > 0.95
    z = (v[ok] - speed) / se[ok]
    # Unbiased, and the stated error neither hides nor inflates the real scatter (overlapping windows are
    # correlated, hence the loose bounds).
    assert abs(np.mean(v[ok]) - speed) < 0.02
    assert 0.6 < np.std(z) < 1.6
    # More samples per second, smaller error.
    _, se5 = _speed(_recording(speed, 0.15, 5.0, seed=2))
    _, se25 = _speed(_recording(speed, 0.15, 25.0, seed=2))
    assert np.nanmedian(se25) < np.nanmedian(se5)


def test_no_barometer_no_evidence() -> None:
    assert vertical_speed(make_windows(_recording(0.0, 0.1, 5.0, seed=3, with_baro=False))) is None
    ll = log_likelihood(np.array([np.nan, 0.3]), np.array([0.05, np.nan]), CLASSES)
    assert np.all(ll == 0.0)
    assert np.all(log_likelihood(np.array([0.3]), np.array([0.05]), ("running", "stationary")) == 0.0)


def test_the_climb_favours_its_stairs_direction_and_leaves_other_classes_alone() -> None:
    v = np.array([STAIRS_SPEED_MPS, -STAIRS_SPEED_MPS, 0.0])
    ll = log_likelihood(v, np.full(3, 0.05), CLASSES)
    col = {c: ll[:, i] for i, c in enumerate(CLASSES)}
    assert np.argmax(ll[0]) == CLASSES.index("stairs_up")
    assert np.argmax(ll[1]) == CLASSES.index("stairs_down")
    assert np.argmax(ll[2]) == CLASSES.index("walking")
    assert np.all(col["running"] == 0.0) and np.all(col["stationary"] == 0.0)
    # A noisy barometer says less: the same climb with a 10x larger error moves the odds less.
    noisy = log_likelihood(v, np.full(3, 0.5), CLASSES)
    up, walk = CLASSES.index("stairs_up"), CLASSES.index("walking")
    assert 0 < noisy[0, up] - noisy[0, walk] < ll[0, up] - ll[0, walk]
    # A door's pressure jump (metres per second of "climb") is no flight of stairs: no class gains much.
    jump = log_likelihood(np.array([1.5, -1.5]), np.full(2, 0.05), CLASSES)
    assert np.all(np.abs(jump) < 0.2)


def test_the_model_adds_the_evidence_to_usable_windows_only_and_can_leave_it_out() -> None:
    rng = np.random.default_rng(5)
    y = np.repeat(["stairs_down", "stairs_up", "walking"], 30)
    est = GaussianBayesClassifier(covariance="tied").fit(rng.normal(size=(90, 2)), y)
    model = ContextModel(task="motion_mode", window=WindowConfig(), feature_groups=(), estimator_kind="bayes",
                         estimator=est, train_priors=np.asarray(est.priors_))
    proba = np.full((3, 3), 1.0 / 3.0)
    usable = np.array([True, True, False])
    speed = (np.array([STAIRS_SPEED_MPS, -STAIRS_SPEED_MPS, STAIRS_SPEED_MPS]), np.full(3, 0.05))
    ll = model.emissions(proba, usable, speed)
    assert np.argmax(ll[0]) == model.classes.index("stairs_up")
    assert np.argmax(ll[1]) == model.classes.index("stairs_down")
    assert np.all(ll[2] == 0.0)
    model.barometer = False
    np.testing.assert_array_equal(model.emissions(proba, usable, speed), model.emissions(proba, usable))
