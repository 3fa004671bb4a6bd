"""Sites in the service: checking an uploaded site, naming one in a session's options, and what its processor runs.

A site is the JSON of ``pdr track --site`` with floor plans (:mod:`pdr.site.plan`): both halves are read by the
library's own readers, the floor plans by :class:`pdr.site.plan.SitePlan` (errors name the floor, polygon, ring and
field) and the landmarks, floor height and per-floor altitudes by :class:`pdr.phone.landmarks.Site`, so an upload is
refused (422) exactly where ``pdr site check`` refuses the file.

A session names an uploaded site in its processing options (``{"site_id": ID, "start": [E, N] | [E, N, FLOOR]}``,
:mod:`server.processing_options`). The view checks them against the user's sites and gives the session its copy
(:class:`server.site_store.SiteStore`); the phone processor then runs the pipeline with the site's floor altitudes
and, with a start (m, the site's frame; the floor defaults to the site's only one), the map-matching stage
(:class:`pdr.mapmatch.stage.MapMatchStage`) online, so the session's track is in the site's frame.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

from pdr.errors import InputError
from pdr.mapmatch.stage import MapMatchStage
from pdr.phone.landmarks import Site
from pdr.phone.stage import StepStage
from pdr.site.plan import SitePlan
from server.errors import APIError
from server.processing_options import ProcessingOptions
from server.site_store import SiteDocument, SiteStore

#: Parsed sites kept per process (a floor plan's check takes a fraction of a second; batches come every second).
CACHE_SIZE = 8


@dataclass(frozen=True)
class CheckedSite:
    """A site description read by both library readers: landmarks and floors (``site``) and floor plans (``plan``)."""

    site: Site
    plan: SitePlan


def check_site(document: Any, source: str = "site") -> CheckedSite:
    """Read a site description; :class:`InputError` naming the floor, polygon, ring or field that is wrong."""
    plan = SitePlan.from_dict(document, source=source)
    landmarks = {"landmarks": [], **document} if isinstance(document, dict) else document
    return CheckedSite(Site.from_dict(landmarks, source=source), plan)


def site_summary(checked: CheckedSite) -> dict[str, Any]:
    """What a site listing shows: its name, floor height, landmarks and per floor the altitude, polygons and bounds."""
    plan = checked.plan
    return {"name": checked.site.name, "floor_height_m": plan.floor_height_m, "landmarks": len(checked.site.landmarks),
            "frame_bearing_deg": plan.frame_bearing_deg,
            "floors": [{"floor": f.floor, "altitude_m": plan.altitude_m(f.floor), "polygons": len(f.polygons),
                        "holes": sum(len(p.holes) for p in f.polygons),
                        "bounds_m": [round(v, 3) for v in f.bounds()]}
                       for f in sorted(plan.floors.values(), key=lambda f: f.floor)]}


_cache: OrderedDict[str, CheckedSite] = OrderedDict()
_cache_lock = threading.Lock()


def cached_site(doc: SiteDocument) -> CheckedSite:
    """The checked site of a stored document, parsed once per process and digest."""
    with _cache_lock:
        hit = _cache.get(doc.digest)
        if hit is not None:
            _cache.move_to_end(doc.digest)
            return hit
    checked = check_site(doc.parsed(), source=f"site '{doc.site_id}'")
    with _cache_lock:
        _cache[doc.digest] = checked
        while len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)
    return checked


def resolve_site(options: ProcessingOptions, user_id: int, store: SiteStore) -> SiteDocument | None:
    """The user's site the options name, with their start checked on its plan (None when they name none).

    Refused with an :class:`InputError` naming ``processing.site_id`` (no such site of this user) or
    ``processing.start`` (a floor the site lacks, several floors and none given, or a point outside the walkable
    area).
    """
    if options.site_id is None:
        return None
    try:
        doc = store.document(options.site_id, user_id)
    except APIError:  # the store's 404 (another user's site is not revealed either)
        raise InputError(f"no site '{options.site_id[:64]}': upload it with POST /api/v1/sites and name the id it "
                         "answers", field="processing.site_id") from None
    if options.start is not None:
        start_site(cached_site(doc).plan, options.start)
    return doc


def start_site(plan: SitePlan, start: tuple[float, ...]) -> tuple[tuple[float, float], int]:
    """The start point (m, site frame) and floor of a session's ``start`` option, checked on ``plan``
    (:class:`InputError` naming ``processing.start``).
    """
    point = (float(start[0]), float(start[1]))
    try:
        floor = plan.start_floor(int(start[2]) if len(start) == 3 else None)
        plan.check_walkable(point, floor)
    except InputError as exc:
        raise InputError(exc.message, field="processing.start") from None
    return point, floor


@dataclass(frozen=True)
class SessionSite:
    """The site a session's phone processor runs with: its floors and landmarks, and the map matcher's start."""

    checked: CheckedSite
    start_en: tuple[float, float] | None
    floor: int | None

    def stages(self) -> list[StepStage]:
        """The pipeline's plugged-in stages: the map matcher when the session has a start, else none."""
        if self.start_en is None or self.floor is None:
            return []
        return [MapMatchStage(self.checked.plan, self.start_en, self.floor, source="processing.start")]


def session_site(options: ProcessingOptions, doc: SiteDocument | None) -> SessionSite | None:
    """The session's site from its options and its copy of the site (None when it names none)."""
    if options.site_id is None or doc is None:
        return None
    checked = cached_site(doc)
    if options.start is None:
        return SessionSite(checked, None, None)
    point, floor = start_site(checked.plan, options.start)
    return SessionSite(checked, point, floor)


def plan_json(checked: CheckedSite) -> dict[str, Any]:
    """The floor plans in the site's metric frame (GeoJSON MultiPolygons per floor, with altitudes), for drawing."""
    d = checked.plan.to_dict()
    for f in d["floors"]:
        f["altitude_m"] = checked.plan.altitude_m(f["floor"])
    return {"name": checked.site.name, **d}
