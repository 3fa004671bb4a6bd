"""The service's own web page: one static HTML page at ``/`` and its scripts and styles under ``/web/``.

The page is plain HTML/CSS/JavaScript (no build step, no external CDN or map tiles, so it works offline);
it reads everything through the JSON API with the user's token in the ``Authorization`` header. The
served files hold no user data, so they need no authentication. A strict Content-Security-Policy allows
only this origin's scripts (no inline script), which keeps a session name or warning text from ever
running as code.
"""

from __future__ import annotations

from pathlib import Path

from flask import Blueprint, Response, send_from_directory

STATIC_DIR = Path(__file__).parent / "static"

bp = Blueprint("web", __name__, static_folder=str(STATIC_DIR), static_url_path="/web")

#: Headers of every page response: only same-origin code, no framing, no referrer (URLs never hold tokens).
SECURITY_HEADERS = {
    "Content-Security-Policy": ("default-src 'self'; script-src 'self'; style-src 'self'; "
                                "img-src 'self' blob: data:; connect-src 'self'; frame-src blob:; "
                                "object-src 'none'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"),
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


@bp.after_request
def _harden(resp: Response) -> Response:
    # Every response of this blueprint (the page and its static files) gets the same hardening headers.
    for key, value in SECURITY_HEADERS.items():
        resp.headers.setdefault(key, value)
    return resp
