"""server.warmup_walk: the warm-up's child process runs the phone path with a stand-in for the attitude filter, so it
compiles every kernel but the filter's; server.warmup: a child that cannot start or fails leaves the warm-up whole
(server.warmup module doc)."""

from __future__ import annotations

import numpy as np
import pytest

import pdr.filters.compiled
from pdr import quaternion as quat
from pdr.phone.attitude import AttitudeFilter
from server import warmup
from server.warmup_walk import TiltOnlyAttitude, warm_up


def test_the_stand_in_attitude_turns_each_specific_force_onto_up() -> None:
    rng = np.random.default_rng(3)
    acc = rng.normal(size=(50, 3)) * 3.0 + np.array([0.0, 0.0, 9.81])
    q, used = TiltOnlyAttitude(100.0).run(acc, rng.normal(size=(50, 3)), rng.normal(size=(50, 3)))
    assert q.shape == (50, 4) and q.dtype == np.float64 and q.flags.c_contiguous
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    up = quat.rotate(q, acc / np.linalg.norm(acc, axis=1, keepdims=True))
    assert np.allclose(up, [0.0, 0.0, 1.0], atol=1e-12)
    assert used.shape == (50,) and not used.any()
    empty, none_used = TiltOnlyAttitude(100.0).run(np.zeros((0, 3)))
    assert empty.shape == (0, 4) and none_used.shape == (0,)


def test_the_child_walk_never_calls_the_attitude_filter(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the attitude filter ran")

    monkeypatch.setattr(AttitudeFilter, "run", refuse)
    assert warm_up(extra=(), attitude_filter=False) > 0.0
    with pytest.raises(AssertionError, match="the attitude filter ran"):
        warm_up(extra=(), attitude_filter=True)


def _cold_start(monkeypatch: pytest.MonkeyPatch) -> dict[str, object]:
    """:func:`warmup.start` as on a fresh cache (a child is wanted), to its end; its status."""
    monkeypatch.setattr(pdr.filters.compiled, "is_cached", lambda kernel: False)
    warmup.start().join()
    return warmup.status()


def test_a_child_that_cannot_start_leaves_the_warm_up_to_this_process(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_process(*args: object, **kwargs: object) -> None:
        raise OSError("no more processes")

    monkeypatch.setattr(warmup.subprocess, "Popen", no_process)
    status = _cold_start(monkeypatch)
    assert status["state"] == "ready" and status["error"] is None and status["helper"] is None
    assert isinstance(status["seconds"], float)


def test_a_failed_child_is_reported_and_the_warm_up_still_ends_ready(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(warmup, "HELPER_MODULE", "server.no_such_warm_up_module")
    status = _cold_start(monkeypatch)
    assert status["state"] == "ready" and status["error"] is None
    helper = status["helper"]
    assert isinstance(helper, dict) and helper["exit"] == 1
    assert "No module named server.no_such_warm_up_module" in helper["error"]
