"""The page's server side without a browser: the served files and their headers, and the truth endpoint."""

from __future__ import annotations

import hashlib
import io
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from flask import Flask
from flask.testing import FlaskClient

from tests.server.conftest import bearer, make_app
from tests.server.web_seed import WebTestProcessor, truth_log, truth_offset_m


@pytest.fixture
def app(tmp_path: Path) -> Iterator[Flask]:
    """The shared ``app`` fixture with the web tests' processor (``client`` and ``tokens`` come from conftest)."""
    app = make_app(tmp_path, processor_factory=WebTestProcessor)
    yield app
    app.extensions["pdr"].worker.stop()


def test_page_is_served_without_authentication_and_holds_no_data(client: FlaskClient) -> None:
    with client.get("/") as resp:
        html = resp.get_data(as_text=True)
    assert resp.status_code == 200
    assert resp.mimetype == "text/html"
    assert '<script src="/web/app.js"' in html and "<script>" not in html  # no inline script
    csp = resp.headers["Content-Security-Policy"]
    assert "script-src 'self'" in csp and "frame-ancestors 'none'" in csp
    assert resp.headers["Referrer-Policy"] == "no-referrer"
    for asset, mime in (("/web/app.js", "text/javascript"), ("/web/plot.js", "text/javascript"),
                        ("/web/trackmap.js", "text/javascript"), ("/web/app.css", "text/css")):
        with client.get(asset) as r:
            r.get_data()
        assert r.status_code == 200, asset
        assert r.mimetype == mime
        assert r.headers["X-Content-Type-Options"] == "nosniff"


STATIC = Path(__file__).resolve().parents[2] / "server" / "web" / "static"


def test_page_references_only_its_own_origin() -> None:
    for f in STATIC.iterdir():
        if not f.is_file():
            continue  # vendor/: third-party files, checked against their record below
        text = f.read_text()
        assert "http://" not in text.replace("http://www.w3.org/2000/svg", ""), f.name
        assert "https://" not in text, f.name
        assert "innerHTML" not in text, f.name  # server text only ever goes through textContent


def test_unknown_asset_is_a_json_404(client: FlaskClient) -> None:
    resp = client.get("/web/nope.js")
    assert resp.status_code == 404
    assert resp.get_json()["error"]["code"] == "not_found"


def _upload_truth_log(client: FlaskClient, token: str) -> str:
    payload = json.dumps(truth_log()).encode()
    resp = client.post("/api/v1/sessions", headers=bearer(token),
                       data={"file": (io.BytesIO(payload), "walk.json")},
                       content_type="multipart/form-data")
    assert resp.status_code == 201, resp.get_json()
    sid: str = resp.get_json()["id"]
    return sid


def test_truth_of_an_uploaded_log_is_served_on_the_track_time_axis(app: Flask, client: FlaskClient,
                                                                   tokens: dict[str, str]) -> None:
    sid = _upload_truth_log(client, tokens["alice"])
    assert app.extensions["pdr"].worker.wait_idle(timeout_s=30)
    body = client.get(f"/api/v1/sessions/{sid}/truth", headers=bearer(tokens["alice"])).get_json()
    expected = truth_log()["truth"]["positions"]
    assert body["count"] == len(expected["t_s"]) == 12
    (truth_set,) = body["truth"]
    assert truth_set["kind"] == "waypoint" and truth_set["frame"] == "enu" and truth_set["error"] is None
    assert [p["t_s"] for p in truth_set["points"]] == expected["t_s"]
    track = client.get(f"/api/v1/sessions/{sid}/track", headers=bearer(tokens["alice"])).get_json()["points"]
    # The test processor's track is the truth shifted by truth_offset_m(k) at the same times: same time axis.
    by_t = {p["t_s"]: p for p in track}
    for k, p in enumerate(truth_set["points"]):
        assert by_t[p["t_s"]]["east_m"] == pytest.approx(p["east_m"] + truth_offset_m(k)[0])
        assert by_t[p["t_s"]]["north_m"] == pytest.approx(p["north_m"] + truth_offset_m(k)[1])
    # Answered again from the cache, identically.
    again = client.get(f"/api/v1/sessions/{sid}/truth", headers=bearer(tokens["alice"])).get_json()
    assert again == body


def test_truth_is_empty_for_streamed_sessions(client: FlaskClient, tokens: dict[str, str]) -> None:
    sid = client.post("/api/v1/sessions", headers=bearer(tokens["alice"]), json={"session_id": "s"}).get_json()["id"]
    body = client.get(f"/api/v1/sessions/{sid}/truth", headers=bearer(tokens["alice"])).get_json()
    assert {k: body[k] for k in ("session", "truth", "count")} == {"session": sid, "truth": [], "count": 0}
    assert set(body) == {"session", "truth", "count", "clock"} and "t0_ns" in body["clock"]


