"""Step-length patterns (eqs. 13-18) and the model fit (eq. 19)."""

import json

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.phone.step_length import StepLengthModel, calibrate_k, fit_model, step_patterns


def test_patterns_of_a_known_signal():
    fs = 50.0
    a_n = 9.80665 + np.array([0.0, 2.0, 0.0, -2.0] * 5)
    a_v = 9.80665 + np.array([1.0, -1.0] * 10)
    p = step_patterns(a_n, a_v, fs)
    assert p[0] == pytest.approx(fs / 20)
    assert p[1] == pytest.approx(2.0)
    assert p[2] == pytest.approx(1.0)
    assert p[3] == pytest.approx(20.0 / fs)
    assert p[4] == pytest.approx(4.0) and p[5] == pytest.approx(2.0)


def test_patterns_are_the_bits_of_numpys_expressions():
    """The compiled centring, area and ranges give the bits of the numpy expressions of eqs. 13-18, on a vertical
    force read as a column of (M, 3) samples as the pipeline passes it."""
    rng = np.random.default_rng(5)
    g = 9.80665
    for m in [*range(2, 140), 257]:
        a_n = g + rng.normal(size=m) * 10.0 ** rng.integers(-3, 2)
        f_n = g + rng.normal(size=(m, 3)) * 10.0 ** rng.integers(-3, 2, size=(m, 3))
        a_v, fs = f_n[:, 2], 50.0
        dn, dv = a_n - a_n.mean(), a_v - a_v.mean()
        expected = np.array([1.0 / (m / fs), float(dn @ dn) / m, float(dv @ dv) / m, float(np.abs(a_n - g).sum() / fs),
                             float(a_n.max() - a_n.min()), float(a_v.max() - a_v.min())])
        assert step_patterns(a_n, a_v, fs).tobytes() == expected.tobytes(), m


def test_fit_recovers_k_and_b():
    rng = np.random.default_rng(0)
    k, q, b = 0.5, 0.25, 0.1
    segs = []
    for _ in range(12):
        pats = rng.uniform(1, 10, (int(rng.integers(8, 30)), 6))
        segs.append((pats, float(np.sum(k * pats[:, 4] ** q + b))))
    res = fit_model(segs, "p5", q)
    assert res.model.k == pytest.approx(k, rel=1e-9) and res.model.b == pytest.approx(b, abs=1e-9)
    assert res.rms_rel_error < 1e-9


def test_calibrate_and_save_load(tmp_path):
    pats = np.full((20, 6), 16.0)
    m = calibrate_k(StepLengthModel(pattern="p5", q=0.25, b=0.0), pats, 14.0)
    assert np.sum(m.length(pats)) == pytest.approx(14.0)
    m.save(tmp_path / "cal.json")
    assert StepLengthModel.load(tmp_path / "cal.json") == m
    (tmp_path / "bad.json").write_text(json.dumps({"x": 1}))
    with pytest.raises(InputError, match="step_length"):
        StepLengthModel.load(tmp_path / "bad.json")
    # Not a JSON document Python reads: an integer of 5000 digits, arrays nested 100 000 deep, not UTF-8.
    for text in ('{"a": ' + "9" * 5000 + "}", "[" * 100_000 + "]" * 100_000, b"\xff{}"):
        bad = tmp_path / "unreadable.json"
        bad.write_bytes(text if isinstance(text, bytes) else text.encode())
        with pytest.raises(InputError, match="cannot read calibration"):
            StepLengthModel.load(bad)
    with pytest.raises(InputError, match="at least 5"):
        calibrate_k(m, pats[:2], 3.0)
    with pytest.raises(InputError, match="at least 5"):   # steps on stairs do not inform K
        calibrate_k(m, pats[:6], 3.0, np.array([True] * 2 + [False] * 4))
    with pytest.raises(InputError, match="pattern"):
        StepLengthModel(pattern="p9")


def test_stairs_step_is_one_tread_whoever_walks():
    p = np.full(6, 1.8)                        # 1.8 steps/s
    for k in (0.40, 0.55):
        m = StepLengthModel(k=k)
        assert m.length(p, True) == pytest.approx(m.stairs_m)
        assert m.length(p, True) < m.length(p, False)
    flags = np.array([False, True, True, False])
    assert np.allclose(StepLengthModel().length(np.tile(p, (4, 1)), flags)[flags], StepLengthModel().stairs_m)


def test_calibration_recovers_k_from_a_walk_with_stairs():
    """Simulate a walk (flat steps from eq. 19 with a known K, stairs steps of one tread), recover K."""
    rng = np.random.default_rng(3)
    pats = rng.uniform(1.4, 2.2, (60, 6))
    stairs = np.zeros(60, bool)
    stairs[20:35] = True
    truth = StepLengthModel(k=0.52, q=0.5, stairs_m=0.30)
    walked = float(np.sum(truth.length(pats, stairs)))
    got = calibrate_k(StepLengthModel(k=0.45, q=0.5, stairs_m=0.30), pats, walked, stairs)
    assert got.k == pytest.approx(0.52, rel=1e-9)
    assert got.stairs_m == 0.30 and got.b == 0.0


