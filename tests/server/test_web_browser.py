"""End-to-end tests of the web page in a real headless browser (Debian's chromium driven by Playwright).

The server is the real application on a real HTTP socket (werkzeug, in a thread) with the web test
processor; sessions are seeded as processed results (a 2-hour walk, a foot session with both feet and
the fused track, another user's session) or uploaded through the API (a log with waypoint truth, a live
upload). Screenshots of the main views go under a temporary folder (:func:`tests.server.live_web.shot`).

The whole module takes about 25 s on the shared 2-core machine, so the default run keeps the core
acceptance path (sign in, the 2-hour session drawn within the render budget, downloads) and the other
views are marked ``slow``.

Chromium is installed by the test set-up itself (``apt-get install chromium``, as root) when missing; the
tests skip with the reason when it cannot be.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import statistics
import struct
import time
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pdr.frames import local_enu_to_geodetic
from pdr.phone.track_geojson import DEGREE_DECIMALS
from server.client import Client
from tests.server.helpers import multipart, phone_batch
from tests.server.live_web import LiveApp, shot, sign_in
from tests.server.web_seed import (
    allan_report,
    corridor_walk,
    drifting_compass_walk,
    expected_truth_errors_m,
    seed_session,
    truth_log,
)

LONG_WALK_S = 2 * 3600.0
FIRST_RENDER_LIMIT_MS = 1000.0


TILE_URL = "https://tiles.test/{z}/{x}/{y}.png"
#: Where the seeded geo-referenced session starts (WGS-84 degrees).
GEO_ORIGIN = (49.4521, 11.0767)


class LiveService(LiveApp):
    """The app on a loopback socket (:class:`~tests.server.live_web.LiveApp`, with map tiles configured), with
    seeded sessions."""

    def __init__(self, data_dir: Path) -> None:
        super().__init__(data_dir, map_tile_url=TILE_URL, map_tile_attribution="test tiles")
        svc = self.app.extensions["pdr"]
        store = svc.store
        walk = corridor_walk(LONG_WALK_S)
        self.long_steps = len(walk.t_s)
        self.long_id = seed_session(store, self.tokens["alice"], "corridor-2h", {"phone": walk.rows()},
                                    warnings=("gyro rate 98 Hz differs from the declared 100 Hz",),
                                    landmarks=((600.0, "stairs"), (3000.0, "elevator")))
        short = corridor_walk(300.0, seed=1)
        self.foot_steps = len(short.t_s)
        self.foot_id = seed_session(store, self.tokens["alice"], "shoes-5min",
                                    {"fused": short.rows(), "left_foot": short.rows(-0.12),
                                     "right_foot": short.rows(0.12)}, placement="foot",
                                    meta={"processing": {"foot": {"zaru": True}}})
        self.compass_id = seed_session(store, self.tokens["alice"], "compass-walk", {"phone": drifting_compass_walk()},
                                       placement="hand")
        self.bob_id = seed_session(store, self.tokens["bob"], "bob-secret-walk", {"phone": short.rows()})
        alice = Client(self.url, self.tokens["alice"])
        payload = json.dumps(truth_log()).encode()
        boundary = "pdrtestboundary"
        body = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"truth-walk.json\"\r\n"
                f"Content-Type: application/json\r\n\r\n").encode() + payload + f"\r\n--{boundary}--\r\n".encode()
        reply = alice.request("POST", "/api/v1/sessions", raw=body,
                              content_type=f"multipart/form-data; boundary={boundary}")
        assert reply.status == 201, reply.body
        self.truth_id = reply.json()["id"]
        self.truth_points = len(truth_log()["truth"]["positions"]["t_s"])
        alice.close()
        assert svc.worker.wait_idle(timeout_s=60)


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> Iterator[LiveService]:
    service = LiveService(tmp_path_factory.mktemp("web"))
    yield service
    service.close()


@pytest.fixture
def page(browser: Any, live: LiveService) -> Iterator[Any]:
    context = browser.new_context(viewport={"width": 1360, "height": 1000}, accept_downloads=True)
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    yield pg
    context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


def track_point_counts(page: Any) -> dict[str, Any]:
    """Points drawn on the map: declared per track path, and the paths' actual vertices (Leaflet's SVG: M/L)."""
    return page.evaluate("""() => {
        const lines = [...document.querySelectorAll('#map path[data-role=track]')];
        const byDevice = {};
        for (const l of lines) {
            byDevice[l.dataset.device] = (byDevice[l.dataset.device] || 0) + Number(l.dataset.points);
        }
        return {declared: lines.reduce((a, l) => a + Number(l.dataset.points), 0),
                vertices: lines.reduce((a, l) => a + (l.getAttribute('d').match(/[ML]/g) || []).length, 0),
                lines: lines.length, byDevice,
                total: Number(document.querySelector('#map').dataset.points)};
    }""")


def test_sign_in_list_sessions_and_open_a_long_session(page: Any, live: LiveService) -> None:
    page.goto(live.url + "/")
    page.wait_for_selector("#view-signin:not([hidden])")
    shot(page, "01-sign-in")
    sign_in(page, live)
    rows = page.locator("#sessions-table tbody tr")
    names = rows.locator("td:first-child").all_inner_texts()
    assert set(names) == {"corridor-2h", "shoes-5min", "truth-walk.json", "compass-walk"}
    long_row = page.locator(f"#sessions-table tr[data-session='{live.long_id}']")
    assert long_row.locator("[data-role=steps]").inner_text() == str(live.long_steps)
    assert "1 h 59 min" in long_row.inner_text() and "pocket" in long_row.inner_text()
    assert "1 warning" in long_row.inner_text()
    shot(page, "02-sessions")

    # First render of the 2-hour session, from the click to the drawn track. Three opens (the machine is
    # shared, so a single one measures the neighbours too); the median is printed against the budget.
    paint_ms, wall_ms = [], []
    for attempt in range(3):
        if attempt:  # back to the list, once it and the previous view's requests are all answered
            page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
            with page.expect_response(lambda r: r.url.endswith("/api/v1/sessions")):
                page.goto(f"{live.url}/#/sessions")
            page.wait_for_selector(f"#sessions-table tr[data-session='{live.long_id}']")
        t0 = time.perf_counter()
        page.click(f"#sessions-table tr[data-session='{live.long_id}'] a")
        page.wait_for_function(f"() => document.querySelector('#map').dataset.points === '{live.long_steps}'")
        wall_ms.append((time.perf_counter() - t0) * 1000)
        page.wait_for_function("() => window.pdrPage.timings.firstPaint !== undefined")
        timings = page.evaluate("window.pdrPage.timings")
        paint_ms.append(timings["firstPaint"])
        print(f"\n2-hour session, {live.long_steps} steps, open {attempt + 1}: track fetched and parsed at "
              f"{timings['fetched']:.0f} ms, drawn at {timings['firstRender']:.0f} ms, painted at "
              f"{timings['firstPaint']:.0f} ms (page clock; the map's last draw {timings['mapDrawMs']:.0f} ms); "
              f"{wall_ms[-1]:.0f} ms from the click (test clock)")
    assert live.long_steps >= 10_000
    # The render time is printed, not asserted (a timed check flakes under load); `pdr bench` owns speed.
    print(f"median first paint {statistics.median(paint_ms):.0f} ms, "
          f"from the click {statistics.median(wall_ms):.0f} ms (budget {FIRST_RENDER_LIMIT_MS:.0f} ms)")

    counts = track_point_counts(page)
    assert counts["declared"] == counts["total"] == live.long_steps
    # Polylines split where the motion mode changes share their joint vertex with the previous one.
    assert counts["vertices"] == live.long_steps + counts["lines"] - 1
    assert page.locator("#map path[data-role=marker]").count() == 2  # start and end
    page.wait_for_function("() => document.querySelectorAll('#map path[data-role=landmark]').length === 2")
    modes = set(page.eval_on_selector_all("#map path[data-role=track]", "ls => ls.map(l => l.dataset.mode)"))
    assert modes == {"walking", "standing", "stairs_up"}
    assert page.locator("#timeline .bands rect").count() > 10
    assert page.locator("#steps-plot polyline").count() >= 1
    assert page.locator("#heading-plot polyline").count() > 1  # broken at the 360° wraps
    assert "gyro rate 98 Hz" in page.inner_text("#session-warnings")
    page.wait_for_selector("[data-role=no-truth]")
    shot(page, "03-session-long")

    # Per-floor filter: floor 1 holds the second 20 minutes of each hour.
    page.select_option("#floor-filter", "1")
    on_floor_1 = track_point_counts(page)["total"]
    assert 0 < on_floor_1 < live.long_steps / 2
    page.select_option("#floor-filter", "")
    # Zoom and pan change the view (metres, CRS.Simple), not the drawing.
    view = "window.pdrPage.trackMap.view()"
    before = page.evaluate(view)
    page.click("#zoom-in")
    zoomed = page.evaluate(view)
    box = page.locator("#map").bounding_box()
    page.mouse.move(box["x"] + 300, box["y"] + 200)
    page.mouse.down()
    page.mouse.move(box["x"] + 350, box["y"] + 230, steps=5)
    page.mouse.move(box["x"] + 400, box["y"] + 260, steps=5)
    page.mouse.up()
    page.wait_for_function(f"() => {view}[0] !== {zoomed[0]!r}")
    after = page.evaluate(view)
    assert zoomed[2] - zoomed[0] == pytest.approx((before[2] - before[0]) / 1.5, rel=1e-3)
    assert after[2] - after[0] == pytest.approx(zoomed[2] - zoomed[0], rel=1e-6)
    assert after[0] < zoomed[0] and after[3] > zoomed[3]  # dragged right and down: the view moved west and north
    assert track_point_counts(page)["total"] == live.long_steps


def test_csv_and_geojson_downloads(page: Any, live: LiveService) -> None:
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.foot_id}")
    page.wait_for_function(f"() => document.querySelector('#map').dataset.points === '{3 * live.foot_steps}'")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    assert page.is_hidden("#dl-geojson")  # local metres: no longitude and latitude to download
    with page.expect_download() as info:
        page.click("#dl-csv")
    download = info.value
    assert download.suggested_filename == f"{live.foot_id}.csv"
    text = Path(download.path()).read_text()
    table = list(csv.reader(io.StringIO(text)))
    assert table[0] == ["t_s", "east_m", "north_m", "up_m", "floor", "heading_deg", "step_length_m", "mode", "device"]
    assert len(table) == 1 + 3 * live.foot_steps
    assert sorted({row[-1] for row in table[1:]}) == ["fused", "left_foot", "right_foot"]
    # GeoJSON (RFC 7946) is lon/lat: only for a geo-referenced session (the API answers 409 otherwise)
    from tests.geojson_rfc7946 import check_rfc7946

    store = live.app.extensions["pdr"].store
    store.set_session(live.foot_id, origin_lat_deg=51.5, origin_lon_deg=-0.12)
    try:
        page.reload()
        page.wait_for_selector("#dl-geojson:visible")
        with page.expect_download() as info:
            page.click("#dl-geojson")
        geo = json.loads(Path(info.value.path()).read_text())
    finally:
        store.set_session(live.foot_id, origin_lat_deg=None, origin_lon_deg=None)
    check_rfc7946(geo)
    assert sorted(f["properties"]["device"] for f in geo["features"]) == ["fused", "left_foot", "right_foot"]


def test_a_finished_session_shows_the_smoothed_track_and_can_show_it_as_streamed(page: Any, live: LiveService
                                                                                  ) -> None:
    alice = Client(live.url, live.tokens["alice"])
    url = f"/api/v1/sessions/{live.compass_id}/track"
    smoothed = alice.request("GET", url + "?heading=smoothed").json()["points"]
    causal = alice.request("GET", url).json()["points"]
    alice.close()
    end = {name: [rows[-1]["east_m"], rows[-1]["north_m"]] for name, rows in (("smoothed", smoothed),
                                                                              ("causal", causal))}
    assert math.dist(end["smoothed"], end["causal"]) > 2.0  # the seeded compass disturbance, smoothed out
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.compass_id}")
    # By default the page ends on the track `pdr track` writes: headings smoothed over the walk.
    page.wait_for_function("() => window.pdrPage.track && window.pdrPage.track.heading === 'smoothed'")
    assert page.evaluate("window.pdrPage.track.last") == pytest.approx(end["smoothed"], abs=1e-9)
    assert page.input_value("#heading-mode") == "smoothed"
    assert "heading smoothed over" in page.inner_text("#session-summary [data-role=heading]")
    assert track_point_counts(page)["total"] == len(smoothed)
    with page.expect_download() as info:
        page.click("#dl-csv")
    table = list(csv.reader(io.StringIO(Path(info.value.path()).read_text())))
    assert [float(v) for v in table[-1][1:3]] == pytest.approx(end["smoothed"], abs=1e-9)
    shot(page, "06-session-smoothed")
    # As streamed: the rows the service computed step by step, and the download follows.
    page.select_option("#heading-mode", "causal")
    page.wait_for_function("() => window.pdrPage.track.heading === 'causal'")
    assert page.evaluate("window.pdrPage.track.last") == pytest.approx(end["causal"], abs=1e-9)
    assert page.inner_text("#session-summary [data-role=heading]") == "Heading: as streamed"
    with page.expect_download() as info:
        page.click("#dl-csv")
    table = list(csv.reader(io.StringIO(Path(info.value.path()).read_text())))
    assert [float(v) for v in table[-1][1:3]] == pytest.approx(end["causal"], abs=1e-9)
    page.select_option("#heading-mode", "smoothed")
    page.wait_for_function("() => window.pdrPage.track.heading === 'smoothed'")


@pytest.mark.slow
def test_foot_session_shows_both_feet_and_the_fused_track(page: Any, live: LiveService) -> None:
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.foot_id}")
    page.wait_for_function(f"() => document.querySelector('#map').dataset.points === '{3 * live.foot_steps}'")
    counts = track_point_counts(page)
    assert counts["byDevice"] == {"fused": live.foot_steps, "left_foot": live.foot_steps,
                                  "right_foot": live.foot_steps}
    assert page.locator("#map path.foot").count() >= 2  # the single feet are drawn dashed
    assert page.input_value("#colour-by") == "device"
    assert set(page.locator("#legend .item").all_inner_texts()) >= {"fused", "left_foot", "right_foot"}
    assert page.inner_text("#session-summary [data-role=processing]") == (
        "Processing: gyro bias by zero angular-rate updates")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    assert page.inner_text("#session-summary [data-role=heading]") == (
        "Heading: from the shoe IMUs (smoothing applies to phone tracks)")
    assert page.is_disabled("#heading-mode")
    shot(page, "04-session-feet")


@pytest.mark.slow
def test_truth_and_error_are_shown_for_an_uploaded_log(page: Any, live: LiveService) -> None:
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.truth_id}")
    page.wait_for_selector("[data-role=truth-stats]")
    stats = page.inner_text("[data-role=truth-stats]")
    assert f"{live.truth_points} (waypoint)" in stats
    # As pdr eval scores it: the track starts at the first truth point, the errors are those of points 2..K.
    errors = expected_truth_errors_m(live.truth_points)
    assert f"({len(errors)} later points)" in stats
    assert f"mean: {statistics.mean(errors):g} m" in stats and f"max: {max(errors):g} m" in stats
    assert "starts at the first truth point (0 s)" in stats
    lines = page.evaluate("window.pdrPage.trackMap.lines")
    first = next(line["xy"][0] for line in lines if line["role"] == "track")
    truth = next(line["xy"][0] for line in lines if line["role"] == "truth")
    assert first == pytest.approx(truth, abs=0.01)  # the lead row before the first truth point is not drawn
    # ... and drawn there: both paths start at the same pixel.
    starts = page.evaluate("""() => ['track', 'truth'].map(r => document.querySelector(`#map path[data-role=${r}]`)
        .getAttribute('d').match(/^M(-?[0-9.]+) (-?[0-9.]+)/).slice(1).map(Number))""")
    assert starts[0] == pytest.approx(starts[1], abs=1.0)
    assert page.locator("#map path[data-role=truth]").count() == 1
    assert page.locator("#map path[data-role=truth-point]").count() == live.truth_points
    assert page.locator("#error-plot polyline").count() == 1
    # The test processor's rows carry none of the smoother's inputs: the page says so and draws them as streamed.
    heading = page.inner_text("#session-summary [data-role=heading]")
    assert heading.startswith("Heading: as streamed (phone: heading not smoothed: the smoother needs")
    shot(page, "05-session-truth")


@pytest.mark.slow
def test_another_users_data_is_not_reachable(page: Any, live: LiveService) -> None:
    sign_in(page, live)
    assert "bob-secret-walk" not in page.content()
    page.goto(f"{live.url}/#/session/{live.bob_id}")
    page.wait_for_selector("#message:not([hidden])")
    message = page.inner_text("#message")
    assert message == f"Could not open the session: no session '{live.bob_id}' (HTTP 404, not_found)"
    assert "bob-secret-walk" not in page.content()
    assert page.evaluate("document.querySelector('#map').childElementCount") == 0
    assert not page.is_visible("#session-body")
    shot(page, "06-other-users-session")
    # The token stays in this tab's session storage: not in the URL, local storage or cookies.
    token = live.tokens["alice"]
    assert token not in page.url
    assert page.evaluate("JSON.stringify(localStorage)") == "{}"
    assert page.evaluate("document.cookie") == ""
    assert page.evaluate("sessionStorage.getItem('pdr.token')") == token
    # Signing out forgets the token and every row shown.
    page.goto(f"{live.url}/#/sessions")
    page.wait_for_selector("#sessions-table tbody tr")
    page.click("#sign-out")
    page.wait_for_selector("#view-signin:not([hidden])")
    assert page.evaluate("sessionStorage.length") == 0
    assert page.locator("#sessions-table tbody tr").count() == 0
    assert "corridor-2h" not in page.content()


@pytest.mark.slow
def test_a_bad_token_gets_a_readable_message(page: Any, live: LiveService) -> None:
    page.goto(live.url + "/")
    page.fill("#token", "pdr_not-a-real-token")
    page.click("#signin-form button[type=submit]")
    page.wait_for_selector("#message:not([hidden])")
    assert page.inner_text("#message") == ("Your token was not accepted: invalid, expired or revoked API token "
                                           "(HTTP 401, unauthorized)")
    assert page.evaluate("sessionStorage.length") == 0
    assert page.is_visible("#view-signin")
    shot(page, "07-bad-token")


def test_a_session_is_deleted_from_its_page(page: Any, live: LiveService) -> None:
    alice = Client(live.url, live.tokens["alice"])
    sid = alice.request("POST", "/api/v1/sessions", {"session_id": "to-delete", "name": "to-delete"}).json()["id"]
    assert alice.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch("b0", 0.0)).status == 201
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{sid}")
    page.wait_for_function("() => document.querySelector('#session-title').textContent === 'to-delete'")
    page.once("dialog", lambda dialog: dialog.accept())
    page.click("#delete-session")
    page.wait_for_function("() => location.hash === '#/sessions'")
    # The list shown before is redrawn once the service answers: wait for the deleted row to go.
    page.wait_for_selector(f"#sessions-table tr[data-session='{sid}']", state="detached")
    assert page.inner_text("#message") == "Session \"to-delete\" deleted."
    assert page.locator("#sessions-table tbody tr").count() > 0
    shot(page, "21-session-deleted")
    assert alice.request("GET", f"/api/v1/sessions/{sid}").status == 404
    alice.close()


@pytest.mark.slow
def test_sessions_update_live_while_uploading(page: Any, live: LiveService) -> None:
    alice = Client(live.url, live.tokens["alice"])
    reply = alice.request("POST", "/api/v1/sessions", {"session_id": "live-upload", "name": "live-upload",
                                                       "placement": "hand"})
    sid = reply.json()["id"]
    sign_in(page, live)
    row = page.locator(f"#sessions-table tr[data-session='{sid}']")
    row.wait_for()
    for k in range(3):
        assert alice.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch(f"b{k}", float(k))).status == 201
    steps_cell = f"#sessions-table tr[data-session='{sid}'] [data-role=steps]"
    page.wait_for_function(f"() => document.querySelector(\"{steps_cell}\")?.textContent === '3'")
    # The session view appends what arrives later (?device=&since= polling) without reloading.
    page.goto(f"{live.url}/#/session/{sid}")
    page.wait_for_function("() => document.querySelector('#map').dataset.points === '3'")
    for k in range(3, 6):
        assert alice.request("POST", f"/api/v1/sessions/{sid}/batches", phone_batch(f"b{k}", float(k))).status == 201
    page.wait_for_function("() => document.querySelector('#map').dataset.points === '6'", timeout=15000)
    assert page.inner_text("#session-summary [data-role=steps]") == "Steps: 6"
    alice.close()


@pytest.mark.slow
def test_reports_and_models_say_when_they_are_not_available(page: Any, live: LiveService) -> None:
    """A server without the report and model endpoints (its routing 404) gets a readable 'not available'."""
    def missing(route: Any) -> None:
        route.fulfill(status=404, content_type="application/json", body=json.dumps(
            {"error": {"status": 404, "code": "not_found", "message": "The requested URL was not found on the "
                       "server.", "details": {}}}))

    page.route("**/api/v1/reports**", missing)
    page.route("**/api/v1/models**", missing)
    sign_in(page, live)
    for view, text in (("reports", "Allan reports are not available on this server"),
                       ("models", "Model cards are not available on this server")):
        page.click(f"#nav a[data-view={view}]")
        page.wait_for_selector(f"#view-{view} [data-role=not-available]:text('{text}')")
        shot(page, f"08-{view}-not-available")


def _png_1x1() -> bytes:
    """The smallest valid PNG: one grey pixel."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00\x80")) + chunk(b"IEND", b""))


