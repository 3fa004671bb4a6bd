"""Sites: upload a building's description once (floor plans, floor altitudes, landmarks), list, get, delete; the
floor plans a session is processed with.

``POST /api/v1/sites`` takes the site JSON ``pdr track --site`` reads (as the JSON body, or a multipart ``file``
with an optional ``name`` field) and checks it with the library's readers (:func:`server.sites.check_site`): a bad
site is refused 422 naming the floor, polygon, ring and field. Sites belong to their user; a session names one in
its processing options (``site_id``, optional ``start``) and keeps its own copy, so deleting a site changes no
session.
"""

from __future__ import annotations

import json
from typing import Any

from flask import Blueprint, Response, jsonify, request

from server.api import current_user, json_body, multipart_file, no_query_parameters, plain_body, services
from server.errors import APIError
from server.processing_options import ProcessingOptions, session_options
from server.schemas import check_representable
from server.site_store import SiteDocument, SiteStore
from server.sites import cached_site, check_site, plan_json, resolve_site, site_summary

bp = Blueprint("sites", __name__, url_prefix="/api/v1")


def site_store() -> SiteStore:
    return SiteStore(services().store.engine)


def site_json(row: Any) -> dict[str, Any]:
    """Public representation of a stored site (without its document)."""
    return {"id": row.id, "created_at": row.created_at.isoformat(), "size_bytes": row.size_bytes,
            "digest": row.digest, **json.loads(row.summary), "name": row.name}


def _uploaded_document() -> tuple[Any, str, int]:
    """The site document of the request (JSON body or multipart ``file``), a name, and its size in bytes."""
    plain_body()
    if request.files or (request.content_type or "").startswith("multipart/"):
        upload = multipart_file("site JSON")
        payload = upload.read()
        upload.close()
        if not payload:
            raise APIError(422, "uploaded site file is empty", details={"field": "file"})
        try:
            document = json.loads(payload)
        except (ValueError, UnicodeDecodeError) as exc:
            raise APIError(422, f"site file is not JSON ({exc})", details={"field": "file"}) from None
        except RecursionError:
            raise APIError(400, "site file is JSON nested too deeply", details={"field": "file"}) from None
        check_representable(document, payload, "site file")
        field, name = ("name", request.form["name"]) if request.form.get("name") else ("file", upload.filename or "")
        if "\x00" in name:   # PostgreSQL refuses it in text
            raise APIError(422, f"the site's {'name' if field == 'name' else 'file name'} holds a NUL character",
                           details={"field": field})
        return document, name, len(payload)
    document = json_body("site")
    return document, "", request.content_length or len(request.get_data())


@bp.post("/sites")
def create_site() -> tuple[Response, int]:
    """Store a site after checking it (422 naming the floor, polygon, ring or field of what is wrong)."""
    user = current_user()
    document, name, size = _uploaded_document()
    checked = check_site(document)
    summary = site_summary(checked)
    name = name or checked.site.name or "site"
    store = site_store()
    sid = store.create(user.id, name, document, summary, size)
    return jsonify(site_json(store.row(sid, user.id))), 201


@bp.get("/sites")
def list_sites() -> Response:
    user = current_user()
    no_query_parameters()
    return jsonify({"sites": [site_json(r) for r in site_store().list_for(user.id)]})


@bp.get("/sites/<site_id>")
def get_site(site_id: str) -> Response:
    """The site's summary and, as ``plan``, its floor plans in its metric frame (the document as stored: ``site``)."""
    user = current_user()
    store = site_store()
    row = store.row(site_id, user.id)
    doc = store.document(site_id, user.id)
    return jsonify({**site_json(row), "plan": plan_json(cached_site(doc)), "site": doc.parsed()})


@bp.delete("/sites/<site_id>")
def delete_site(site_id: str) -> tuple[str, int]:
    """Delete the site; sessions that named it keep the copy they are processed with."""
    user = current_user()
    site_store().delete(site_id, user.id)
    return "", 204


@bp.get("/sessions/<session_id>/site")
def session_site_plan(session_id: str) -> Response:
    """The floor plans of the site the session is processed with, and its start (404 when it names none)."""
    user = current_user()
    row = services().store.session_row(session_id, user.id)
    doc = site_store().session_site(session_id)
    if doc is None:
        raise APIError(404, "this session names no uploaded site (processing option site_id)")
    options = session_options(json.loads(row.meta or "{}"))
    start = None if options.start is None else {"east_m": options.start[0], "north_m": options.start[1],
                                                 "floor": None if len(options.start) < 3 else int(options.start[2])}
    return jsonify({"site_id": doc.site_id, "start": start, **plan_json(cached_site(doc))})


def named_site(options: ProcessingOptions, user_id: int) -> SiteDocument | None:
    """The user's site the options name, checked with their start (422 naming the option when it is wrong)."""
    return resolve_site(options, user_id, site_store())


def give_session_site(session_id: str, doc: SiteDocument | None) -> None:
    """Store the session's copy of its site (None: it names none)."""
    site_store().set_session_site(session_id, doc)
