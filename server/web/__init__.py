"""The service's own web page: one static HTML page at ``/`` and its scripts and styles under ``/web/``.

The page is plain HTML/CSS/JavaScript (no build step, no external CDN, so it works offline); it reads
everything through the JSON API with the user's token in the ``Authorization`` header. The served files hold
no user data, so they need no authentication. A strict Content-Security-Policy allows only this origin's
scripts (no inline script), which keeps a session name or warning text from ever running as code.

Leaflet (npm ``leaflet``, BSD-2-Clause; ``static/vendor/leaflet/``, see its ``VENDORED.md``) draws every track:
in local metres with ``L.CRS.Simple`` (``static/trackmap.js``: floor plan, truth and errors, one unit a metre), and a
geo-referenced session also on a real map in longitude/latitude (Web Mercator). Map tiles come only from the
operator's ``PDR_MAP_TILE_URL`` (``GET /web/config.json`` hands it to the page, and the policy's ``img-src`` names
its host); without it the map has no tiles and the page loads nothing from elsewhere.
"""

from __future__ import annotations

from pathlib import Path

from flask import Blueprint, Response, current_app, jsonify, send_from_directory

from server.config import tile_origins

STATIC_DIR = Path(__file__).parent / "static"

bp = Blueprint("web", __name__, static_folder=str(STATIC_DIR), static_url_path="/web")

#: Content-Security-Policy of the page; ``{tiles}``: the configured tile server's origin, if any.
CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:{tiles}; "
       "connect-src 'self'; frame-src blob:; object-src 'none'; base-uri 'none'; form-action 'none'; "
       "frame-ancestors 'none'")

#: Headers of every page response: only same-origin code, no framing, no referrer (URLs never hold tokens).
SECURITY_HEADERS = {
    "Referrer-Policy": "no-referrer",
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
}


@bp.get("/")
def index() -> Response:
    """The single page; its views are chosen by the URL fragment (``#/sessions``, ``#/session/ID``, ...)."""
    resp = send_from_directory(STATIC_DIR, "index.html", max_age=0)
    resp.headers["Cache-Control"] = "no-cache"
    return resp


@bp.get("/web/config.json")
def config() -> Response:
    """What the page needs of the service's configuration: the map tile URL template and its attribution."""
    settings = current_app.extensions["pdr"].settings
    resp = jsonify({"map": {"tile_url": settings.map_tile_url or None,
                            "attribution": settings.map_tile_attribution or None}})
    resp.headers["Cache-Control"] = "no-cache"
    return resp


@bp.after_request
def _harden(resp: Response) -> Response:
    # Every response of this blueprint (the page and its static files) gets the same hardening headers.
    tiles = "".join(" " + o for o in tile_origins(current_app.extensions["pdr"].settings.map_tile_url))
    resp.headers.setdefault("Content-Security-Policy", CSP.format(tiles=tiles))
    for key, value in SECURITY_HEADERS.items():
        resp.headers.setdefault(key, value)
    return resp