@pytest.mark.slow
def test_allan_report_renders_from_the_api(page: Any, live: LiveService) -> None:
    """The report view on the API's answers (GET /api/v1/reports, /reports/ID, /reports/ID/files/NAME), answered
    in the browser with a real ``pdr.allan`` report of a synthetic record."""
    report_id = "r-1"
    report = allan_report()
    listing = {"reports": [{"id": report_id, "kind": "allan", "status": "done", "source": "static.csv",
                            "created_at": "2026-01-01T00:00:00+00:00", "error": None}]}
    detail = {"id": report_id, "kind": "allan", "status": "done", "source": "static.csv", "error": None,
              "created_at": "2026-01-01T00:00:00+00:00",
              "files": ["gyro.png", "report.html", "report.json", "temperature.png"],
              "report": report}
    answers: dict[str, tuple[str, bytes]] = {
        "/api/v1/reports": ("application/json", json.dumps(listing).encode()),
        f"/api/v1/reports/{report_id}": ("application/json", json.dumps(detail).encode()),
        f"/api/v1/reports/{report_id}/files/report.html": ("text/html", b"<html><body>Allan report</body></html>"),
        f"/api/v1/reports/{report_id}/files/gyro.png": ("image/png", _png_1x1()),
        f"/api/v1/reports/{report_id}/files/temperature.png": ("image/png", _png_1x1()),
    }
    seen_auth: list[str] = []

    def fulfil(route: Any) -> None:
        path = "/" + route.request.url.split("://", 1)[1].split("/", 1)[1].split("?")[0]
        seen_auth.append(route.request.headers.get("authorization", ""))
        media, body = answers[path]
        route.fulfill(status=200, content_type=media, body=body)

    page.route("**/api/v1/reports**", fulfil)
    sign_in(page, live)
    page.click("#nav a[data-view=reports]")
    assert page.inner_text(f"#reports-body a[href='#/report/{report_id}']") == "static.csv"
    page.click(f"#reports-body a[href='#/report/{report_id}']")
    page.wait_for_selector("svg.loglog[data-sensor=acc]")
    # Titled by the recording, not the report's id.
    assert page.inner_text("#report-title") == "Allan report: static.csv"
    n_tau = len(report["gyro"]["tau_s"])
    for sensor in ("gyro", "acc"):
        series = page.eval_on_selector_all(f"svg.loglog[data-sensor={sensor}] polyline[data-series]",
                                           "ls => ls.map(l => [l.dataset.series, l.points.numberOfItems])")
        assert series == [["x", n_tau], ["y", n_tau], ["z", n_tau]]
    text = page.inner_text("#report-body")
    assert f"{report['gyro']['x']['N']:.3e}".replace("e-0", "e-") in text
    assert "not resolved" in text  # the short record cannot resolve every term
    assert "Predicted PDR impact" in text
    # The grade table names the axis of every call and cites the paper, not the project's seed number.
    grade_rows = page.eval_on_selector_all("#report-body table.grade tbody tr",
                                           "rs => rs.map(r => [...r.cells].map(c => c.textContent))")
    calls = report["gyro"]["grade"]["calls"] + report["acc"]["grade"]["calls"]
    assert [r[:2] for r in grade_rows] == [[c["axis"], c["parameter"].replace("_", " ")] for c in calls]
    assert {r[0] for r in grade_rows} == {"x", "y", "z"}
    assert "Collin" in text and "Handbook of Signal Processing Systems" in text and "seed 004" not in text
    # The IMU is not a phone: the reader's default role is not shown as one.
    assert "role standalone IMU" in text and "role phone" not in text
    # Each plot once: the sensor's curves are drawn by the page, so its PNG (the same plot) is not added.
    # (a plot of something else, here "temperature.png", is still shown: once it is there, the loop is done)
    page.wait_for_selector("#report-body img.report-png[alt='temperature.png']")
    assert page.locator("#report-body img.report-png").count() == 1
    assert page.locator("svg.loglog[data-sensor=gyro]").count() == 1
    shot(page, "09-allan-report")
    # A phone's width: the curves are drawn again at the new size (their labels keep their size on screen).
    drawn_width = "(s) => Number(s.getAttribute('viewBox').split(' ')[2]) === s.clientWidth"
    page.set_viewport_size({"width": 390, "height": 844})
    page.wait_for_function(f"() => [...document.querySelectorAll('svg.loglog')].every({drawn_width})")
    assert not _overlapping_labels(page, ("svg.loglog[data-sensor=gyro]",))
    assert page.evaluate("""() => [...document.querySelectorAll('svg.loglog')].every(s => {
        const t = s.querySelector('text.title').getBoundingClientRect(), b = s.getBoundingClientRect();
        return t.left >= b.left && t.right <= b.right; })""")  # the title is not cut off
    shot(page, "09b-allan-report-phone")
    page.set_viewport_size({"width": 1360, "height": 1000})
    with page.expect_download() as info:
        page.click("#dl-report-html")
    assert Path(info.value.path()).read_text() == "<html><body>Allan report</body></html>"
    assert info.value.suggested_filename == "allan-report-static.html"
    assert seen_auth and all(a == f"Bearer {live.tokens['alice']}" for a in seen_auth)


