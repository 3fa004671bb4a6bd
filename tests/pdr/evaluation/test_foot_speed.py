"""Foot navigator cost measurement (pdr.evaluation.foot_speed)."""

from __future__ import annotations

import numpy as np

from pdr.evaluation.foot_speed import tiled


def test_tiled_recording_has_a_continuous_time_axis() -> None:
    t = np.arange(5) / 100.0 + 3.0
    acc = np.arange(15, dtype=float).reshape(5, 3)
    gyro = -acc
    tt, aa, gg = tiled(t, acc, gyro, 100.0, 0.12)
    assert tt.size == 15 and aa.shape == (15, 3) and gg.shape == (15, 3)
    assert np.allclose(np.diff(tt), 0.01)
    assert tt[0] == 0.0 and tt[-1] >= 0.12
    assert np.array_equal(aa[5:10], acc) and np.array_equal(gg[10:], gyro)
