import numpy as np
import pytest

from pdr.allan.record_checks import detect_motion, prepare_stream
from pdr.errors import InputError
from pdr.recording import SensorStream

FS = 100.0


def _stream(kind, values, t_s=None):
    n = values.shape[0]
    t = np.arange(n) / FS if t_s is None else t_s
    return SensorStream(kind, np.round(t * 1e9).astype(np.int64), values)


def _static_acc(n, rng):
    return np.array([0.0, 0.0, 9.81]) + 0.02 * rng.standard_normal((n, 3))


def test_clean_record_passes_untouched():
    rng = np.random.default_rng(0)
    v = _static_acc(6000, rng)
    vals, rate, q = prepare_stream(_stream("acc", v))
    assert rate == pytest.approx(FS) and q.flags == () and not q.resampled and q.gaps == ()
    np.testing.assert_array_equal(vals, v)


def test_gaps_use_longest_segment_or_raise():
    rng = np.random.default_rng(1)
    t = np.r_[np.arange(1000), np.arange(1500, 5000)] / FS
    s = _stream("gyro", 0.01 * rng.standard_normal((t.size, 3)), t)
    vals, _, q = prepare_stream(s)
    assert vals.shape[0] == 3500 and len(q.gaps) == 1 and q.gaps[0][1] == pytest.approx(5.01)
    assert "longest unbroken segment" in q.flags[0]
    with pytest.raises(InputError, match=r"gap of 5.01 s after t = 9.99 s"):
        prepare_stream(s, gap_policy="error")


def test_jittery_timestamps_are_resampled_and_flagged():
    rng = np.random.default_rng(2)
    t = np.cumsum(0.01 * (1 + 0.1 * rng.uniform(-1, 1, 5000)))
    vals, rate, q = prepare_stream(_stream("gyro", 0.01 * rng.standard_normal((5000, 3)), t))
    assert q.resampled and "non-uniform sampling" in q.flags[0]
    assert rate == pytest.approx(FS, rel=0.02) and vals.shape[1] == 3


def test_motion_is_detected_and_reported():
    rng = np.random.default_rng(3)
    g = 0.005 * rng.standard_normal((20_000, 3))
    g[8000:8300, 2] += 1.5  # a 3 s turn
    _, _, q = prepare_stream(_stream("gyro", g))
    assert len(q.motion) == 1 and 79.0 <= q.motion[0][0] <= 80.5 and 82.5 <= q.motion[0][1] <= 84.0
    assert "motion detected" in q.flags[0]
    with pytest.raises(InputError, match="motion detected"):
        prepare_stream(_stream("gyro", g), motion_policy="error")


def test_tilt_is_motion_for_the_accelerometer():
    rng = np.random.default_rng(4)
    a = _static_acc(20_000, rng)
    tilt = np.deg2rad(10.0)
    a[12_000:] = np.array([0.0, 9.81 * np.sin(tilt), 9.81 * np.cos(tilt)]) + 0.02 * rng.standard_normal((8000, 3))
    assert detect_motion(a, FS, "acc")  # the sensor was put down differently: not one static record


def test_static_noise_is_not_motion():
    rng = np.random.default_rng(5)
    assert detect_motion(_static_acc(100_000, rng), FS, "acc") == []


def test_bad_input():
    with pytest.raises(InputError, match="has 3 samples"):
        prepare_stream(_stream("gyro", np.zeros((3, 3))))
    with pytest.raises(InputError, match="gap_policy"):
        prepare_stream(_stream("gyro", np.zeros((30, 3))), gap_policy="fill")