def test_truth_of_another_users_session_is_not_found(client: FlaskClient, tokens: dict[str, str]) -> None:
    sid = _upload_truth_log(client, tokens["alice"])
    resp = client.get(f"/api/v1/sessions/{sid}/truth", headers=bearer(tokens["bob"]))
    assert resp.status_code == 404
    assert resp.get_json()["error"]["message"] == f"no session '{sid}'"
    assert client.get(f"/api/v1/sessions/{sid}/truth").status_code == 401


def test_track_columns_match_the_track_rows(app: Flask, client: FlaskClient, tokens: dict[str, str]) -> None:
    sid = _upload_truth_log(client, tokens["alice"])
    assert app.extensions["pdr"].worker.wait_idle(timeout_s=30)
    h = bearer(tokens["alice"])
    rows = client.get(f"/api/v1/sessions/{sid}/track", headers=h).get_json()["points"]
    body = client.get(f"/api/v1/sessions/{sid}/track/columns", headers=h).get_json()
    cols = body["columns"]
    assert body["count"] == len(rows) == 13  # a row before the first of the 12 truth points, then one at each
    assert [dict(zip(cols, values, strict=True)) for values in zip(*cols.values(), strict=True)] == rows
    assert body["next_since"] == rows[-1]["t_s"]
    later = client.get(f"/api/v1/sessions/{sid}/track/columns?since={rows[5]['t_s']}&device=phone",
                           headers=h).get_json()
    assert later["columns"]["t_s"] == [r["t_s"] for r in rows[6:]]
    empty = client.get(f"/api/v1/sessions/{sid}/track/columns?device=left_foot", headers=h).get_json()
    assert empty["count"] == 0 and empty["columns"]["t_s"] == [] and empty["next_since"] is None


def test_track_columns_errors(client: FlaskClient, tokens: dict[str, str]) -> None:
    sid = _upload_truth_log(client, tokens["alice"])
    bad = client.get(f"/api/v1/sessions/{sid}/track/columns?since=soon", headers=bearer(tokens["alice"]))
    assert bad.status_code == 400 and "'since' must be a number" in bad.get_json()["error"]["message"]
    assert client.get(f"/api/v1/sessions/{sid}/track/columns", headers=bearer(tokens["bob"])).status_code == 404
    assert client.get(f"/api/v1/sessions/{sid}/track/columns").status_code == 401


def test_vendored_leaflet_is_the_recorded_npm_release_with_its_licence() -> None:
    folder = STATIC / "vendor" / "leaflet"
    record = (folder / "VENDORED.md").read_text()
    assert "leaflet@1.9.4" in record and "BSD 2-Clause" in record
    assert (folder / "LICENSE").read_text().startswith("BSD 2-Clause License")
    files = sorted([*folder.glob("*.js"), *folder.glob("*.css"), *folder.glob("images/*.png")])
    assert {f.name for f in files} >= {"leaflet.js", "leaflet.css", "marker-icon.png"}
    for f in files:
        assert f"`{f.relative_to(folder).as_posix()}`: `{hashlib.sha256(f.read_bytes()).hexdigest()}`" in record, f


def test_map_tiles_come_only_from_the_configured_server(tmp_path: Path) -> None:
    """Without PDR_MAP_TILE_URL the page loads no image from elsewhere; with it, its host only, and the page's
    configuration names the template and attribution; a malformed template is refused at start-up."""
    plain = make_app(tmp_path / "plain", processor_factory=WebTestProcessor)
    tiled = make_app(tmp_path / "tiled", processor_factory=WebTestProcessor,
                     map_tile_url="https://{s}.tiles.example.org/osm/{z}/{x}/{y}.png", map_tile_attribution="© OSM")
    try:
        with plain.test_client() as c:
            csp = c.get("/").headers["Content-Security-Policy"]
            assert "img-src 'self' blob: data:;" in csp
            assert c.get("/web/config.json").get_json() == {"map": {"tile_url": None, "attribution": None}}
            with c.get("/web/vendor/leaflet/leaflet.js") as r:
                assert r.status_code == 200 and r.mimetype == "text/javascript" and len(r.get_data()) > 100_000
        with tiled.test_client() as c:
            csp = c.get("/").headers["Content-Security-Policy"]
            assert "img-src 'self' blob: data: https://*.tiles.example.org;" in csp
            assert c.get("/web/config.json").get_json() == {"map": {
                "tile_url": "https://{s}.tiles.example.org/osm/{z}/{x}/{y}.png", "attribution": "© OSM"}}
    finally:
        plain.extensions["pdr"].worker.stop()
        tiled.extensions["pdr"].worker.stop()
    for bad in ("tiles.example.org/{z}/{x}/{y}.png", "https://tiles.example.org/{z}/{x}.png", "ftp://h/{z}/{x}/{y}"):
        with pytest.raises(ValueError, match="PDR_MAP_TILE_URL must be an http"):
            make_app(tmp_path / "bad", processor_factory=WebTestProcessor, map_tile_url=bad)
