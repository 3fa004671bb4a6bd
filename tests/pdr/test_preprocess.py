"""Resampling, anti-alias filtering, gap detection and quaternion interpolation against analytic truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.preprocess import (
    Gap,
    UniformSegment,
    contiguous_segments,
    find_gaps,
    resample,
    slerp,
)
from pdr.recording import Recording, SensorStream


def _ns(t_s):
    return np.round(np.asarray(t_s) * 1e9).astype(np.int64)


def _rec(**streams) -> Recording:
    return Recording({k: SensorStream(k, _ns(t), v) for k, (t, v) in streams.items()}, t0_ns=0)


def _attitude_distance(q, p):
    """Element-wise distance of attitudes up to sign (angle_between's arccos is only ~1e-8 exact)."""
    return np.minimum(np.linalg.norm(q - p, axis=-1), np.linalg.norm(q + p, axis=-1))


def _sine_acc(t, f_hz, amp=2.0, phase=0.3):
    v = np.zeros((t.size, 3))
    v[:, 0] = amp * np.sin(2 * np.pi * f_hz * t + phase)
    v[:, 2] = 9.81
    return v


# ----------------------------------------------------------------------------------------- gaps

def test_find_gaps_reports_the_missing_interval():
    t = np.arange(0, 10, 0.01)
    t = np.delete(t, np.s_[300:350])  # 2.99 -> 3.50
    gaps = find_gaps(t)
    assert len(gaps) == 1
    g = gaps[0]
    assert g.start_s == pytest.approx(2.99) and g.end_s == pytest.approx(3.50) and g.index == 300
    assert g.duration_s == pytest.approx(0.51)
    assert find_gaps(t, factor=100) == []
    assert find_gaps(t, min_gap_s=1.0) == []
    assert len(find_gaps(np.arange(0, 1, 0.01), nominal_dt=0.001)) == 99


def test_find_gaps_trivial_and_bad_input():
    assert find_gaps([]) == [] and find_gaps([1.0]) == []
    with pytest.raises(InputError, match="strictly increasing"):
        find_gaps([0.0, 1.0, 1.0])
    with pytest.raises(InputError, match="1-D"):
        find_gaps(np.zeros((3, 2)))
    with pytest.raises(InputError, match="nominal_dt"):
        find_gaps([0.0, 1.0], nominal_dt=0.0)


def test_contiguous_segments():
    t = np.array([0.0, 0.1, 0.2, 1.0, 1.1, 5.0])
    assert contiguous_segments(t, 0.5) == [(0, 3), (3, 5), (5, 6)]
    assert contiguous_segments(t, 10.0) == [(0, 6)]
    assert contiguous_segments([], 1.0) == []


# ----------------------------------------------------------------------------------- resampling

def test_decimation_keeps_amplitude_and_phase_of_a_tone_below_cutoff():
    t = np.arange(0, 20, 1 / 200)
    rec = _rec(acc=(t, _sine_acc(t, 3.0)))
    (seg,) = resample(rec, 50.0)
    assert seg.rate_hz == 50.0 and np.allclose(np.diff(seg.t_s), 0.02)
    truth = _sine_acc(seg.t_s, 3.0)
    inner = (seg.t_s > 1) & (seg.t_s < 19)
    np.testing.assert_allclose(seg["acc"][inner], truth[inner], atol=0.01 * 2.0)
    # edges: zero-phase filtering with odd extension keeps them usable too
    np.testing.assert_allclose(seg["acc"], truth, atol=0.1 * 2.0)


def test_decimation_attenuates_a_tone_above_the_new_nyquist():
    t = np.arange(0, 20, 1 / 200)
    rec = _rec(acc=(t, _sine_acc(t, 35.0)))  # new Nyquist: 25 Hz, would alias to 15 Hz
    (seg,) = resample(rec, 50.0)
    inner = (seg.t_s > 1) & (seg.t_s < 19)
    residual = seg["acc"][inner, 0]
    assert np.sqrt(np.mean(residual**2)) < 0.02 * 2.0 / np.sqrt(2)
    naive = np.interp(seg.t_s, t, rec.values("acc")[:, 0])  # what interpolation alone would give
    assert np.sqrt(np.mean(naive[inner] ** 2)) > 0.5 * 2.0 / np.sqrt(2)


def test_upsampling_interpolates_and_jitter_is_removed():
    rng = np.random.default_rng(3)
    t = np.arange(0, 10, 1 / 50) + rng.uniform(-0.002, 0.002, 500)
    rec = _rec(gyro=(t, _sine_acc(t, 1.0)))
    (seg,) = resample(rec, 100.0)
    truth = _sine_acc(seg.t_s, 1.0)
    np.testing.assert_allclose(seg["gyro"], truth, atol=0.01)
    assert seg.t_s[0] >= t[0] and seg.t_s[-1] <= t[-1]


def test_streams_at_different_rates_share_one_grid():
    ta = np.arange(0.013, 30, 1 / 50)
    tg = np.arange(0.0, 30, 1 / 100)
    tb = np.arange(0.5, 29, 1 / 8)
    rec = _rec(acc=(ta, _sine_acc(ta, 1.0)), gyro=(tg, _sine_acc(tg, 0.5)),
               baro=(tb, 1000.0 + 0.01 * tb))
    (seg,) = resample(rec, 25.0)
    k = seg.t_s * 25.0
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)  # grid at integer multiples of 1/rate
    assert seg.t_s[0] >= 0.5 and seg.t_s[-1] <= tb[-1]
    assert set(seg.data) == {"acc", "gyro", "baro"}
    assert seg["baro"].shape == (len(seg), 1)
    np.testing.assert_allclose(seg["baro"][:, 0], 1000.0 + 0.01 * seg.t_s, atol=1e-9)
    assert seg.bridged_gaps == {}
    only_gyro = resample(rec, 25.0, kinds=["gyro"])
    assert set(only_gyro[0].data) == {"gyro"} and only_gyro[0].t_s[0] == 0.0


