"""OnlineGrid: the uniform grid on the log clock, linear interpolation, batch independence, flush and state."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.phone.grid import OnlineGrid
from pdr.recording import Recording, SensorStream


def _rec(t_s: dict[str, np.ndarray], fn) -> Recording:
    return Recording({k: SensorStream(k, np.round(t * 1e9).astype(np.int64), fn(k, t)) for k, t in t_s.items()})


def _lin(kind: str, t: np.ndarray) -> np.ndarray:
    # A linear signal per stream: interpolation onto the grid is exact.
    a = {"acc": 1.0, "gyro": -2.0}[kind]
    return np.column_stack([a * t + 0.5, 3.0 * t, np.full(t.size, a)])


def _feed(grid: OnlineGrid, rec: Recording, cuts: list[float]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    ts: list[np.ndarray] = []
    vs: dict[str, list[np.ndarray]] = {k: [] for k in grid.kinds}
    edges = [-np.inf, *cuts, np.inf]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        part = Recording({k: SensorStream(k, s.t_ns[(s.t_ns / 1e9 >= a) & (s.t_ns / 1e9 < b)],
                                          s.values[(s.t_ns / 1e9 >= a) & (s.t_ns / 1e9 < b)])
                          for k, s in rec.streams.items()})
        grid.push(part)
        t, v = grid.pull()
        _keep(ts, vs, t, v)
        grid = OnlineGrid.from_state(grid.state())     # resumed after every batch
    _keep(ts, vs, *grid.flush())
    return np.concatenate(ts), {k: np.concatenate(vs[k]) for k in grid.kinds}


def _keep(ts: list, vs: dict, t: np.ndarray, v: dict[str, np.ndarray]) -> None:
    if t.size:
        ts.append(t)
        for k, x in v.items():
            vs[k].append(x)


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