def _outside_view(page: Any) -> dict[str, int]:
    """Vertices of the map's lines (track and truth) outside its view (both in metres)."""
    return page.evaluate("""() => {
        const m = window.pdrPage.trackMap;
        const [w, s, e, n] = m.view();
        let count = 0, out = 0;
        for (const line of m.lines) {
            for (const [x, y] of line.xy) {
                count++;
                if (x < w || x > e || y < s || y > n) out++;
            }
        }
        return {n: count, out};
    }""")


def _overlapping_labels(page: Any, charts: tuple[str, ...]) -> list[Any]:
    """Pairs of text labels of the charts whose boxes overlap on screen."""
    found = []
    for chart in charts:
        boxes = page.evaluate(f"""() => [...document.querySelectorAll('{chart} text')].map(t => {{
            const b = t.getBoundingClientRect(); return [b.left, b.top, b.right, b.bottom, t.textContent]; }})""")
        for i, a in enumerate(boxes):
            for b in boxes[i + 1:]:
                if min(a[2], b[2]) - max(a[0], b[0]) > 0.5 and min(a[3], b[3]) - max(a[1], b[1]) > 0.5:
                    found.append((chart, a, b))
    return found


def _stop_walk(live: LiveService) -> tuple[str, float, float]:
    """A seeded walk with a 40 s stop in the middle (no steps); returns its id, the stop's start and its end (s)."""
    walk = corridor_walk(120.0, seed=3)
    rows = walk.rows()
    half = len(rows) // 2
    stop_s = 40.0
    moved = [dataclasses.replace(r, t_s=r.t_s + stop_s) if k >= half else r for k, r in enumerate(rows)]
    sid = seed_session(live.app.extensions["pdr"].store, live.tokens["alice"], "stop-40s", {"phone": moved})
    return sid, moved[half - 1].t_s, moved[half].t_s