def test_long_gap_splits_and_short_gap_is_bridged_and_reported():
    t = np.arange(0, 20, 0.01)
    long_gap = (t > 5.0) & (t < 6.5)
    short_gap = (t > 12.0) & (t < 12.08)
    t_g = t[~(long_gap | short_gap)]
    t_a = np.arange(0, 20, 0.02)
    rec = _rec(acc=(t_a, _sine_acc(t_a, 1.0)), gyro=(t_g, _sine_acc(t_g, 1.0)))
    segs = resample(rec, 50.0)
    assert len(segs) == 2
    first, second = segs
    assert first.t_s[0] == 0.0 and first.t_s[-1] == pytest.approx(5.0)
    assert second.t_s[0] == pytest.approx(6.5) and second.t_s[-1] == pytest.approx(19.98)
    assert first.bridged_gaps == {}
    (bridged,) = second.bridged_gaps["gyro"]
    assert isinstance(bridged, Gap) and bridged.start_s == pytest.approx(12.0)
    assert bridged.end_s == pytest.approx(12.08)
    away = np.abs(second.t_s - 12.04) > 0.05
    np.testing.assert_allclose(second["gyro"][away], _sine_acc(second.t_s[away], 1.0), atol=0.01)
    # across the bridged gap: a straight chord, at most A (2 pi f)^2 (h/2)^2 / 2 = 0.063 below the sine
    np.testing.assert_allclose(second["gyro"], _sine_acc(second.t_s, 1.0), atol=0.07)
    assert len(resample(rec, 50.0, max_gap_s=2.0)) == 1


def test_streams_that_never_overlap_give_no_segment():
    t1, t2 = np.arange(0, 1, 0.01), np.arange(2, 3, 0.01)
    assert resample(_rec(acc=(t1, _sine_acc(t1, 1)), gyro=(t2, _sine_acc(t2, 1))), 50.0) == []


