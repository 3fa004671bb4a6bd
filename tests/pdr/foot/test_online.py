"""Online foot navigation: batch by batch (any chunking, state saved and restored) equals the whole-log result."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.foot.detectors import DetectorConfig
from pdr.foot.navigate import navigate
from pdr.foot.online import FootStep, OnlineFootNavigator
from pdr.foot.zupt import ZuptConfig
from pdr.frames import yaw_to_heading_deg
from pdr.recording import DeviceInfo, Recording, SensorStream
from tests.conftest import data_path
from tests.pdr.foot.gait import simulate_gait

T0_NS = 1_700_000_000_123_456_789
# Times (log clock), positions and compass headings of the batch navigator's resets, and its warnings.
BatchSteps = tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]


def gait_recording(gyro_shift_ns: int = 0, start_s: float = 0.0, n_strides: int = 12,
                   role: str = "left_foot") -> Recording:
    g = simulate_gait(n_strides=n_strides, turn_rad=0.2, sigma_acc=0.02, sigma_gyro=0.002, seed=3)
    keep = g.t_s >= start_s
    t_ns = T0_NS + np.round(g.t_s[keep] * 1e9).astype(np.int64)
    return Recording({"acc": SensorStream("acc", t_ns, g.acc_b[keep]),
                      "gyro": SensorStream("gyro", t_ns + gyro_shift_ns, g.gyro_b[keep])},
                     DeviceInfo(platform="imu", role=role, placement="foot"), t0_ns=T0_NS)


def batch_steps(rec: Recording, zupt: ZuptConfig | None = None) -> BatchSteps:
    """Times (log clock), positions and compass headings of the resets of ``navigate(..., 'stepwise')``."""
    imu, track = navigate(rec, "stepwise", zupt=zupt)
    idx = np.array([s.index for s in track.steps], dtype=np.int64)
    return (track.t_s[idx] + imu.clock_offset_s, track.pos_n[idx], yaw_to_heading_deg(track.yaw[idx]),
            track.warnings)


def chunks(rec: Recording, rng: np.random.Generator, min_s: float, max_s: float) -> list[Recording]:
    t0, t1 = rec.time_span_s()
    out, a = [], t0
    while a <= t1:
        b = a + float(rng.uniform(min_s, max_s))
        try:
            out.append(rec.slice_time(a, b))
        except InputError:      # no sample in this interval
            pass
        a = b
    return out


def run_online(parts: list[Recording], restore: bool,
               zupt: ZuptConfig | None = None) -> tuple[list[FootStep], list[str], OnlineFootNavigator]:
    nav = OnlineFootNavigator(zupt=zupt)
    steps, warnings = [], []
    for part in parts:
        steps += nav.update(part)
        warnings += nav.take_warnings()
        if restore:
            nav = OnlineFootNavigator.from_dict(json.loads(json.dumps(nav.to_dict())))
    steps += nav.finish()
    return steps, warnings + nav.take_warnings(), nav


def assert_same_track(steps: list[FootStep], ref: BatchSteps) -> None:
    t, pos, heading = ref[:3]
    assert len(steps) == t.size > 5
    np.testing.assert_allclose([s.t_s for s in steps], t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.array([s.pos_n for s in steps]), pos, rtol=0, atol=1e-9)
    dh = (yaw_to_heading_deg(np.array([s.yaw for s in steps])) - heading + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(dh, 0.0, atol=1e-7)


@pytest.mark.parametrize("seed", [0, 1])
def test_random_chunks_with_state_round_trips_equal_the_whole_log(seed: int) -> None:
    rec = gait_recording()
    ref = batch_steps(rec)
    steps, _, nav = run_online(chunks(rec, np.random.default_rng(seed), 0.01, 2.5), restore=True)
    assert_same_track(steps, ref)
    # Every step increment composes to its position (eq. 7 on the log's clock and sample indices).
    assert [s.increment.t_s for s in steps] == [s.t_s for s in steps]
    assert np.all(np.diff([s.increment.index for s in steps]) > 0)
    # The carried buffer is the detector's context, not the session: cost proportional to the batch.
    assert nav.buf_t_ns.size < 2 * 200


def test_zero_angular_rate_update_in_random_chunks_equals_the_whole_log() -> None:
    # 0.2 s of stillness suffices here, so that the 0.5 s stances of the simulated walk update the bias.
    rec = gait_recording()
    cfg = ZuptConfig(zaru=True, zaru_min_still_s=0.2)
    ref = batch_steps(rec, cfg)
    steps, _, nav = run_online(chunks(rec, np.random.default_rng(4), 0.01, 2.5), restore=True, zupt=cfg)
    assert_same_track(steps, ref)
    assert nav.filter is not None and np.any(nav.filter.bias != 0.0)
    assert not np.allclose(ref[1], batch_steps(rec)[1], rtol=0, atol=1e-9)


def test_interval_samples_in_random_chunks_equal_the_whole_log() -> None:
    rec = gait_recording()
    cfg = ZuptConfig(interval_samples=True)
    ref = batch_steps(rec, cfg)
    steps, _, _ = run_online(chunks(rec, np.random.default_rng(6), 0.01, 2.5), restore=True, zupt=cfg)
    assert_same_track(steps, ref)
    assert not np.allclose(ref[1], batch_steps(rec)[1], rtol=0, atol=1e-9)


def test_gyroscope_on_other_instants_is_interpolated_like_the_batch_reader() -> None:
    rec = gait_recording(gyro_shift_ns=2_000_000)
    ref = batch_steps(rec)
    steps, warnings, _ = run_online(chunks(rec, np.random.default_rng(5), 0.2, 1.5), restore=True)
    assert_same_track(steps, ref)
    assert any("gyroscope interpolated" in w for w in warnings)


def test_start_in_swing_is_navigated_like_the_batch() -> None:
    rec = gait_recording(start_s=0.7)
    ref = batch_steps(rec)
    steps, warnings, _ = run_online(chunks(rec, np.random.default_rng(2), 0.3, 1.0), restore=False)
    assert_same_track(steps, ref)
    assert any("starts in motion" in w for w in warnings) == any("starts in motion" in w for w in ref[3])


def test_gap_is_reported() -> None:
    rec = gait_recording()
    t0, t1 = rec.time_span_s()
    parts = [rec.slice_time(t0, 6.0), rec.slice_time(6.5, t1 + 1.0)]
    _, warnings, _ = run_online(parts, restore=False)
    assert any("gap of 0.50" in w for w in warnings)


def test_bad_input_is_refused() -> None:
    rec = gait_recording()
    nav = OnlineFootNavigator()
    nav.update(rec.slice_time(0.0, 2.0))
    with pytest.raises(InputError, match="time order"):
        nav.update(rec.slice_time(1.0, 3.0))
    with pytest.raises(InputError, match="phone recording"):
        OnlineFootNavigator().update(Recording(rec.streams, DeviceInfo(platform="android", role="phone")))
    with pytest.raises(InputError, match="gyro"):
        OnlineFootNavigator().update(Recording({"acc": rec.stream("acc")}, rec.device, t0_ns=T0_NS))


def test_a_foot_that_never_rests_gives_no_track_and_says_why() -> None:
    rec = gait_recording()
    moving = Recording({k: SensorStream(k, s.t_ns, s.values + np.sin(np.arange(len(s)))[:, None])
                        for k, s in rec.streams.items()}, rec.device, t0_ns=T0_NS)
    with pytest.raises(InputError, match="no stationary period"):
        navigate(moving, "stepwise", DetectorConfig(adaptive=False))
    nav = OnlineFootNavigator(DetectorConfig(adaptive=False))
    assert nav.update(moving) == []
    assert nav.finish() == []
    assert any("never came to rest" in w for w in nav.take_warnings())


@pytest.mark.data
@pytest.mark.parametrize("path", [("pyshoe_vicon", "2018-02-09-11-16-53.mat"),
                                  ("xio_gait_loop", "short_walk.csv")])
def test_real_foot_log_in_random_chunks_equals_navigate(path: tuple[str, str]) -> None:
    from pdr.io import read_recording

    rec = read_recording(data_path(*path))
    ref = batch_steps(rec)
    steps, _, _ = run_online(chunks(rec, np.random.default_rng(7), 0.05, 3.0), restore=True)
    assert_same_track(steps, ref)