def test_map_fits_on_load_and_charts_break_at_stops(page: Any, live: LiveService) -> None:
    """The map shows the whole track once everything is loaded (the smoothed track replaces the streamed one
    after the first fit); the step-length and heading charts draw no line across a 40 s stop."""
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.compass_id}")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined && "
                           "window.pdrPage.track.heading === 'smoothed'")
    seen = _outside_view(page)
    assert seen["n"] > 100 and seen["out"] == 0
    shot(page, "11-map-fit-on-load")
    # A pan is kept when more rows arrive; Fit brings the whole track back.
    page.click("#zoom-in")
    page.click("#zoom-in")
    assert _outside_view(page)["out"] > 0
    page.click("#zoom-reset")
    assert _outside_view(page)["out"] == 0

    sid, stop_t0, stop_t1 = _stop_walk(live)
    page.goto(f"{live.url}/#/sessions/{sid}")  # the plural form opens the session too
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    assert page.inner_text("#session-title") == "stop-40s"
    for chart in ("#steps-plot", "#heading-plot"):
        spans = page.evaluate(f"""() => {{
            const svg = document.querySelector('{chart}');
            return [...svg.querySelectorAll('polyline[data-series]')].map(l => {{
                const xs = [];
                for (let i = 0; i < l.points.numberOfItems; i++) xs.push(l.points.getItem(i).x);
                return xs;
            }});
        }}""")
        width = page.evaluate(f"document.querySelector('{chart}').clientWidth")
        # The stop takes 40 s of the walk's 160 s: about a quarter of the plot; no segment may be that wide.
        widest = max(b - a for xs in spans for a, b in zip(xs, xs[1:], strict=False))
        assert widest < 0.1 * width, (chart, widest, width)
        assert len(spans) >= 2
    assert stop_t1 - stop_t0 > 39.0
    shot(page, "12-charts-break-at-a-stop")


