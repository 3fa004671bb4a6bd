"""Incremental polling of a session's modes: ``?after=SEQ`` gets entries stored with a time in the past."""

from __future__ import annotations

from flask import Flask
from flask.testing import FlaskClient

from server.store import EventRow
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


def test_a_bad_after_is_a_400_naming_the_field(client: FlaskClient, tokens: dict[str, str], app: Flask) -> None:
    sid = seed_session(app.extensions["pdr"].store, tokens["alice"], "walk", {"phone": []})
    for bad in ("abc", "-1", "1.5"):
        resp = client.get(f"/api/v1/sessions/{sid}/landmarks?after={bad}", headers=bearer(tokens["alice"]))
        assert resp.status_code == 400
        assert "'after'" in resp.get_json()["error"]["message"]