def test_resample_bad_arguments():
    t = np.arange(0, 1, 0.01)
    rec = _rec(acc=(t, _sine_acc(t, 1)))
    with pytest.raises(InputError, match="rate"):
        resample(rec, 0.0)
    with pytest.raises(InputError, match="no 'gyro' stream"):
        resample(rec, 50.0, kinds=["gyro"])
    with pytest.raises(InputError, match="unknown stream kind"):
        resample(rec, 50.0, kinds=["accel"])
    with pytest.raises(InputError, match="cutoff_ratio"):
        resample(rec, 50.0, cutoff_ratio=1.5)
    with pytest.raises(InputError, match="expected"):
        UniformSegment(np.arange(3.0), 1.0, {"acc": np.zeros((2, 3))})


# ----------------------------------------------------------------------------------- quaternions

def test_orientation_is_slerped_exactly_for_a_constant_rate_rotation():
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    rate = 0.8  # rad/s
    t = np.arange(0, 10, 0.1)
    q = quat.from_rotvec(rate * t[:, None] * axis)
    q[1::2] *= -1.0  # q and -q are the same attitude: interpolation must not care
    rec = _rec(orientation=(t, q))
    (seg,) = resample(rec, 100.0)
    out = seg["orientation"]
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)
    truth = quat.from_rotvec(rate * seg.t_s[:, None] * axis)
    assert np.max(_attitude_distance(out, truth)) < 1e-12


def test_slerp_matches_scipy_on_random_attitudes():
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0, 10, 20))
    q = quat.normalize(rng.standard_normal((20, 4)))
    tn = np.linspace(t[0], t[-1], 500)
    ours = slerp(t, q, tn)
    ref = Slerp(t, Rotation.from_quat(q[:, [1, 2, 3, 0]]))(tn).as_quat()[:, [3, 0, 1, 2]]
    assert np.max(_attitude_distance(ours, ref)) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(ours, axis=1), 1.0, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=8, max_size=8), st.floats(0, 1))
def test_slerp_moves_at_constant_angular_speed(raw, u):
    q0, q1 = np.array(raw[:4]), np.array(raw[4:])
    if np.linalg.norm(q0) < 0.1 or np.linalg.norm(q1) < 0.1:
        return
    q0, q1 = quat.normalize(q0), quat.normalize(q1)
    qu = slerp([0.0, 1.0], np.stack([q0, q1]), [u])[0]
    assert np.linalg.norm(qu) == pytest.approx(1.0, abs=1e-12)
    total = quat.angle_between(q0, q1)
    assert quat.angle_between(q0, qu) == pytest.approx(u * total, abs=1e-7)
    assert quat.angle_between(qu, q1) == pytest.approx((1 - u) * total, abs=1e-7)


# ------------------------------------------------------------------------------ real recordings

@pytest.mark.data
def test_ipin_streams_on_one_grid():
    from pdr.io.registry import read_recording
    from tests.conftest import data_path

    rec = read_recording(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt"))
    (seg,) = resample(rec, 25.0)  # acc/mag/AHRS at 50 Hz, gyro 100 Hz, pressure 6 Hz: no gap on this file
    assert set(seg.data) == set(rec.streams)
    starts = [rec.t_s(k)[0] for k in rec.streams]
    ends = [rec.t_s(k)[-1] for k in rec.streams]
    assert max(starts) <= seg.t_s[0] < max(starts) + 0.04 and min(ends) - 0.04 < seg.t_s[-1] <= min(ends)
    np.testing.assert_allclose(np.linalg.norm(seg["orientation"], axis=1), 1.0, atol=1e-12)
    # the low-pass keeps the mean (DC): average specific force agrees with the raw samples
    inner = (rec.t_s("acc") >= seg.t_s[0]) & (rec.t_s("acc") <= seg.t_s[-1])
    np.testing.assert_allclose(seg["acc"].mean(axis=0), rec.values("acc")[inner].mean(axis=0), atol=0.02)
    # pressure (6 Hz) is interpolated, never extrapolated beyond its range
    p = rec.values("baro")[:, 0]
    assert p.min() <= seg["baro"].min() and seg["baro"].max() <= p.max()
