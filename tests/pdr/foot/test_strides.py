"""Strides told from the zero-velocity flags (pdr.foot.strides): a stance broken by a short motion is one stride, and
the step-wise navigation's resets while the foot stands close no stride."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pdr.foot.online import OnlineFootNavigator
from pdr.foot.strides import SwingsSinceReset, stance_onsets
from pdr.io import read_recording
from tests.conftest import data_path
from tests.pdr.foot.test_online import chunks, gait_recording, run_online

RATE_HZ = 200.0


def _flags(runs: list[tuple[int, int]]) -> np.ndarray:
    return np.concatenate([np.full(n, bool(v)) for v, n in runs])


def test_resets_while_standing_close_no_stride() -> None:
    # Stand 2 s (a reset at 1 s), swing 0.4 s (a reset at its start), stance 0.5 s broken by a 0.05 s roll, swing
    # 0.4 s (a reset at its start), stand 2.5 s (resets at 1 s and 2 s into it).
    zv = _flags([(1, 400), (0, 80), (1, 40), (0, 10), (1, 50), (0, 80), (1, 500)])
    t = np.arange(zv.size) / RATE_HZ
    resets = [200, 400, 580, 860, 1060]
    assert SwingsSinceReset().update(zv, t, resets) == [False, False, True, True, False]
    # The same in pieces, each call's sample 0 being the last sample of the one before (whatever flag it is given).
    counter, got, start = SwingsSinceReset(), [], 0
    for stop in (150, 401, 420, 600, 700, zv.size):
        part = zv[start:stop + 1].copy() if stop < zv.size else zv[start:].copy()
        part[0] = False
        got += counter.update(part, t[start:start + part.size], [r - start for r in resets if start < r <= stop])
        start = stop
    assert got == [False, False, True, True, False]
    assert stance_onsets(zv, t).tolist() == [480, 660]


def test_walk_with_stands_in_random_chunks_flags_the_same_resets_as_one_batch() -> None:
    rec = gait_recording()
    nav = OnlineFootNavigator()
    whole = nav.update(rec) + nav.finish()
    steps, _, _ = run_online(chunks(rec, np.random.default_rng(7), 0.01, 2.5), restore=True)
    assert [s.stride for s in steps] == [s.stride for s in whole]
    # The simulated walk: 12 strides from a stand. Its first reset opens the first swing (no stride behind it), the
    # last stride ends the recording with no reset after it: the end closes it.
    assert [s.stride for s in whole] == [False] + [True] * 12


def test_the_last_stride_is_closed_by_the_end_once_whatever_the_batches() -> None:
    """A recording that ends while the foot stands after its last swing: no reset closes that stride (Algorithm 1
    resets at the end of a stance, or c_max_s into it), so it was never counted (11 of the walk's 12). The end now
    closes it with a step at the last sample. A session shows it in its provisional tail (finish on a copy), which
    the next batch replaces: at every batch the steps so far and the tail count each stride once."""
    rec = gait_recording()
    nav, committed, counts = OnlineFootNavigator(), [], []
    for part in chunks(rec, np.random.default_rng(11), 0.2, 1.5):
        committed += nav.update(part)
        nav = OnlineFootNavigator.from_dict(json.loads(json.dumps(nav.to_dict())))
        tail = OnlineFootNavigator.from_dict(nav.to_dict()).finish()
        counts.append(sum(s.stride for s in committed + tail))
    assert sum(s.stride for s in committed) == 11          # no reset closes the 12th stride
    end = nav.finish()
    assert [s.stride for s in end] == [True] and end[0].t_s == pytest.approx(rec.time_span_s()[1] + rec.origin_ns / 1e9)
    assert counts == sorted(counts) and counts[-1] == 12 == sum(s.stride for s in committed + end)
    # The batch navigation closes it too: the last step at the last sample, where the track is.
    from pdr.foot.navigate import navigate
    _, track = navigate(rec, "stepwise")
    assert track.step_strides == (False,) + (True,) * 12 and track.steps[-1].index == track.t_s.size - 1
    np.testing.assert_allclose(end[0].pos_n, track.pos_n[-1], atol=1e-9)
    assert nav.finish() == []                                # closed once


def test_a_state_saved_before_strides_were_told_resumes() -> None:
    rec = gait_recording()
    parts = chunks(rec, np.random.default_rng(3), 0.5, 2.0)
    nav = OnlineFootNavigator()
    for part in parts[:3]:
        nav.update(part)
    old = json.loads(json.dumps(nav.to_dict()))
    del old["swings"]
    resumed = OnlineFootNavigator.from_dict(old)
    steps = [s for part in parts[3:] for s in resumed.update(part)] + resumed.finish()
    assert steps and all(isinstance(s.stride, bool) for s in steps)



def test_pdr_foot_per_step_rows_say_which_resets_are_strides(tmp_path: Path) -> None:
    """``pdr foot LOG --method stepwise --per-step``: its rows are the resets, stands included, as the session's
    track; column ``stride`` says which close a stride (0: a reset while the foot stands, mode ``standing`` in the
    session, left out of its step count), the flags the online navigator gives. The CSV had no such column."""
    import csv

    from pdr.cli import main
    from pdr.io import native

    rec = gait_recording()
    log, out = native.write(rec, tmp_path / "walk"), tmp_path / "steps.csv"
    assert main(["foot", str(log), "--method", "stepwise", "--per-step", "--out", str(out)]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    nav = OnlineFootNavigator()
    online = nav.update(rec) + nav.finish()
    assert [int(r["stride"]) for r in rows] == [int(s.stride) for s in online] == [0] + [1] * 12
    np.testing.assert_allclose([float(r["east_m"]) for r in rows], [s.pos_n[0] for s in online], atol=1e-6)

def _llio_walks() -> list[tuple[str, Path, int]]:
    """(name, log, strides) of the stride-indexed walks whose log is in ../shared/data (one row per stride end
    after the start's)."""
    out = []
    pyshoe, own = data_path("pyshoe_vicon"), data_path("foot_stride_gcp", "own")
    for f in sorted(data_path("foot_stride_gcp", "LLIO_training_data").glob("*.csv")):
        name = f.name.split("_strideIndex")[0]
        logs = [p for p in (pyshoe / f"{name}.mat", own / f"{name}.csv") if p.exists()]
        if logs:
            out.append((name, logs[0], len(f.read_text().splitlines()) - 2))
    return out


@pytest.mark.data
@pytest.mark.slow
def test_strides_of_the_stride_indexed_walks() -> None:
    """Every stride of the 26 walks, the last one too when the recording ends within a stand's reset interval of its
    last stance (no reset closes it: the end does; 9 walks were one short). Counting the resets was right on 3
    (2018-02-09-11-29-43: 51 resets for 33 strides)."""
    walks = _llio_walks()
    assert len(walks) == 26
    for name, log, truth in walks:
        nav = OnlineFootNavigator()
        steps = nav.update(read_recording(log)) + nav.finish()
        assert sum(s.stride for s in steps) == truth, name
