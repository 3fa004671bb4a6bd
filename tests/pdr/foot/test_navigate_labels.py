"""Foot navigation with given zero-velocity labels (a data set's reference labels) instead of the detector's."""

from __future__ import annotations

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.foot.navigate import labels_at, navigate
from pdr.foot.zupt import run_zupt
from pdr.recording import DeviceInfo, Recording, SensorStream
from tests.pdr.foot.gait import simulate_gait


def test_each_sample_takes_the_label_nearest_in_time() -> None:
    lt = np.array([0.0, 1.0, 2.0, 3.0])
    flags = np.array([True, False, True, False])
    t = np.array([-5.0, 0.4, 0.6, 1.49, 1.51, 2.9, 9.0])
    assert labels_at(t, lt, flags).tolist() == [True, True, False, False, True, False, False]
    assert labels_at(lt, lt, flags).tolist() == flags.tolist()
    assert labels_at(t, [1.0], [True]).tolist() == [True] * t.size
    for bad in (([0.0, 1.0], [True]), ([1.0, 0.0], [True, False]), ([], [])):
        with pytest.raises(InputError, match="zero-velocity labels"):
            labels_at(t, *bad)


def test_navigation_uses_the_given_labels() -> None:
    g = simulate_gait(n_strides=6, sigma_acc=0.02, sigma_gyro=0.002, seed=3)
    t_ns = np.round(g.t_s * 1e9).astype(np.int64)
    rec = Recording({"acc": SensorStream("acc", t_ns, g.acc_b), "gyro": SensorStream("gyro", t_ns, g.gyro_b)},
                    DeviceInfo(platform="imu", role="left_foot", placement="foot"))
    imu, track = navigate(rec, "zupt", smooth=False, zero_velocity=(g.t_s, g.stance))
    assert np.array_equal(track.zero_velocity, g.stance)
    ref = run_zupt(imu.t_s, imu.acc_b, imu.gyro_b, g.stance, rate_hz=imu.rate_hz, smooth=False)
    np.testing.assert_array_equal(track.pos_n, ref.pos_n)
    # The true stances give the true stride positions; the detector's differ from them.
    _, detected = navigate(rec, "zupt", smooth=False)
    assert not np.array_equal(detected.zero_velocity, g.stance)
    assert np.linalg.norm(track.pos_n[-1, :2] - g.pos_n[-1, :2]) < 0.05
