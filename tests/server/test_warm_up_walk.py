"""server.warmup: a warm-up child that cannot start or fails leaves the warm-up whole (server.warmup module doc); the
child's walk (server.warmup_walk) also warms the reader and the classifier."""

from __future__ import annotations

import pytest

import pdr.filters.compiled
from server import warmup, warmup_walk


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


def test_the_services_child_walk_also_reads_and_classifies(monkeypatch: pytest.MonkeyPatch) -> None:
    ran: list[str] = []
    monkeypatch.setattr(warmup_walk, "warm_reader", lambda rec: ran.append("reader"))
    monkeypatch.setattr(warmup_walk, "warm_classifier", lambda rec: ran.append("classifier"))
    assert warmup_walk.warm_up(attitude_filter=False) > 0.0
    assert ran == ["reader", "classifier"]