def _tick_labels(page: Any, chart: str) -> list[tuple[float, str]]:
    return page.evaluate(f"""() => [...document.querySelectorAll('{chart} text[text-anchor=middle]')]
        .map(t => [Math.round(Number(t.getAttribute('x'))), t.textContent])""")


@pytest.mark.slow
def test_every_chart_is_on_the_sessions_time_axis(page: Any, live: LiveService) -> None:
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.truth_id}")
    page.wait_for_selector("#error-plot polyline")
    steps = _tick_labels(page, "#steps-plot")
    assert steps and _tick_labels(page, "#error-plot") == steps == _tick_labels(page, "#heading-plot")
    shot(page, "22-charts-on-the-session-time-axis")


def test_charts_and_map_are_redrawn_when_the_window_is_resized(page: Any, live: LiveService) -> None:
    """A phone turned or a window resized: the charts are drawn again at their new width, so their labels keep
    their size on screen and stay apart, and the map fits the track into its new box."""
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.truth_id}")
    page.wait_for_selector("#error-plot polyline")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    charts = ("#timeline", "#steps-plot", "#heading-plot", "#error-plot")
    label_height = "() => document.querySelector('#steps-plot text').getBoundingClientRect().height"
    before = page.evaluate(label_height)
    drawn_width = "(c) => Number(document.querySelector(c).getAttribute('viewBox').split(' ')[2])"
    assert all(page.evaluate(f"() => ({drawn_width})('{c}')") > 1000 for c in charts)
    page.set_viewport_size({"width": 390, "height": 844})
    page.wait_for_function(f"() => {list(charts)!r}.every(c => "
                           f"({drawn_width})(c) === document.querySelector(c).clientWidth)")
    assert page.evaluate(label_height) == pytest.approx(before, rel=0.1)  # not shrunk with the chart
    assert not _overlapping_labels(page, charts)
    seen = _outside_view(page)
    assert seen["n"] > 0 and seen["out"] == 0
    assert page.evaluate("document.documentElement.scrollWidth") <= 390
    shot(page, "24-session-after-resize")


