"""Online hard-iron offset (pdr.phone.magcal): simulate a pocket walk, add a known offset, recover it."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.phone.grid import OnlineGrid
from pdr.phone.magcal import HardIronEstimator, MagCalConfig, _block_sums, _pair_rows, mag_os_calibrated
from pdr.phone.pipeline import PdrPipeline
from pdr.recording import SensorStream
from pdr.sim import simulate

RATE = 50.0


def _pocket_walk(seed: int, grade: str = "ideal") -> tuple[np.ndarray, np.ndarray]:
    """Field (uT) and rate (rad/s) of a simulated 40 s pocket walk with turns, on the pipeline's grid."""
    sc = {"name": "pocket", "placement": "trouser_pocket", "side": "left", "mount_rpy_deg": "random",
          "sensors": {"grade": grade},
          "start": {"position_m": [0, 0, 0], "heading_deg": 30, "floor": 0},
          "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "distance_m": 20, "speed_mps": 1.2},
                       {"type": "turn", "angle_deg": 90, "duration_s": 2},
                       {"type": "walk", "duration_s": 10, "speed_mps": 1.4},
                       {"type": "turn", "angle_deg": -180, "duration_s": 3},
                       {"type": "walk", "duration_s": 8, "speed_mps": 1.0}]}
    g = OnlineGrid(RATE, ("acc", "gyro", "mag"))
    g.push(simulate(sc, seed))
    _, v = g.pull()
    return v["mag"], v["gyro"]


@pytest.fixture(scope="module")
def walk() -> tuple[np.ndarray, np.ndarray]:
    return _pocket_walk(0)


def test_known_offset_is_recovered_and_removed(walk):
    mag, gyro = walk
    b = np.array([8.0, -12.0, 5.0])
    est = HardIronEstimator(RATE)
    out = est.update(mag + b, gyro)
    np.testing.assert_allclose(est.hard_iron.estimate, b, atol=1.0)
    np.testing.assert_allclose(est.hard_iron.applied, est.hard_iron.estimate)     # significant, well conditioned
    assert np.all(est.hard_iron.std < 1.0)
    # Once applied, the corrected field is the true field up to the estimation error.
    assert np.abs(out[-50:] - mag[-50:]).max() < 1.0
    # Causal: the first block passes unchanged.
    np.testing.assert_array_equal(out[:50], mag[:50] + b)


def test_calibrated_field_gives_no_offset(walk):
    mag, gyro = walk
    est = HardIronEstimator(RATE)
    out = est.update(mag, gyro)
    assert np.linalg.norm(est.hard_iron.estimate) < 1.0
    np.testing.assert_array_equal(est.hard_iron.applied, np.zeros(3))
    np.testing.assert_array_equal(out, mag)


def test_consumer_grade_walk_recovers_most_of_the_offset():
    # Consumer errors (3 % soft iron, gyro scale and misalignment) bias the rows: a few uT remain.
    mag, gyro = _pocket_walk(1, "consumer")
    b = np.array([-15.0, 4.0, 10.0])
    clean, exact = HardIronEstimator(RATE), HardIronEstimator(RATE)
    clean.update(mag, gyro)
    exact.update(mag + b, gyro)
    # The sensor's own turn-on offset is in both; the added one is recovered as the difference.
    np.testing.assert_allclose(exact.hard_iron.estimate - clean.hard_iron.estimate, b, atol=1.0)
    assert np.linalg.norm(exact.hard_iron.applied) > 10.0


def test_batches_give_the_same_result_and_state_round_trips(walk):
    mag, gyro = walk
    b = np.array([3.0, 9.0, -6.0])
    whole = HardIronEstimator(RATE).update(mag + b, gyro)
    est = HardIronEstimator(RATE)
    parts = []
    for a in range(0, mag.shape[0], 37):
        parts.append(est.update(mag[a:a + 37] + b, gyro[a:a + 37]))
        est = HardIronEstimator.from_state(est.state(), RATE)
    np.testing.assert_allclose(np.vstack(parts), whole, atol=1e-9)


def test_disabled_and_bad_input():
    m = np.ones((5, 3))
    np.testing.assert_array_equal(HardIronEstimator(RATE, MagCalConfig(enabled=False)).update(m, m), m)
    with pytest.raises(InputError, match="mag and gyro"):
        HardIronEstimator(RATE).update(m, np.ones((4, 3)))
    with pytest.raises(InputError, match="rate"):
        HardIronEstimator(0.0)
    with pytest.raises(InputError, match="tau_s"):
        MagCalConfig(tau_s=0.0)
    with pytest.raises(InputError, match="magnetometer calibration state"):
        HardIronEstimator.from_state({"info": []}, RATE)


def test_pipeline_state_keeps_the_offset_and_reads_older_states():
    p = PdrPipeline()
    p.magcal.hard_iron.applied = np.array([1.0, 2.0, 3.0])
    d = p.state()
    np.testing.assert_array_equal(PdrPipeline.from_state(d).magcal.hard_iron.applied, [1.0, 2.0, 3.0])
    del d["magcal"]
    np.testing.assert_array_equal(PdrPipeline.from_state(d).magcal.hard_iron.applied, np.zeros(3))


