"""pdr.phone.warm_up: the warm-up walk, whose child process runs the pipeline with a stand-in for the attitude filter
so that it compiles every kernel but the filter's (module doc)."""

from __future__ import annotations

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.phone import warm_up as warm
from pdr.phone.attitude import AttitudeFilter


def test_the_stand_in_attitude_turns_each_specific_force_onto_up() -> None:
    rng = np.random.default_rng(3)
    acc = rng.normal(size=(50, 3)) * 3.0 + np.array([0.0, 0.0, 9.81])
    q, used = warm.TiltOnlyAttitude(100.0).run(acc, rng.normal(size=(50, 3)), rng.normal(size=(50, 3)))
    assert q.shape == (50, 4) and q.dtype == np.float64 and q.flags.c_contiguous
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    up = quat.rotate(q, acc / np.linalg.norm(acc, axis=1, keepdims=True))
    assert np.allclose(up, [0.0, 0.0, 1.0], atol=1e-12)
    assert used.shape == (50,) and not used.any()
    empty, none_used = warm.TiltOnlyAttitude(100.0).run(np.zeros((0, 3)))
    assert empty.shape == (0, 4) and none_used.shape == (0,)


def test_the_child_walk_never_calls_the_attitude_filter(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the attitude filter ran")

    monkeypatch.setattr(AttitudeFilter, "run", refuse)
    seen: list[object] = []
    assert warm.warm_up(extra=(seen.append,), attitude_filter=False) > 0.0
    assert len(seen) == 1                                 # each extra is given the walk's recording
    with pytest.raises(AssertionError, match="the attitude filter ran"):
        warm.warm_up(attitude_filter=True)


def test_no_process_alongside_on_one_core_or_when_none_can_start(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warm.os, "cpu_count", lambda: 1)
    assert warm.compile_alongside() is None

    def no_process(*args: object, **kwargs: object) -> None:
        raise OSError("no more processes")

    monkeypatch.setattr(warm.os, "cpu_count", lambda: 2)
    monkeypatch.setattr(warm.subprocess, "Popen", no_process)
    assert warm.compile_alongside() is None


def test_the_child_runs_the_walk_and_says_how_long() -> None:
    child = warm.compile_alongside()
    assert child is not None
    out = warm.wait_alongside(child)
    assert out is not None and child.returncode == 0 and float(out.decode()) > 0.0


def test_a_process_that_outlives_the_wait_is_stopped(monkeypatch: pytest.MonkeyPatch) -> None:
    import subprocess
    import sys

    monkeypatch.setattr(warm, "ALONGSIDE_WAIT_S", 0.2)
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], stdout=subprocess.PIPE)
    assert warm.wait_alongside(sleeper) is None and sleeper.returncode is not None