def test_models_page_shows_model_cards(page: Any, live: LiveService) -> None:
    """The installed models (../models) as model cards; the fitted internals only behind a download."""
    models_dir = Path(__file__).resolve().parents[2] / "models"
    names = sorted(d.name for d in models_dir.iterdir() if (d / "model.json").is_file())
    sign_in(page, live)
    page.click("#nav a[data-view=models]")
    page.wait_for_selector(".card[data-model]")
    assert sorted(page.eval_on_selector_all(".card[data-model]", "cs => cs.map(c => c.dataset.model)")) == names
    card = page.locator(".card[data-model=motion_mode]")
    text = card.inner_text()
    doc = json.loads((models_dir / "motion_mode" / "model.json").read_text())
    for expected in ("Task", "motion_mode", "Classes", "Training data", "Features", "Versions", "Date",
                     f"{len(doc['feature_names'])} features", "Protocol: leave-one-group-out",
                     "macro F1", "Recordings"):
        assert expected in text, expected
    assert all(c in text for c in doc["classes"])
    # The page stays short (the raw dump was 290 000 px tall) and nothing sticks out of its card.
    height = page.evaluate("document.documentElement.scrollHeight")
    assert height < 3000, height
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    shot(page, "10-models")
    with page.expect_download() as info:
        card.locator("[data-role=download-model]").click()
    assert info.value.suggested_filename == "motion_mode.model.json"
    assert json.loads(Path(info.value.path()).read_text()) == doc


@pytest.mark.slow
def test_the_page_is_usable_at_phone_width(browser: Any, live: LiveService) -> None:
    """390 px wide (a phone): no sideways scrolling, time labels apart, the whole track in the map."""
    context = browser.new_context(viewport={"width": 390, "height": 844}, accept_downloads=True)
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        sign_in(pg, live)
        assert pg.evaluate("document.documentElement.scrollWidth") <= 390
        shot(pg, "13-phone-sessions")
        pg.goto(f"{live.url}/#/session/{live.long_id}")
        pg.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
        assert pg.evaluate("document.documentElement.scrollWidth") <= 390
        box = pg.locator("#map").bounding_box()
        assert box["x"] >= 0 and box["x"] + box["width"] <= 390
        assert _outside_view(pg)["out"] == 0
        assert not _overlapping_labels(pg, ("#timeline", "#steps-plot", "#heading-plot"))
        shot(pg, "14-phone-session")
        pg.click("#nav a[data-view=models]")
        pg.wait_for_selector(".card[data-model]")
        assert pg.evaluate("document.documentElement.scrollWidth") <= 390
        shot(pg, "15-phone-models")
    finally:
        context.close()
    assert not errors, errors


@pytest.mark.slow
def test_an_allan_report_is_deleted_from_its_page(page: Any, live: LiveService) -> None:
    """A real report (uploaded, computed by the service) opened from the list and deleted with its button."""
    from tests.server.test_models_reports import _static_npz

    alice = Client(live.url, live.tokens["alice"])
    body, ctype = multipart({"file": (_static_npz(seconds=60.0), "bench-static.npz")})
    reply = alice.request("POST", "/api/v1/reports/allan", raw=body, content_type=ctype)
    assert reply.status == 202, reply.body
    rid = reply.json()["id"]
    deadline = time.monotonic() + 120
    while alice.request("GET", f"/api/v1/reports/{rid}").json()["status"] == "pending":
        assert time.monotonic() < deadline
        time.sleep(0.3)
    sign_in(page, live)
    page.click("#nav a[data-view=reports]")
    page.click(f"#reports-body a[href='#/report/{rid}']")
    page.wait_for_function("() => document.querySelector('#report-title').textContent === "
                           "'Allan report: bench-static.npz'")
    shot(page, "16-report-before-delete")
    page.once("dialog", lambda dialog: dialog.accept())
    page.click("#delete-report")
    page.wait_for_function("() => location.hash === '#/reports'")
    page.wait_for_selector(f"#reports-body a[href='#/report/{rid}']", state="detached")
    assert "Report \"bench-static.npz\" deleted." in page.inner_text("#message")
    shot(page, "17-report-deleted")
    assert alice.request("GET", f"/api/v1/reports/{rid}").status == 404
    alice.close()


