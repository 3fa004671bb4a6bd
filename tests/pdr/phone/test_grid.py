"""OnlineGrid: the uniform grid on the log clock, linear interpolation, batch independence, flush and state, and
streams that stop (gaps longer than MAX_STREAM_GAP_S are not bridged)."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.phone.grid import MAX_JUMP_S, MAX_LAG_S, MAX_RUN_S, MAX_STREAM_GAP_S, OnlineGrid
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


def test_a_stream_missing_from_the_first_batch_joins_when_it_arrives():
    # The gyroscope starts 1.5 s after the accelerometer, in the second batch: it joins the grid then, absent before
    # its first sample and interpolated from there on; a stream not named in may_join never joins.
    acc_t, gyro_t = np.arange(0.0, 5.0, 0.01), np.arange(1.505, 5.0, 0.01)
    rec = _rec({"acc": acc_t, "gyro": gyro_t}, _lin)
    first = Recording({"acc": rec.streams["acc"]}).slice_time(0.0, 1.0)
    g = OnlineGrid(50.0, ("acc",), may_join=("gyro",))
    assert g.push(first) == []
    ts: list[np.ndarray] = []
    vs: dict[str, list[np.ndarray]] = {"acc": [], "gyro": []}
    while _keep(ts, vs, *g.pull()):
        pass
    g = OnlineGrid.from_state(g.state())
    assert g.push(rec.slice_time(1.0, 2.0)) == ["gyroscope data starts at t=1.50 s, after the session's first batch: "
                                                "used from there on"] and g.kinds == ("acc", "gyro")
    g = OnlineGrid.from_state(g.state())
    assert g.push(rec.slice_time(2.0, 5.0)) == []
    while _keep(ts, vs, *g.pull()):
        pass
    while _keep(ts, vs, *g.flush()):
        pass
    t, gyro = np.concatenate(ts), np.concatenate(vs["gyro"])
    late = t < gyro_t[0]
    assert late.any() and np.isnan(gyro[late]).all()
    np.testing.assert_allclose(gyro[~late], _lin("gyro", t[~late]), atol=1e-9)
    assert np.all(np.diff(t) == pytest.approx(0.02)) and t[-1] == pytest.approx(4.98)
    # Without may_join (and in states saved before it) the stream is not taken up.
    g = OnlineGrid(50.0, ("acc",))
    g.push(first)
    assert g.push(rec.slice_time(1.0, 2.0)) == [] and g.kinds == ("acc",)


def test_a_batch_whose_clock_went_back_is_said_once_and_a_batch_sent_again_is_not():
    acc_t = np.arange(0.0, 20.0, 0.01)
    rec = _rec({"acc": acc_t, "gyro": acc_t + 0.003}, _lin)
    g = OnlineGrid(50.0, ("acc", "gyro"))
    assert g.push(rec.slice_time(0.0, 4.0)) == [] and g.push(rec.slice_time(4.0, 8.0)) == []
    # Sent again (after a timeout), or overlapping the last batch by less than BACK_TOLERANCE_S: nothing to say.
    assert g.push(rec.slice_time(4.0, 8.0)) == [] and g.push(rec.slice_time(7.7, 9.0)) == []
    g = OnlineGrid.from_state(g.state())
    # The app restarts with a new clock (from 0 s again): said once, while its batches stay before what was taken.
    shifted = _rec({"acc": acc_t[:600] + 0.0042, "gyro": acc_t[:600] + 0.0072}, _lin)
    said = g.push(shifted.slice_time(0.0, 2.0))
    assert len(said) == 1 and "goes 8.99 s back before data already processed (up to t=8.99 s)" in said[0]
    g = OnlineGrid.from_state(g.state())
    assert g.push(shifted.slice_time(2.0, 4.0)) == []
    assert g.push(rec.slice_time(9.0, 12.0)) == []
    assert len(g.push(rec.slice_time(3.0, 5.0))) == 1           # a new episode is said again


def test_a_stream_a_whole_batch_late_is_waited_for_once_its_lag_is_known():
    # 5 s batches; from the second on, the gyroscope's samples come a batch late (5 s behind, more than the 4 s
    # slack). The first late batch is taken as a stop (its points go without the gyro); the gyro then goes on where it
    # left off, so the grid learns the lag, says so, and from there every point has the gyro.
    t = np.arange(0.0, 40.0, 0.01)
    rec = _rec({"acc": t, "gyro": t + 0.004}, _lin)
    g = OnlineGrid(50.0, ("acc", "gyro"))
    ts: list[np.ndarray] = []
    vs: dict[str, list[np.ndarray]] = {"acc": [], "gyro": []}
    said = []
    for a in np.arange(0.0, 40.0, 5.0):
        acc = rec.slice_time(a, a + 5.0).streams["acc"]
        gyro = rec.slice_time(max(a - 5.0, 0.0), a if a >= 10.0 else a + 5.0).streams["gyro"] if a != 5.0 else None
        said += g.push(Recording({"acc": acc} if gyro is None else {"acc": acc, "gyro": gyro}))
        while _keep(ts, vs, *g.pull()):
            pass
        g = OnlineGrid.from_state(g.state())
    assert len(said) == 1 and said[0].startswith("gyroscope data comes 5.0 s behind the accelerometer's")
    tg, gyro_v = np.concatenate(ts), np.concatenate(vs["gyro"])
    missing = np.isnan(gyro_v[:, 0])
    assert missing.any() and tg[missing].max() < 10.0       # only the points of the first late batch
    assert tg[-1] >= 29.0                                    # live: waits at most the learnt lag (7 s)


def test_an_hour_without_data_is_bridged_run_by_run_and_a_clock_reset_by_days_is_refused():
    # The app is suspended for an hour: the accelerometer is interpolated across it in runs of at most MAX_RUN_S
    # (before, one run of 180 000 points; a day took 2 GB), the gyroscope absent there.
    t = np.arange(0.0, 5.0, 0.01)
    g = OnlineGrid(50.0, ("acc", "gyro"))
    g.push(_rec({"acc": t, "gyro": t + 0.004}, _lin))
    runs = []
    said = g.push(_rec({"acc": t + 3605.0, "gyro": t + 3605.004}, _lin))
    assert said == ["no accelerometer data from t=4.99 to 3605.00 s (3600.0 s: the app suspended, or the phone stopped "
                    "sending): it is bridged by interpolation, no step is counted in it and the track goes on from "
                    "where it was"]
    while (run := g.pull())[0].size:
        runs.append(run)
    assert max(r[0].size for r in runs) <= MAX_RUN_S * 50.0
    tg = np.concatenate([r[0] for r in runs])
    assert np.all(np.diff(tg) == pytest.approx(0.02)) and tg[0] < 5.0 and tg[-1] > 3600.0
    acc = np.concatenate([r[1]["acc"] for r in runs])
    np.testing.assert_allclose(acc, _lin("acc", tg), atol=1e-6)
    assert not any("gyro" in r[1] for r in runs if r[0][0] > 10.0 and r[0][-1] < 3600.0)
    # A clock that jumps forward by more than MAX_JUMP_S is refused, and the grid is left as it was.
    before = g.state()
    with pytest.raises(InputError, match="clock jumps .* forward"):
        g.push(_rec({"acc": t + 3610.0 + MAX_JUMP_S + 1.0, "gyro": t + 3610.0 + MAX_JUMP_S + 1.0}, _lin))
    assert g.state() == before


@pytest.mark.parametrize("cuts", [[], list(np.arange(2.0, 120.0, 2.0))])
def test_a_barometer_at_half_a_hertz_is_bridged_between_its_samples_and_still_stops(cuts):
    # A barometer that reports every 2 s (with 30 ms of jitter): every interval is near MAX_STREAM_GAP_S. Before, about
    # half of its intervals were taken as gaps (54 % of the points had it; at 0.4 Hz, none); its gaps are now measured
    # in its own periods. It stops at 80 s: absent from some 2.5 periods after its last sample.
    rng = np.random.default_rng(0)
    baro_t = np.sort(np.arange(0.3, 80.0, 2.0) + rng.normal(0.0, 0.03, 40))
    rec = Recording({"acc": SensorStream("acc", np.round(np.arange(0.0, 120.0, 0.01) * 1e9).astype(np.int64),
                                         np.zeros((12000, 3))),
                     "baro": SensorStream("baro", np.round(baro_t * 1e9).astype(np.int64), np.full((40, 1), 1000.0))})
    t, v = _feed(OnlineGrid(50.0, ("acc", "baro")), rec, cuts)
    present = ~np.isnan(v["baro"][:, 0])
    assert present[t <= baro_t[-1]].all()
    assert not present[t > baro_t[-1] + 5.5].any()


def test_other_streams_stay_bounded_while_the_accelerometer_has_stopped():
    # The accelerometer stops at 10 s while the gyroscope goes on for 10 minutes in 5 s batches. Before, the gyro's
    # buffer (and the saved state) grew with the session; now it keeps what the accelerometer's points need and its
    # last MAX_LAG_S, and a notice says so once. A recording pushed whole keeps the gyro up to the accelerometer's end.
    t = np.arange(0.0, 610.0, 0.01)
    rec = _rec({"acc": t[t < 10.0], "gyro": t + 0.004}, _lin)
    g = OnlineGrid(50.0, ("acc", "gyro"))
    said, sizes = [], []
    for a in np.arange(0.0, 610.0, 5.0):
        said += g.push(rec.slice_time(a, a + 5.0))
        while g.pull()[0].size:
            pass
        g = OnlineGrid.from_state(g.state())
        sizes.append(g.buf_t["gyro"].size)
    assert len(said) == 1 and said[0].startswith("no accelerometer data since t=9.99 s while the other sensors go on")
    assert max(sizes) <= (MAX_LAG_S + 5.0) * 100 + 10
    whole = OnlineGrid(50.0, ("acc", "gyro"))
    whole.push(rec)
    tg, vals = whole.pull()
    assert tg[-1] == pytest.approx(9.98) and "gyro" in vals
    np.testing.assert_allclose(vals["gyro"], _lin("gyro", tg), atol=1e-9)


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


@pytest.mark.parametrize("cuts", [[], list(np.arange(0.5, 12.0, 1.0)), [5.0, 5.05, 7.5]])
def test_a_short_pause_of_every_stream_is_bridged_and_a_stream_missing_as_long_while_the_primary_goes_on_is_not(cuts):
    # Every stream pauses from about 5.0 to 6.9 s (the joins of a tiled log): the accelerometer's gap is 1.90 s, the
    # barometer's (5 Hz) 2.05 s, over MAX_STREAM_GAP_S only by what it adds to the accelerometer's. It is bridged, as
    # the accelerometer's own gap is. The gyroscope missing as long while the accelerometer goes on has stopped.
    acc_t = np.concatenate([np.arange(0.0, 5.0, 0.01), np.arange(6.9, 12.0, 0.01)])
    baro_t = np.concatenate([np.arange(0.05, 4.9, 0.2), np.arange(6.95, 12.0, 0.2)])
    gyro_t = np.concatenate([np.arange(0.003, 8.0, 0.01), np.arange(10.053, 12.0, 0.01)])
    rec = _rec({"acc": acc_t, "gyro": gyro_t, "baro": baro_t},
               lambda k, t: t[:, None] if k == "baro" else np.column_stack([np.sin(t), np.cos(2 * t), t]))
    assert np.diff(acc_t).max() < MAX_STREAM_GAP_S < np.diff(baro_t).max() < 2 * MAX_STREAM_GAP_S
    t, v = _feed(OnlineGrid(50.0, ("acc", "gyro", "baro")), rec, cuts)
    assert not np.isnan(v["baro"]).any()
    stopped = (t > gyro_t[gyro_t < 8.0][-1]) & (t < 10.053)
    assert stopped.any() and np.isnan(v["gyro"][stopped]).all() and not np.isnan(v["gyro"][~stopped]).any()
    t1, v1 = _feed(OnlineGrid(50.0, ("acc", "gyro", "baro")), rec, [])
    np.testing.assert_array_equal(t, t1)
    for k in v:
        np.testing.assert_array_equal(v[k], v1[k])
