import numpy as np

from pdr.io.sensor_logger import parse_push_message
from pdr.io.sensor_logger_writer import to_push_messages, window_count
from pdr.recording import DeviceInfo, Recording, SensorStream


def _rec() -> Recording:
    t = 1_700_000_000_000_000_000 + np.arange(250, dtype=np.int64) * 10_000_000  # 2.5 s at 100 Hz
    rng = np.random.default_rng(0)
    acc = np.array([0.0, 0.0, 9.81]) + 0.01 * rng.standard_normal((250, 3))
    gyro = 0.01 * rng.standard_normal((250, 3))
    return Recording({"acc": SensorStream("acc", t, acc), "gyro": SensorStream("gyro", t, gyro),
                      "baro": SensorStream("baro", t[::10], np.full(25, 1000.0))}, DeviceInfo(platform="android"))


def test_messages_round_trip_through_the_reader():
    rec = _rec()
    msgs = to_push_messages(rec, session_id="s", device_id="d", period_s=1.0)
    assert [m["messageId"] for m in msgs] == [0, 1, 2] == list(range(window_count(rec, 1.0)))
    parts = [parse_push_message(m, platform="android", standardised=True) for m in msgs]
    for kind in ("acc", "gyro", "baro"):
        t = np.concatenate([p.stream(kind).t_ns for p in parts])
        v = np.concatenate([p.stream(kind).values for p in parts])
        np.testing.assert_array_equal(t, rec.stream(kind).t_ns)
        np.testing.assert_array_equal(v, rec.stream(kind).values)
