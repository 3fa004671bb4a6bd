"""The floor plan on the web page's session map, in a real headless browser (the live service of live_web.py): the
walkable area of the current floor drawn under a map-matched track, with its holes, at phone width (390 px)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from server.client import Client
from server.site_store import SiteStore
from server.store import TrackRow
from tests.server.live_web import LiveApp, shot, sign_in
from tests.server.test_sites_api import HALL
from tests.server.web_seed import seed_session, user_id

START = [5.0, 6.0, 0]


def _hall_walk() -> list[TrackRow]:
    """East along the hall's floor 0 at 1.2 m/s for 40 steps, then 30 steps back west on floor 1."""
    rows = [TrackRow(0.6 * k, 5.0 + 0.7 * k, 6.0, 0.0, 0.0, 90.0, 0.7, "walking") for k in range(40)]
    rows += [TrackRow(30.0 + 0.6 * k, 32.0 - 0.7 * k, 4.0, 3.5, 1.0, 270.0, 0.7, "walking") for k in range(30)]
    return rows


class SiteService(LiveApp):
    """The app on a loopback socket with alice's uploaded hall and two sessions: map-matched on it, and not."""

    def __init__(self, data_dir: Path) -> None:
        super().__init__(data_dir, users=("alice",))
        self.token = self.tokens["alice"]
        store = self.store
        client = Client(self.url, self.token)
        reply = client.request("POST", "/api/v1/sites", HALL)
        assert reply.status == 201, reply.body
        site_id = reply.json()["id"]
        client.close()
        sites = SiteStore(store.engine)
        self.matched = seed_session(store, self.token, "hall-walk", {"phone": _hall_walk()}, placement="hand",
                                    meta={"processing": {"site_id": site_id, "start": START}})
        sites.set_session_site(self.matched, sites.document(site_id, user_id(store, self.token)))
        self.plain = seed_session(store, self.token, "floors-only", {"phone": _hall_walk()}, placement="hand",
                                  meta={"processing": {"site_id": site_id}})
        sites.set_session_site(self.plain, sites.document(site_id, user_id(store, self.token)))


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> Iterator[SiteService]:
    s = SiteService(tmp_path_factory.mktemp("web-sites"))
    yield s
    s.close()


def test_the_floor_plan_is_drawn_under_the_track_at_phone_width(browser: Any, service: SiteService) -> None:
    context = browser.new_context(viewport={"width": 390, "height": 844})
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        sign_in(pg, service)
        pg.goto(f"{service.url}/#/session/{service.matched}")
        pg.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
        plan = pg.locator("#map path[data-role=floor-plan]")
        # The current floor: the walk ends on floor 1. One polygon: its outer ring and the shop's hole.
        assert plan.get_attribute("data-floor") == "1" and plan.get_attribute("data-rings") == "2"
        # Under the track: drawn before the first track polyline.
        assert pg.evaluate("""() => {
            const p = document.querySelector('#map path[data-role=floor-plan]');
            const t = document.querySelector('#map path[data-role=track]');
            return Boolean(p.compareDocumentPosition(t) & Node.DOCUMENT_POSITION_FOLLOWING); }""")
        # Walkable where the hall is, not in the shop (east, north in metres; drawn in Leaflet's layer points).
        inside = pg.evaluate("""() => {
            const p = document.querySelector('#map path[data-role=floor-plan]');
            const at = (e, n) => p.isPointInFill(new DOMPoint(...window.pdrPage.trackMap.toLayerPoint(e, n)));
            return [at(5, 5), at(15, 15), at(70, 5)]; }""")
        assert inside == [True, False, False]
        assert "walkable area, floor 1" in pg.inner_text("#legend")
        assert "map-matched from (5, 6) m on floor 0" in pg.inner_text("#session-summary")
        assert pg.evaluate("document.documentElement.scrollWidth") <= 390
        box = pg.locator("#map").bounding_box()
        assert box["x"] >= 0 and box["x"] + box["width"] <= 390
        shot(pg, "20-phone-floor-plan")
        # Choosing a floor draws that floor's plan under that floor's part of the track.
        pg.select_option("#floor-filter", "0")
        assert pg.locator("#map path[data-role=floor-plan]").get_attribute("data-floor") == "0"
        assert "walkable area, floor 0" in pg.inner_text("#legend")
        # A session whose track is not in the site's frame (no start) gets no plan.
        pg.goto(f"{service.url}/#/session/{service.plain}")
        pg.wait_for_function("() => window.pdrPage.timings.complete !== undefined")
        assert pg.locator("#map path[data-role=track]").count() >= 1
        assert pg.locator("#map path[data-role=floor-plan]").count() == 0
        assert "uploaded site (floor altitudes)" in pg.inner_text("#session-summary")
    finally:
        context.close()
    assert not errors, errors