def test_a_geo_referenced_session_is_drawn_on_a_real_map(page: Any, live: LiveService) -> None:
    """Leaflet (vendored from npm) over the configured tile server, the track in longitude/latitude from the API,
    fitted, with start and end markers; a session in local metres gets no such map."""
    walk = corridor_walk(120.0, seed=4)
    store = live.app.extensions["pdr"].store
    sid = seed_session(store, live.tokens["alice"], "geo-walk", {"phone": walk.rows()}, placement="hand")
    store.set_session(sid, origin_lat_deg=GEO_ORIGIN[0], origin_lon_deg=GEO_ORIGIN[1])
    tiles: list[str] = []

    def tile(route: Any) -> None:
        tiles.append(route.request.url)
        route.fulfill(status=200, content_type="image/png", body=_png_1x1())

    page.route("https://tiles.test/**", tile)
    sign_in(page, live)
    page.goto(f"{live.url}/#/sessions/{sid}")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    assert page.is_hidden("#message"), page.inner_text("#message")
    page.wait_for_function("() => document.querySelector('#geomap').dataset.features === '1'")
    assert page.get_attribute("#geomap", "data-points") == str(len(walk.t_s))
    assert page.get_attribute("#geomap", "data-tiles") == "yes"
    page.wait_for_function("() => document.querySelectorAll('#geomap img.leaflet-tile-loaded').length > 0")
    assert tiles and all(t.startswith("https://tiles.test/") and t.endswith(".png") for t in tiles)
    assert "test tiles" in page.inner_text("#geomap .leaflet-control-attribution")
    # The track is fitted inside the map, and drawn once with its start and end markers.
    box = page.locator("#geomap").bounding_box()
    line = page.locator("#geomap path.leaflet-interactive").first.bounding_box()
    assert box is not None and line is not None
    assert box["x"] <= line["x"] and line["x"] + line["width"] <= box["x"] + box["width"] + 1
    assert box["y"] <= line["y"] and line["y"] + line["height"] <= box["y"] + box["height"] + 1
    assert line["width"] > 0.3 * box["width"] or line["height"] > 0.3 * box["height"]
    assert page.locator("#geomap path.geo-start").count() == 1 and page.locator("#geomap path.geo-end").count() == 1
    # The start marker is where the API's GeoJSON starts: the first step, placed about the session's origin.
    # (RFC 7946 output keeps DEGREE_DECIMALS decimals, about a centimetre.)
    lat, lon = local_enu_to_geodetic(walk.east_m[0], walk.north_m[0], *GEO_ORIGIN)
    assert page.evaluate("window.pdrPage.geo.start") == pytest.approx(
        [round(float(lat), DEGREE_DECIMALS), round(float(lon), DEGREE_DECIMALS)], abs=1e-12)
    assert f"{GEO_ORIGIN[0]:.6f}°, {GEO_ORIGIN[1]:.6f}°" in page.inner_text("#geo-note")
    # The page's policy lets the browser fetch tiles from the configured host only.
    csp = page.evaluate("fetch('/').then(r => r.headers.get('content-security-policy'))")
    assert "img-src 'self' blob: data: https://tiles.test;" in csp
    shot(page, "18-geo-session")
    # At phone width the map fits the screen, and the track is fitted into the narrower map again.
    page.set_viewport_size({"width": 390, "height": 844})
    page.wait_for_function("""() => {
        const m = document.querySelector('#geomap').getBoundingClientRect();
        const l = document.querySelector('#geomap path.leaflet-interactive').getBoundingClientRect();
        return m.width <= 390 && l.left >= m.left && l.right <= m.right + 1; }""")
    assert page.evaluate("document.documentElement.scrollWidth") <= 390
    box = page.locator("#geomap").bounding_box()
    assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= 390
    shot(page, "18b-geo-session-phone")
    # A session in local metres: the metric map only.
    page.goto(f"{live.url}/#/session/{live.compass_id}")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    assert page.is_hidden("#geo-wrap")


@pytest.mark.slow
def test_a_sensor_logger_push_with_a_location_is_drawn_on_the_real_map(page: Any, live: LiveService) -> None:
    """A real client end to end: Sensor Logger's HTTP push with a ``location`` reading geo-references the session
    (its first fix is the origin), so the page draws the track on the real map and offers the GeoJSON."""
    from pdr.io.sensor_logger_writer import to_push_messages
    from pdr.recording import DeviceInfo, Recording, SensorStream

    t = 1_700_000_000_000_000_000 + np.arange(150, dtype=np.int64) * 20_000_000
    rec = Recording({"acc": SensorStream("acc", t, np.tile([0.0, 0.0, 9.81], (t.size, 1))),
                     "gyro": SensorStream("gyro", t, np.zeros((t.size, 3)))}, DeviceInfo(platform="android"))
    messages = to_push_messages(rec, session_id="sl-geo", device_id="pixel-geo", period_s=1.0)
    fix = (48.8584, 2.2945)
    messages[0]["payload"].append({"name": "location", "time": messages[0]["payload"][0]["time"],
                                   "values": {"latitude": fix[0], "longitude": fix[1], "altitude": 35.0,
                                              "horizontalAccuracy": 4.0}})
    alice = Client(live.url, live.tokens["alice"])
    for m in messages:
        reply = alice.request("POST", f"/api/v1/ingest/sensor-logger?token={live.tokens['alice']}", m)
        assert reply.status == 200, reply.body
    assert live.app.extensions["pdr"].worker.wait_idle(timeout_s=60)
    sid = next(s["id"] for s in alice.request("GET", "/api/v1/sessions").json()["sessions"]
               if s["session_id"] == "sl-geo")
    alice.close()
    page.route("https://tiles.test/**", lambda route: route.fulfill(status=200, content_type="image/png",
                                                                      body=_png_1x1()))
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{sid}")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
    page.wait_for_function("() => document.querySelector('#geomap').dataset.features === '1'")
    assert page.get_attribute("#map", "data-points") == page.get_attribute("#geomap", "data-points") == "3"
    # The test processor's first step is 0.7 m east of the session's start: on the map, next to the fix.
    lat, lon = local_enu_to_geodetic(0.7, 0.0, *fix)
    assert page.evaluate("window.pdrPage.geo.start") == pytest.approx([float(lat), float(lon)], abs=1e-6)
    assert f"{fix[0]:.6f}°, {fix[1]:.6f}°" in page.inner_text("#geo-note")
    assert page.is_visible("#dl-geojson")
    shot(page, "25-sensor-logger-location-on-the-map")


