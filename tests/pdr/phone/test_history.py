"""The phone pipeline's sample history (pdr.phone.history): indexing by grid sample, trimming, state round trips."""

from __future__ import annotations

import numpy as np
import pytest

from pdr import state_codec
from pdr.phone.history import SampleHistory


def batch(history: SampleHistory, start: int, n: int) -> None:
    """Append ``n`` samples from grid index ``start``; every field holds the sample's grid index (t in s at 100 Hz)."""
    i = np.arange(start, start + n, dtype=np.float64)
    history.append(start, i / 100.0, np.stack([i, i, i], axis=1), i, i, i, i)
    sl = history.sl(start, start + n)
    history.q[sl] = np.stack([i, i, i, i], axis=1)
    history.gyro_yaw[sl] = i


def test_samples_are_found_by_their_grid_index_after_trimming() -> None:
    h = SampleHistory(size=100)
    batch(h, 500, 80)
    batch(h, 580, 70)                  # 150 samples held, the first 50 beyond the size
    assert h.t.size == 150 and h.start == 500
    h.trim()
    assert h.t.size == 100 and h.start == 550
    for name in ("t", "acc", "q", "an", "mag_n", "up", "floor", "gyro_yaw"):
        assert getattr(h, name).shape[0] == 100, name
    sl = h.sl(600, 610)
    assert np.array_equal(h.an[sl], np.arange(600, 610))
    assert np.array_equal(h.q[sl][:, 2], np.arange(600, 610))
    assert np.allclose(h.t[sl], np.arange(600, 610) / 100.0)
    # Indices before the held window clip to its start; the stages' rows not yet computed are NaN.
    assert h.sl(400, 560) == slice(0, 10)
    assert np.isnan(h.f_n[h.sl(600, 601)]).all()


def test_trim_keeps_a_short_history_whole() -> None:
    h = SampleHistory(size=100)
    batch(h, 0, 40)
    h.trim()
    assert h.start == 0 and h.t.size == 40


def test_state_round_trip_through_the_codec() -> None:
    """A history restored from its saved state (the pipeline's codec) is equal field by field, NaN rows included,
    and independent of the original.
    """
    h = SampleHistory(size=120)
    batch(h, 1000, 90)
    batch(h, 1090, 60)
    h.trim()
    again = SampleHistory.from_state(state_codec.loads(state_codec.dumps(h.state())))
    assert (again.size, again.start) == (h.size, h.start)
    for name in ("t", "acc", "q", "f_n", "yaw_y", "yaw_z", "y_up", "an", "mag_n", "up", "floor", "gyro_yaw",
                 "up_time"):
        assert np.array_equal(getattr(again, name), getattr(h, name), equal_nan=True), name
    again.an[0] = -1.0
    assert h.an[0] == 1030.0


def test_state_saved_before_the_heading_smoother_resumes_with_nan_gyro_rows() -> None:
    h = SampleHistory(size=50)
    batch(h, 10, 30)
    old = {k: v for k, v in h.state().items() if k not in ("gyro_yaw", "up_time")}
    again = SampleHistory.from_state(old)
    assert again.gyro_yaw.shape == (30,) and np.isnan(again.gyro_yaw).all()
    assert again.up_time.shape == (30, 3) and np.isnan(again.up_time).all()
    assert np.array_equal(again.an, h.an)


def test_appended_rows_are_what_concatenate_gives_bit_for_bit():
    """One batch appended: the history's arrays are np.concatenate of the old rows and the batch's (or NaN rows for
    what the stages fill in later), and a batch field of another length is refused.
    """
    rng = np.random.default_rng(5)
    h = SampleHistory(10_000)
    parts: dict[str, list[np.ndarray]] = {}
    start = 0
    for n in (7, 0, 130, 1, 3):
        t = start / 100.0 + np.arange(n) / 100.0
        acc = rng.normal(size=(n, 3))
        an, mag, up, floor = rng.normal(size=n), np.where(rng.random(n) < 0.3, np.nan, 40.0), -0.0 * t, np.ones(n)
        h.append(start, t, acc, an, mag, up, floor)
        for name, v in (("t", t), ("acc", acc), ("an", an), ("mag_n", mag), ("up", up), ("floor", floor),
                        ("q", np.full((n, 4), np.nan)), ("up_time", np.full((n, 3), np.nan)),
                        ("yaw_y", np.full(n, np.nan))):
            parts.setdefault(name, []).append(v)
        start += n
    for name, chunks in parts.items():
        want = np.concatenate([np.zeros((0, *chunks[0].shape[1:])), *chunks])
        got = getattr(h, name)
        assert got.dtype == want.dtype and got.shape == want.shape and got.flags.c_contiguous
        assert got.tobytes() == want.tobytes(), name
    with pytest.raises(ValueError, match="history rows"):
        h.append(start, np.zeros(3), np.zeros((3, 3)), np.zeros(1), np.zeros(3), np.zeros(3), np.zeros(3))
