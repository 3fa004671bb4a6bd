"""OnlineGrid: the uniform grid on the log clock, linear interpolation, batch independence, flush and state, and
streams that stop (gaps longer than MAX_STREAM_GAP_S are not bridged)."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.phone.grid import MAX_STREAM_GAP_S, OnlineGrid
from pdr.recording import Recording, SensorStream


def _rec(t_s: dict[str, np.ndarray], fn) -> Recording:
    return Recording({k: SensorStream(k, np.round(t * 1e9).astype(np.int64), fn(k, t)) for k, t in t_s.items()})


def _lin(kind: str, t: np.ndarray) -> np.ndarray:
    # A linear signal per stream: interpolation onto the grid is exact.
    a = {"acc": 1.0, "gyro": -2.0}[kind]
    return np.column_stack([a * t + 0.5, 3.0 * t, np.full(t.size, a)])


def _feed(grid: OnlineGrid, rec: Recording, cuts: list[float]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Every grid point, in batches cut at ``cuts`` (s); a stream absent over a run of points gets NaN there."""
    ts: list[np.ndarray] = []
    vs: dict[str, list[np.ndarray]] = {k: [] for k in grid.kinds}
    edges = [-np.inf, *cuts, np.inf]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        part = Recording({k: SensorStream(k, s.t_ns[(s.t_ns / 1e9 >= a) & (s.t_ns / 1e9 < b)],
                                          s.values[(s.t_ns / 1e9 >= a) & (s.t_ns / 1e9 < b)])
                          for k, s in rec.streams.items() if ((s.t_ns / 1e9 >= a) & (s.t_ns / 1e9 < b)).any()})
        grid.push(part)
        while _keep(ts, vs, *grid.pull()):
            pass
        grid = OnlineGrid.from_state(grid.state())     # resumed after every batch
    while _keep(ts, vs, *grid.flush()):
        pass
    return np.concatenate(ts), {k: np.concatenate(vs[k]) for k in grid.kinds}


def _keep(ts: list, vs: dict, t: np.ndarray, v: dict[str, np.ndarray]) -> bool:
    if t.size:
        ts.append(t)
        for k in vs:
            vs[k].append(v[k] if k in v else np.full((t.size, 1 if k == "baro" else 3), np.nan))
    return bool(t.size)


def test_grid_points_are_multiples_of_the_period_and_interpolate_linear_signals_exactly():
    rng = np.random.default_rng(0)
    acc_t = np.sort(rng.uniform(10.013, 14.0, 380))           # irregular sampling, ~95 Hz
    gyro_t = np.arange(10.031, 13.5, 0.0097)
    rec = _rec({"acc": acc_t, "gyro": gyro_t}, _lin)
    t, v = _feed(OnlineGrid(50.0, ("acc", "gyro")), rec, [])
    k = t * 50.0
    assert np.allclose(k, np.round(k), atol=1e-9)              # t_k = k / rate on the log clock
    assert t[0] >= max(acc_t[0], gyro_t[0]) and t[0] - max(acc_t[0], gyro_t[0]) < 0.02
    assert np.all(np.diff(t) == pytest.approx(0.02))
    # flush runs to the first (primary) stream's last sample and holds the others' last value.
    assert acc_t[-1] - t[-1] < 0.02 and t[-1] > gyro_t[-1]
    inside = t <= gyro_t[-1]
    np.testing.assert_allclose(v["acc"], _lin("acc", t), atol=1e-9)
    np.testing.assert_allclose(v["gyro"][inside], _lin("gyro", t[inside]), atol=1e-9)
    np.testing.assert_allclose(v["gyro"][~inside], np.repeat(_lin("gyro", gyro_t[-1:]), (~inside).sum(), 0))


@pytest.mark.parametrize("cuts", [[10.5], [10.2, 11.0, 11.01, 13.3], list(np.arange(10.1, 14.0, 0.37))])
def test_batches_and_state_round_trips_give_the_one_batch_grid(cuts):
    rng = np.random.default_rng(1)
    acc_t = np.sort(rng.uniform(10.0, 14.0, 400))
    gyro_t = np.sort(rng.uniform(10.0, 14.0, 300))
    rec = _rec({"acc": acc_t, "gyro": gyro_t}, lambda k, t: np.column_stack([np.sin(7 * t), np.cos(3 * t), t]))
    t1, v1 = _feed(OnlineGrid(50.0, ("acc", "gyro")), rec, [])
    t2, v2 = _feed(OnlineGrid(50.0, ("acc", "gyro")), rec, cuts)
    np.testing.assert_array_equal(t1, t2)
    for k in ("acc", "gyro"):
        np.testing.assert_array_equal(v1[k], v2[k])


def test_repeated_samples_are_dropped_and_nothing_is_emitted_before_every_stream_has_data():
    g = OnlineGrid(50.0, ("acc", "baro"))
    acc = _rec({"acc": np.arange(0.0, 1.0, 0.01)}, lambda k, t: np.column_stack([t, t, t]))
    g.push(acc)
    t, _ = g.pull()
    assert t.size == 0                                          # no barometer sample yet
    g.push(acc)                                                 # the same batch again: ignored
    assert g.buf_t["acc"].size == 100
    g.push(_rec({"baro": np.array([0.1, 0.9])}, lambda k, t: t[:, None] * 0 + 1000.0))
    t, v = g.pull()
    assert t[0] == pytest.approx(0.1) and t[-1] == pytest.approx(0.9) and np.all(v["baro"] == 1000.0)