def test_turn_factor_shortens_turning_steps_only():
    from pdr.phone.step_length import turn_factor
    t = np.radians([0.0, 30.0, 45.0, 90.0, 135.0])
    assert np.allclose(turn_factor(t), [1.0, 0.75, 0.5, 0.0, 0.0])
    assert np.allclose(turn_factor(t, "none"), 1.0)
    p = np.full(6, 1.8)
    m = StepLengthModel()
    assert m.length(p, False, np.radians(30.0)) == pytest.approx(0.75 * m.length(p))
    assert m.length(p, True, np.radians(30.0)) == pytest.approx(m.stairs_m)        # a tread stays a tread
    assert StepLengthModel(turn="none").length(p, False, 1.0) == pytest.approx(m.length(p))
    with pytest.raises(InputError, match="turn"):
        StepLengthModel(turn="sharp")


def test_calibration_and_fit_recover_k_from_a_turning_walk():
    """Simulate a walk whose turning steps cover less ground (eq. 19 times the turn factor), recover K."""
    rng = np.random.default_rng(4)
    pats = rng.uniform(1.4, 2.2, (80, 6))
    turns = np.where(rng.uniform(size=80) < 0.2, rng.uniform(0.2, 1.8, 80), rng.normal(0.0, 0.03, 80))
    truth = StepLengthModel(k=0.52, q=0.5)
    walked = float(np.sum(truth.length(pats, False, turns)))
    got = calibrate_k(StepLengthModel(k=0.45, q=0.5), pats, walked, None, turns)
    assert got.k == pytest.approx(0.52, rel=1e-9)
    # Ignoring the turns would give a K too small by the turning steps' share.
    assert calibrate_k(StepLengthModel(k=0.45, q=0.5), pats, walked).k < 0.97 * 0.52
    from pdr.phone.step_length import turn_factor
    segs = [(pats[i:i + 20], float(np.sum(truth.length(pats[i:i + 20], False, turns[i:i + 20]))))
            for i in range(0, 80, 20)]
    fit = fit_model(segs, "p1", 0.5, False, [turn_factor(turns[i:i + 20]) for i in range(0, 80, 20)])
    assert fit.model.k == pytest.approx(0.52, rel=1e-9)
    with pytest.raises(InputError, match="turn_rad"):
        calibrate_k(truth, pats, walked, None, turns[:10])


def test_a_model_saved_before_the_turn_factor_loads_without_it(tmp_path):
    (tmp_path / "old.json").write_text(json.dumps({"step_length": {"pattern": "p1", "k": 0.5, "q": 0.5, "b": 0.0}}))
    assert StepLengthModel.load(tmp_path / "old.json").turn == "none"
    StepLengthModel(k=0.5).save(tmp_path / "new.json")
    assert StepLengthModel.load(tmp_path / "new.json") == StepLengthModel(k=0.5)


@pytest.mark.parametrize("model", [StepLengthModel(), StepLengthModel(pattern="p2", q=1.0 / 3.0, b=0.1, turn="none"),
                                   StepLengthModel(pattern="p5", q=0.25, k=0.3, min_m=0.0)])
def test_one_step_length_equals_the_batch_formula_bit_for_bit(model):
    """The pipeline's per-step path (floats) gives exactly the batch path's lengths, clamps, stairs and NaN."""
    rng = np.random.default_rng(7)
    for i in range(3000):
        p = rng.normal(0.0, 3.0, 6) * 10.0 ** rng.uniform(-3.0, 2.0)
        if i % 97 == 0:
            p[:] = np.nan
        if i % 89 == 0:
            p[:] = 0.0 if i % 2 else -0.0
        turn, stairs = float(rng.uniform(-4.0, 4.0)), bool(rng.random() < 0.1)
        batch = float(model.length(p, stairs, turn))
        one = model.step_length(p.tolist(), stairs, turn)
        assert isinstance(one, float)
        assert np.float64(one).tobytes() == np.float64(batch).tobytes(), (p, stairs, turn)


def test_turn_factor_float_is_turn_factor_bit_for_bit():
    from pdr.phone.step_length import turn_factor, turn_factor_float
    rng = np.random.default_rng(7)
    turns = np.concatenate([rng.uniform(-7.0, 7.0, 20000), [0.0, -0.0, np.pi / 2, -np.pi / 2, np.pi, 1e-300, np.nan]])
    for model in ("cos2", "none"):
        want = np.array([float(turn_factor(float(t), model)) for t in turns])
        got = np.array([turn_factor_float(float(t), model) for t in turns])
        assert np.array_equal(want.view(np.int64), got.view(np.int64))
