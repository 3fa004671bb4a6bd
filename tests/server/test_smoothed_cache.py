"""``?heading=smoothed`` is computed once per version of a session's results: new batches and a reprocessing
give a new version, repeated requests (and other ``since``) reuse the smoothed track."""

from __future__ import annotations

import pytest

from server.api import results
from tests.server.conftest import bearer
from tests.server.helpers import phone_batch


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = results._smoothed

    def counting(points):  # noqa: ANN001, ANN202
        calls.append(len(points))
        return real(points)

    monkeypatch.setattr(results, "_smoothed", counting)
    results._SMOOTHED.clear()
    return calls


def test_smoothed_track_is_cached_per_results_version(app, client, tokens, counted):
    h = bearer(tokens["alice"])
    sid = client.post("/api/v1/sessions", json={"session_id": "walk-1"}, headers=h).get_json()["id"]
    url = f"/api/v1/sessions/{sid}/track?heading=smoothed"
    for i in range(3):
        assert client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch(f"b{i}", float(i)),
                           headers=h).status_code == 201
    app.extensions["pdr"].worker.wait_idle()
    first = client.get(url, headers=h).get_json()
    again = client.get(url, headers=h).get_json()
    assert first == again and first["count"] == 3 and counted == [3]
    later = client.get(url + f"&since={first['points'][0]['t_s']}", headers=h).get_json()
    assert later["points"] == first["points"][1:] and counted == [3]          # since: the same cached track
    columns = client.get(f"/api/v1/sessions/{sid}/track/columns?heading=smoothed", headers=h).get_json()
    assert columns["count"] == 3 and counted == [3]
    # A new batch: a new version, smoothed again with the new row.
    assert client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b3", 3.0), headers=h).status_code == 201
    app.extensions["pdr"].worker.wait_idle()
    grown = client.get(url, headers=h).get_json()
    assert grown["count"] == 4 and counted == [3, 4]
    assert grown["points"][:3] == first["points"]
    # Reprocessing replaces every row (same content here, stored anew: next_after moves on): a new version again.
    assert client.post(f"/api/v1/sessions/{sid}/reprocess", headers=h).status_code == 202
    app.extensions["pdr"].worker.wait_idle()
    rebuilt = client.get(url, headers=h).get_json()
    assert rebuilt | {"next_after": grown["next_after"]} == grown and counted == [3, 4, 4]
    assert rebuilt["next_after"] > grown["next_after"]
    # The causal track never goes through the cache.
    assert client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["count"] == 4 and len(counted) == 3


def test_cache_keeps_a_bounded_number_of_tracks(app, client, tokens, counted):
    h = bearer(tokens["alice"])
    for k in range(results.SMOOTHED_CACHE_SIZE + 2):
        sid = client.post("/api/v1/sessions", json={"session_id": f"walk-{k}"}, headers=h).get_json()["id"]
        client.post(f"/api/v1/sessions/{sid}/batches", json=phone_batch("b0", 0.0), headers=h)
        app.extensions["pdr"].worker.wait_idle()
        assert client.get(f"/api/v1/sessions/{sid}/track?heading=smoothed", headers=h).status_code == 200
    assert len(results._SMOOTHED) == results.SMOOTHED_CACHE_SIZE