@pytest.mark.slow
@pytest.mark.data
def test_the_pages_error_on_a_real_log_is_the_scorers(browser: Any, tmp_path_factory: pytest.TempPathFactory
                                                       ) -> None:
    """A real IPIN log uploaded to the service with its real processors: the mean error the page shows is the mean of
    ``pdr.evaluation.scoring.landmark_errors`` (what ``pdr eval ipin`` reports percentiles of) on the track the page
    draws, scored against the truth the page draws."""
    from pdr.evaluation.scoring import landmark_errors
    from tests.conftest import data_path

    log = data_path("ipin2023_t3", "logfiles") / "IPIN2023_T3_TrainingTrial22_repetition01.txt"
    service = LiveApp(tmp_path_factory.mktemp("web-real"), users=("alice",), processor_factory=None)
    context = browser.new_context(viewport={"width": 1360, "height": 1000})
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        alice = Client(service.url, service.tokens["alice"])
        body, ctype = multipart({"file": (log.read_bytes(), log.name)})
        reply = alice.request("POST", "/api/v1/sessions", raw=body, content_type=ctype)
        assert reply.status == 201, reply.body
        sid = reply.json()["id"]
        assert service.app.extensions["pdr"].worker.wait_idle(timeout_s=300)
        sign_in(pg, service)
        pg.goto(f"{service.url}/#/session/{sid}")
        pg.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
        heading = pg.evaluate("window.pdrPage.track.heading")
        stats = pg.inner_text("[data-role=truth-stats]")
        shot(pg, "19-real-ipin-truth")
        points = alice.request("GET", f"/api/v1/sessions/{sid}/track?heading={heading}").json()["points"]
        truth = alice.request("GET", f"/api/v1/sessions/{sid}/truth").json()["truth"]
        alice.close()
    finally:
        context.close()
        service.close()
    assert not errors, errors
    pts = sorted((p for s in truth for p in s.get("points", [])), key=lambda p: p["t_s"])
    t = np.array([p["t_s"] for p in points])
    en = np.array([[p["east_m"], p["north_m"]] for p in points])
    tt = np.array([p["t_s"] for p in pts])
    gt = np.array([[p["east_m"], p["north_m"]] for p in pts])
    e = landmark_errors(t, en, tt, gt, "none")
    print(f"\n{log.name}: page '{stats}'; scorer mean {e.mean():.2f} m over {e.size} points "
          f"(track {t[0]:.1f}-{t[-1]:.1f} s, truth {tt[0]:.1f}-{tt[-1]:.1f} s, heading {heading})")
    assert f"({e.size} later points)" in stats
    # The page's number format (plot.js fmt): two decimals, trailing zeros dropped (0.90 shows as 0.9).
    assert f"mean: {f'{e.mean():.2f}'.rstrip('0').rstrip('.')} m" in stats


def test_truth_beyond_the_tracks_ends_is_scored_as_the_scorer_does(page: Any, live: LiveService) -> None:
    """Truth points before the first step and after the last one: the page takes the track's first and last
    positions there (numpy's interp in ``landmark_errors``), so its mean error is still ``pdr eval``'s."""
    from pdr.evaluation.scoring import landmark_errors

    alice = Client(live.url, live.tokens["alice"])
    rows = alice.request("GET", f"/api/v1/sessions/{live.compass_id}/track?heading=smoothed").json()["points"]
    alice.close()
    t = np.array([r["t_s"] for r in rows])
    en = np.array([[r["east_m"], r["north_m"]] for r in rows])
    tt = np.arange(t[0] - 10.0, t[-1] + 30.0, 20.0)   # from 10 s before the first step to past the last
    gt = np.column_stack([3.0 + 0.5 * tt, 2.0 - 0.2 * tt])
    answer = {"session": live.compass_id, "count": len(tt), "truth": [{
        "batch_id": "seed", "device": "phone", "kind": "landmark", "frame": "enu", "t0_ns": 0, "origin": None,
        "error": None, "points": [{"t_s": float(a), "east_m": float(e), "north_m": float(n), "up_m": 0.0, "floor": 0.0}
                                  for a, (e, n) in zip(tt, gt, strict=True)]}]}
    page.route(f"**/api/v1/sessions/{live.compass_id}/truth",
               lambda route: route.fulfill(status=200, content_type="application/json", body=json.dumps(answer)))
    sign_in(page, live)
    page.goto(f"{live.url}/#/session/{live.compass_id}")
    page.wait_for_function("() => window.pdrPage.timings.complete !== undefined && "
                           "window.pdrPage.track.heading === 'smoothed'")
    stats = page.inner_text("[data-role=truth-stats]")
    e = landmark_errors(t, en, tt, gt, "none")
    assert tt[0] < t[0] and tt[-1] > t[-1]
    assert f"({e.size} later points)" in stats and f"mean: {e.mean():.2f} m" in stats, (stats, e.mean())
    assert "starts at the first truth point (-10 s)" in stats
    shot(page, "23-truth-beyond-the-track")
