import numpy as np
import pytest

from pdr import DeviceInfo, GroundTruth, InputError, Labels, PositionTruth, Recording, SensorStream


def _acc(n=5, t0=1_000_000_000):
    return SensorStream("acc", t0 + np.arange(n) * 10_000_000, np.tile([0.0, 0.0, 9.81], (n, 1)))


def test_stream_arrays_are_readonly_and_typed():
    s = _acc()
    assert s.t_ns.dtype == np.int64 and s.values.dtype == np.float64
    with pytest.raises(ValueError):
        s.values[0, 0] = 1.0
    assert s.median_rate_hz() == pytest.approx(100.0)


def test_single_column_stream_accepts_1d_values():
    s = SensorStream("baro", np.array([1, 2, 3]), np.array([1000.0, 1000.1, 1000.2]))
    assert s.values.shape == (3, 1)


@pytest.mark.parametrize(
    ("t", "v", "match"),
    [
        ([1, 2, 2], np.zeros((3, 3)), r"stream 'acc'.*sample 2.*duplicates sample 1"),
        ([1, 3, 2], np.zeros((3, 3)), r"stream 'acc'.*sample 2.*goes back"),
        ([1, 2, 3], [[0, 0, 0], [0, np.nan, 0], [0, 0, 0]], r"stream 'acc'.*sample 1 is not finite"),
        ([1, 2, 3], np.zeros((3, 2)), r"stream 'acc'.*shape \(3, 3\)"),
        ([1, 2, 3], np.zeros((2, 3)), r"stream 'acc'.*shape \(3, 3\)"),
        ([[1, 2, 3]], np.zeros((3, 3)), r"stream 'acc'.*1-D"),
        ([1, 2, 3], [["a", "b", "c"]] * 3, r"stream 'acc'.*not numeric"),
    ],
)
def test_invalid_stream_names_stream_and_sample(t, v, match):
    with pytest.raises(InputError, match=match):
        SensorStream("acc", t, v)


def test_unknown_kind_and_metadata_rejected():
    with pytest.raises(InputError, match="unknown stream kind"):
        SensorStream("accel", np.array([1]), np.array([[0.0, 0.0, 0.0]]))
    with pytest.raises(InputError, match="device role"):
        DeviceInfo(role="pocket")
    with pytest.raises(InputError, match="placement"):
        DeviceInfo(placement="shoe")


def test_recording_time_axis_and_equality():
    acc = _acc(t0=5_000_000_000)
    gyro = SensorStream("gyro", 4_990_000_000 + np.arange(3) * 5_000_000, np.zeros((3, 3)))
    rec = Recording({"gyro": gyro, "acc": acc}, DeviceInfo(platform="android", model="X"))
    assert rec.t0_ns == 4_990_000_000
    assert list(rec.streams) == ["acc", "gyro"]  # canonical order
    np.testing.assert_allclose(rec.t_s("acc")[:2], [0.01, 0.02])
    assert rec.duration_s == pytest.approx(0.05)
    assert rec == Recording({"acc": acc, "gyro": gyro}, DeviceInfo(platform="android", model="X"))
    with pytest.raises(InputError, match="no 'mag' stream"):
        rec.stream("mag")
    part = rec.slice_time(0.0, 0.02)
    assert len(part.stream("acc")) == 1 and len(part.stream("gyro")) == 3


def test_recording_rejects_mismatched_key_and_empty():
    with pytest.raises(InputError, match="at least one"):
        Recording({})
    with pytest.raises(InputError, match="kind is 'acc'"):
        Recording({"gyro": _acc()})


def test_ground_truth_validation():
    pos = PositionTruth(np.array([0.0, 1.0]), np.array([[0.0, 0, 0], [1, 0, 0]]), floor=np.array([0.0, 0.0]))
    gt = GroundTruth(positions=pos, step_times_s=np.array([0.5, 1.0]))
    assert gt.step_count == 2 and "positions" in gt.kinds()
    with pytest.raises(InputError, match="pos_m must have shape"):
        PositionTruth(np.array([0.0, 1.0]), np.array([[0.0, 0, 0]]))
    with pytest.raises(InputError, match="goes back"):
        GroundTruth(step_times_s=np.array([1.0, 0.5]))
    with pytest.raises(InputError, match="ends"):
        Labels(np.array([0.0]), np.array([-1.0]), ("walking",))
    labels = Labels(np.array([0.0, 2.0]), np.array([2.0, 3.0]), ("walking", "stairs_up"))
    assert list(labels.at(np.array([1.0, 2.5, 4.0]), default="?")) == ["walking", "stairs_up", "?"]
