"""server.warmup_walk: the warm-up's child process runs the phone path with a stand-in for the attitude filter, so it
compiles every kernel but the filter's (server.warmup module doc)."""

from __future__ import annotations

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.phone.attitude import AttitudeFilter
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
