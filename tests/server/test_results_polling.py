"""Incremental polling of a session's results: ``?after=SEQ`` gets entries stored with a time in the past."""

from __future__ import annotations

import pytest
from flask import Flask
from flask.testing import FlaskClient

from server.store import EventRow, TrackRow
from tests.server.conftest import bearer
from tests.server.web_seed import seed_session


def _modes(client: FlaskClient, token: str, sid: str, query: str = "") -> dict:
    resp = client.get(f"/api/v1/sessions/{sid}/modes{query}", headers=bearer(token))
    assert resp.status_code == 200, resp.get_json()
    return resp.get_json()


def test_a_stop_stored_after_the_poll_but_dated_before_it_reaches_an_after_poller(
        app: Flask, client: FlaskClient, tokens: dict[str, str]) -> None:
    store = app.extensions["pdr"].store
    token = tokens["alice"]
    sid = seed_session(store, token, "walk", {"phone": []})
    store.commit_results(sid, "phone", None, b"{}", None, [], [EventRow("mode", 0.0, 10.0, "walking")])
    first = _modes(client, token, sid)
    assert [m["label"] for m in first["modes"]] == ["walking"] and first["next_since"] == 0.0
    # The next batch ends a stop that began at 4 s (stored now, dated then) and walks on from 10 s.
    store.commit_results(sid, "phone", None, b"{}", None, [],
                         [EventRow("mode", 4.0, 8.0, "standing"), EventRow("mode", 10.0, 14.0, "walking")])
    by_time = _modes(client, token, sid, "?since=0.0")
    assert [m["label"] for m in by_time["modes"]] == ["standing", "walking"]
    assert _modes(client, token, sid, f"?since={by_time['next_since']}")["count"] == 0
    by_seq = _modes(client, token, sid, f"?after={first['next_after']}")
    assert [(m["label"], m["t_s"]) for m in by_seq["modes"]] == [("standing", 4.0), ("walking", 10.0)]
    assert by_seq["next_after"] == max(m["seq"] for m in by_seq["modes"]) > first["next_after"]
    # Nothing new: the same cursor comes back, and an empty session answers null.
    again = _modes(client, token, sid, f"?after={by_seq['next_after']}")
    assert again["count"] == 0 and again["next_after"] == by_seq["next_after"]
    empty = seed_session(store, token, "empty", {"phone": []})
    assert _modes(client, token, empty)["next_after"] is None


@pytest.mark.parametrize("route", ["landmarks", "track", "steps"])
def test_a_bad_after_is_a_400_naming_the_field(client: FlaskClient, tokens: dict[str, str], app: Flask,
                                              route: str) -> None:
    sid = seed_session(app.extensions["pdr"].store, tokens["alice"], "walk", {"phone": []})
    for bad in ("abc", "-1", "1.5", str(2**31)):
        resp = client.get(f"/api/v1/sessions/{sid}/{route}?after={bad}", headers=bearer(tokens["alice"]))
        assert resp.status_code == 400, resp.get_json()
        error = resp.get_json()["error"]
        assert "'after'" in error["message"] and error["details"]["field"] == "after"


def _steps(t0_s: float, n: int) -> list[TrackRow]:
    return [TrackRow(t0_s + i, float(i), 0.0, 0.0, 0.0, 90.0, 0.7, "walking") for i in range(n)]


@pytest.mark.parametrize("route", ["track", "track/columns", "steps"])
def test_a_shoe_file_uploaded_after_the_walk_reaches_an_after_poller_of_the_track_and_steps(
        app: Flask, client: FlaskClient, tokens: dict[str, str], route: str) -> None:
    """The track and steps ignored ``?after=`` (every row answered) where modes, landmarks and floors honour it; a
    poller using ``since`` misses rows stored late but dated earlier, as a shoe's steps uploaded after the phone's.
    The track's columns (the web page's form of it) take ``?after=`` too."""
    store = app.extensions["pdr"].store
    token, key = tokens["alice"], "points" if route == "track" else "steps"

    def rows(answer: dict) -> list[tuple[str, float]]:
        """(device, t_s) of an answer's rows, in its order."""
        if route == "track/columns":
            return list(zip(answer["columns"]["device"], answer["columns"]["t_s"], strict=True))
        return [(r["device"], r["t_s"]) for r in answer[key]]

    def poll(query: str = "") -> dict:
        resp = client.get(f"/api/v1/sessions/{sid}/{route}{query}", headers=bearer(token))
        assert resp.status_code == 200, resp.get_json()
        return resp.get_json()

    sid = seed_session(store, token, "walk", {"phone": _steps(0.0, 10)})
    first = poll()
    assert first["count"] == 10 and isinstance(first["next_after"], int)
    store.commit_results(sid, "left_foot", None, b"{}", None, _steps(2.0, 3), [])   # dated 2-4 s, stored now
    store.commit_results(sid, "phone", None, b"{}", None, _steps(10.0, 2), [])
    assert [t for _, t in rows(poll(f"?since={first['next_since']}"))] == [10.0, 11.0]
    late = poll(f"?after={first['next_after']}")
    expected = [("left_foot", 2.0), ("left_foot", 3.0), ("left_foot", 4.0), ("phone", 10.0), ("phone", 11.0)]
    assert sorted(rows(late)) == expected
    assert late["next_after"] > first["next_after"]
    again = poll(f"?after={late['next_after']}")
    assert again["count"] == 0 and again["next_after"] == late["next_after"]
    if route != "steps":   # the smoothed track: the same rows, smoothed over the whole session
        smoothed = poll(f"?after={first['next_after']}&heading=smoothed")
        assert sorted(rows(smoothed)) == expected
        assert smoothed["next_after"] == late["next_after"]