def test_mag_os_calibrated_needs_an_os_offset_at_shared_sample_times():
    rng = np.random.default_rng(4)
    t = np.arange(200) / RATE
    mag = rng.normal(0.0, 30.0, (200, 3))
    offset = np.array([83.0, -53.0, 408.0])           # the Nexus 5's OS hard-iron estimate (uT)
    assert mag_os_calibrated(t, mag, t, mag + offset)
    assert not mag_os_calibrated(t, mag, t, mag.copy())                   # a phone that reports no estimate
    assert not mag_os_calibrated(t, mag, t + 0.5 / RATE, mag + offset)    # no common sample: no evidence


def test_pipeline_leaves_an_os_calibrated_field_to_the_os():
    """With the raw field beside it and an OS offset between them, the field the pipeline uses is the log's calibrated
    one as it is: a building's field seen as an offset is not removed. Without the raw stream the same field gets
    the estimator's offset; the flag survives a saved state and an older state reads as not calibrated.
    """
    sc = {"name": "pocket", "placement": "trouser_pocket", "side": "left", "mount_rpy_deg": "random",
          "start": {"position_m": [0, 0, 0], "heading_deg": 30, "floor": 0},
          "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "distance_m": 20, "speed_mps": 1.2},
                       {"type": "turn", "angle_deg": 90, "duration_s": 2},
                       {"type": "walk", "duration_s": 20, "speed_mps": 1.4}]}
    rec = simulate(sc, 1)
    m = rec.stream("mag")
    seen = SensorStream("mag", m.t_ns, m.values + np.array([9.0, -7.0, 4.0]))    # left over by the OS (uT)
    raw = SensorStream("mag_uncal", m.t_ns, seen.values + np.array([83.0, -53.0, 408.0]))
    alone = PdrPipeline()
    alone.update(rec.with_streams({"mag": seen}))
    assert not alone.mag_os_calibrated
    assert np.linalg.norm(alone.magcal.hard_iron.applied) > 5.0
    with_raw = PdrPipeline()
    with_raw.update(rec.with_streams({"mag": seen, "mag_uncal": raw}))
    assert with_raw.mag_os_calibrated
    np.testing.assert_array_equal(with_raw.magcal.hard_iron.applied, np.zeros(3))
    d = with_raw.state()
    assert PdrPipeline.from_state(d).mag_os_calibrated
    del d["mag_os_calibrated"]
    assert not PdrPipeline.from_state(d).mag_os_calibrated


def _numpy_block_sums(m, w, m_prev, w_prev, ts, min_rate, first_pair, starts):
    """The block sums as whole-array numpy expressions (the calibration's before its loops were compiled)."""
    n = m.shape[0]
    mp, wp = np.vstack([m_prev[None], m[:-1]]), np.vstack([w_prev[None], w[:-1]])
    wb, mb = 0.5 * (w + wp), 0.5 * (m + mp)
    y = (m - mp) + ts * np.cross(wb, mb)
    tw = ts * wb
    aa = np.einsum("ni,ni->n", tw, tw)[:, None, None] * np.eye(3) - np.einsum("ni,nj->nij", tw, tw)
    ay, yy = -np.cross(tw, y), np.einsum("ni,ni->n", y, y)
    keep = (np.linalg.norm(wb, axis=1) >= min_rate) & np.isfinite(yy)
    keep[0] &= first_pair
    kf = keep.astype(np.float64)
    return np.hstack([np.add.reduceat((aa * kf[:, None, None]).reshape(n, 9), starts, axis=0),
                      np.add.reduceat(ay * kf[:, None], starts, axis=0),
                      np.add.reduceat(np.where(keep, yy, 0.0), starts)[:, None],
                      np.add.reduceat(kf, starts)[:, None]])


def test_compiled_block_sums_are_the_bits_of_the_numpy_expressions():
    rng = np.random.default_rng(8)
    for n, first_pair in ((1, True), (2, False), (37, True), (400, False), (3000, True)):
        m, w = rng.normal(20.0, 30.0, (n, 3)), rng.normal(0.0, 1.0, (n, 3)) * 10.0 ** rng.integers(-2, 1, (n, 1))
        m[n // 2, 1] = np.nan            # a missing sample: its two rows are not kept
        m_prev, w_prev = rng.normal(20.0, 30.0, 3), rng.normal(0.0, 1.0, 3)
        starts = np.flatnonzero(np.r_[True, np.diff((7 + np.arange(n)) // 50) != 0])
        tw, y, w_norm = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        _pair_rows(m, w, m_prev, w_prev, 0.02, tw, y, w_norm)
        with np.errstate(invalid="ignore"):
            got = _block_sums(tw, y, np.einsum("ni,ni->n", tw, tw), np.einsum("ni,ni->n", y, y), w_norm, 0.3,
                              first_pair, starts)
            expected = _numpy_block_sums(m, w, m_prev, w_prev, 0.02, 0.3, first_pair, starts)
        assert got.tobytes() == expected.tobytes(), n