def test_bad_rate_and_state_are_named():
    with pytest.raises(InputError, match="grid rate must be positive"):
        OnlineGrid(0.0, ("acc",))
    with pytest.raises(InputError, match="bad grid state"):
        OnlineGrid.from_state({"rate_hz": 50.0})


def _gappy() -> Recording:
    """acc at 100 Hz over 0-30 s; gyro with a 4 s gap (8-12 s) and ending at 20 s; baro at 1 Hz to 29.5 s."""
    acc_t = np.arange(0.0, 30.0, 0.01)
    gyro_t = np.concatenate([np.arange(0.003, 8.0, 0.01), np.arange(12.003, 20.0, 0.01)])
    baro_t = np.arange(0.4, 29.6, 1.0)
    return _rec({"acc": acc_t, "gyro": gyro_t, "baro": baro_t},
                lambda k, t: t[:, None] if k == "baro" else np.column_stack([np.sin(t), np.cos(2 * t), t]))


def test_a_stream_is_absent_over_its_long_gaps_and_after_it_stops_and_bridged_over_short_ones():
    t, v = _feed(OnlineGrid(50.0, ("acc", "gyro", "baro")), _gappy(), [])
    gyro_t = _gappy().t_s("gyro")
    gap = (t > gyro_t[gyro_t < 8.0][-1]) & (t < 12.003)
    stopped = t > gyro_t[-1]
    assert np.all(np.isnan(v["gyro"][gap | stopped])) and not np.isnan(v["gyro"][~(gap | stopped)]).any()
    # The barometer's 1 s period is bridged, and its last sample (0.5 s before the end) held.
    assert not np.isnan(v["baro"]).any() and np.all(v["baro"][t > 29.4][:, 0] == pytest.approx(29.4))
    assert t[-1] == pytest.approx(29.98) and np.all(np.diff(t) == pytest.approx(0.02))


@pytest.mark.parametrize("cuts", [list(np.arange(0.5, 30.0, 1.0)), [9.0, 9.01, 15.5, 25.0],
                                  list(np.arange(0.1, 30, 0.37))])
def test_a_stopped_stream_does_not_hold_up_a_live_session_and_batches_give_the_one_batch_grid(cuts):
    t1, v1 = _feed(OnlineGrid(50.0, ("acc", "gyro", "baro")), _gappy(), [])
    t2, v2 = _feed(OnlineGrid(50.0, ("acc", "gyro", "baro")), _gappy(), cuts)
    np.testing.assert_array_equal(t1, t2)
    for k in v1:
        np.testing.assert_array_equal(v1[k], v2[k])
    # Live: once the accelerometer is 2 max_gap_s past the gyro's last sample, the grid goes on without the gyro.
    g = OnlineGrid(50.0, ("acc", "gyro"))
    g.push(_gappy().slice_time(0.0, 20.0 + 2 * MAX_STREAM_GAP_S + 1.0).with_streams({}))
    emitted = []
    while (run := g.pull())[0].size:
        emitted.append(run)
    assert emitted[-1][0][-1] == pytest.approx(20.0 + MAX_STREAM_GAP_S + 1.0, abs=0.02)
    assert "gyro" not in emitted[-1][1] and "gyro" in emitted[-2][1]


def test_runs_longer_than_the_search_window_are_found_whole():
    # Runs of 7 500 and 15 000 grid points, past the first window in which the grid looks for a change of the
    # streams present: the one-batch grid has the same runs as one fed in batches shorter than that window.
    acc_t = np.arange(0.0, 400.0, 0.01)
    gyro_t = np.concatenate([np.arange(0.003, 150.0, 0.01), np.arange(154.003, 300.0, 0.01),
                             np.arange(304.003, 400.0, 0.01)])
    rec = _rec({"acc": acc_t, "gyro": gyro_t}, lambda k, t: np.column_stack([np.sin(t), np.cos(2 * t), t]))
    g = OnlineGrid(50.0, ("acc", "gyro"))
    g.push(rec)
    runs = []
    while (run := g.pull())[0].size:
        runs.append((run[0][0], run[0][-1], "gyro" in run[1]))
    assert [(round(a, 2), round(b, 2), p) for a, b, p in runs[:4]] == [
        (0.02, 149.98, True), (150.0, 154.0, False), (154.02, 299.98, True), (300.0, 304.0, False)]
    t1, v1 = _feed(OnlineGrid(50.0, ("acc", "gyro")), rec, [])
    t2, v2 = _feed(OnlineGrid(50.0, ("acc", "gyro")), rec, list(np.arange(20.0, 400.0, 20.0)))
    np.testing.assert_array_equal(t1, t2)
    for k in v1:
        np.testing.assert_array_equal(v1[k], v2[k])
    # The values are np.interp's over the whole streams, to the bit (the grid interpolates the bracketing samples).
    s = rec.stream("acc")
    whole = np.column_stack([np.interp(t1, s.t_ns / 1e9, s.values[:, j]) for j in range(3)])
    np.testing.assert_array_equal(v1["acc"], whole)
