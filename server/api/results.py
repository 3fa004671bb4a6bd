"""Results of a session: track (JSON, CSV, GeoJSON), steps, motion modes, landmarks, floors; ``?since=`` polling.

``GET .../track?heading=smoothed`` gives the track ``pdr track`` writes by default: the hand-held and torso phone
steps' headings smoothed over the whole session so far (:mod:`pdr.phone.heading_smoother`) and the positions
re-integrated. Smoothing moves earlier rows too, so a poller asking with ``since`` gets the rows after it of the
track smoothed over everything received. ``heading=causal`` (the default) is the track as it was streamed.

The track, steps, modes, landmarks and floors also take ``?after=SEQ``: every entry (track row, step) stored since
the one numbered ``SEQ`` (a mode, landmark or floor carries its ``seq``; every answer's ``next_after``, the largest
number among its entries, is the one to ask with next), whatever its time. ``since`` filters by the entry's own
time, and some entries are stored with a time in the past: a stop or an elevator ride once it has ended, a stairs
entry moved back by the barometer's lag, the steps of a shoe's file uploaded after the phone's walk. A poller using
``since`` misses those; one using ``after`` does not.
Provisional entries (the session's open end) are replaced at every batch and come again with new numbers, as do all
entries after a rebuild.
While a rebuild runs (reprocessing, new processing options, a late batch) every answer is the results from
before it, until it ends. A smoothed answer names the devices whose headings the smoother changed
(``smoothed_devices``; foot sensors and phones without its inputs keep their tracks) and gives its note per
device (``heading_notes``).
"""

from __future__ import annotations

import csv
import io
import json
import math
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, TypeVar

from flask import Blueprint, Response, jsonify, request
from sqlalchemy import func, select

from pdr.phone.heading_smoother import smooth_track
from pdr.phone.track_geojson import NotGeoReferenced, track_geojson
from pdr.phone.track_schema import TRACK_COLUMNS
from server import db
from server.api import current_user, only_query_parameters, services
from server.errors import APIError
from server.feet import ROLE_PRIORITY, primary_role
from server.processing_options import map_matched
from server.session_clock import session_clock
from server.store import step_fields

T = TypeVar("T")

bp = Blueprint("results", __name__, url_prefix="/api/v1/sessions")

EVENT_KINDS = {"modes": "mode", "landmarks": "landmark", "floors": "floor"}

#: The largest ``seq`` an entry can have: ``events.id`` is an ``Integer`` column, PostgreSQL's 4-byte ``integer``
#: (SQLite's is wider); a larger ``?after=`` would fail in the database rather than match nothing.
MAX_SEQ = 2**31 - 1

#: Values of ``?device=`` (:func:`parse_device`): a device role with a track, or ``primary``.
DEVICES = (*ROLE_PRIORITY, "primary")


def _query_value(name: str, convert: Callable[[str], T], expected: str, status: int = 400) -> T | None:
    """The query parameter ``name`` converted by ``convert``; None when absent, a 400 (``status``) naming it (as
    ``expected``) when it does not convert.
    """
    raw = request.args.get(name)
    if raw is None:
        return None
    try:
        return convert(raw)
    except ValueError:
        raise APIError(status, f"'{name}' must be {expected}, got '{raw[:40]}'", details={"field": name}) from None


def parse_since(name: str = "since", status: int = 400) -> float | None:
    """The ``?since=`` query parameter (seconds on the log's clock; or the one called ``name``), a finite number;
    None when absent, a 400 (``status``) naming it otherwise.
    """
    value = _query_value(name, float, "a number of seconds", status)
    if value is not None and not math.isfinite(value):
        raise APIError(status, f"'{name}' must be finite", details={"field": name})
    return value


def parse_after() -> int | None:
    """The ``?after=`` query parameter (an entry's ``seq``), validated; None when absent."""
    value = _query_value("after", int, "an entry's seq (an integer)")
    if value is not None and value < 0:
        raise APIError(400, "'after' must not be negative", details={"field": "after"})
    if value is not None and value > MAX_SEQ:
        raise APIError(400, f"'after' must be at most {MAX_SEQ} (no entry's seq is larger)", details={"field": "after"})
    return value


def parse_device(session_id: str) -> str | None:
    """The ``?device=`` query parameter: a device role, ``primary`` (the session's primary track,
    :mod:`server.feet`), or None (every device's rows); a 400 naming it for anything else.
    """
    device = request.args.get("device") or None
    if device is not None and device not in DEVICES:
        raise APIError(400, f"unknown device '{device[:40]}'; use one of {', '.join(ROLE_PRIORITY)} or primary",
                       details={"field": "device"})
    if device == "primary":
        store = services().store
        return primary_role(store.track_summary(session_id, previous=store.rebuilding(session_id))) or device
    return device


def parse_heading() -> str:
    """The ``?heading=`` query parameter, ``causal`` (default) or ``smoothed`` (module doc)."""
    heading = request.args.get("heading", "causal")
    if heading not in ("causal", "smoothed"):
        raise APIError(400, f"unknown heading '{heading[:20]}'; use causal or smoothed", details={"field": "heading"})
    return heading


@dataclass(frozen=True)
class Smoothing:
    """What ``?heading=smoothed`` did: the smoother's note per device and the devices whose headings it smoothed."""

    notes: tuple[str, ...] = ()
    devices: tuple[str, ...] = ()

    def fields(self) -> dict[str, Any]:
        """The response fields (module doc): ``smoothed_devices`` always, ``heading_notes`` when there are notes."""
        return {"smoothed_devices": list(self.devices)} | ({"heading_notes": list(self.notes)} if self.notes else {})


def track_points(session_id: str, device: str | None, since: float | None, heading: str, after: int | None = None
                 ) -> tuple[list[dict[str, Any]], Smoothing | None, int | None]:
    """The stored track rows after ``since`` (s) and stored after the row numbered ``after`` as dicts (the track
    columns, ``device``, ``provisional``; non-finite values as None), for ``heading="smoothed"`` what the smoother
    did (None for the causal track), and the answer's ``next_after`` (:func:`next_after`).
    ``heading="smoothed"`` smooths the whole stored track before taking the rows after ``since`` and ``after``
    (module doc).
    """
    store = services().store
    previous = store.rebuilding(session_id)   # results from before a running rebuild (Store.clear_results)
    if heading != "smoothed" or map_matched(json.loads(store.session_row(session_id).meta or "{}")):
        points = store.track(session_id, device, since, previous=previous, after_id=after)
        # Map-matched: re-integrating smoothed headings would undo the walls; the track as streamed, with the reason.
        smoothing = None if heading != "smoothed" else Smoothing((MAP_MATCHED_NOTE,))
        return _rows(points), smoothing, next_after((p.id for p in points), after)
    key = (str(store.engine.url), session_id, device, previous, _results_version(store.engine, session_id))
    with _SMOOTHED_LOCK:
        hit = _SMOOTHED.get(key)
        if hit is not None:
            _SMOOTHED.move_to_end(key)
    if hit is None:
        points = store.track(session_id, device, None, previous=previous)
        # Store.track groups the rows by device, as _smoothed does: its rows are in the order of their ids here.
        hit = (*_smoothed(points), tuple(p.id for p in points))
        with _SMOOTHED_LOCK:
            _SMOOTHED[key] = hit
            while len(_SMOOTHED) > SMOOTHED_CACHE_SIZE:
                _SMOOTHED.popitem(last=False)
    rows, smoothing, ids = hit
    kept = [(r, i) for r, i in zip(rows, ids, strict=True)
            if (since is None or r["t_s"] > since) and (after is None or i > after)]
    return [r for r, _ in kept], smoothing, next_after((i for _, i in kept), after)


#: The note of ``?heading=smoothed`` on a session map-matched online (``server.sites``).
MAP_MATCHED_NOTE = ("phone: not smoothed: the track is map-matched online on the session's site (its positions come "
                    "from the floor plan; smoothed headings re-integrated would leave it)")

#: Smoothed tracks kept (:func:`track_points`): the sessions being watched, a few thousand rows each.
SMOOTHED_CACHE_SIZE = 8
#: (database URL, session id, device, results version) -> the smoothed rows, what the smoother did and the rows'
#: numbers. The rows are shared between answers: read them, never change them.
_SMOOTHED: OrderedDict[tuple[Any, ...], tuple[list[dict[str, Any]], Smoothing, tuple[int, ...]]] = OrderedDict()
_SMOOTHED_LOCK = threading.Lock()


def _results_version(engine: Any, session_id: str) -> tuple[Any, ...]:
    """What changes whenever a session's stored results do: every commit of results (``Store.commit_results``)
    stamps its processor state's ``updated_at`` and adds or replaces track rows (new ids), a reprocessing
    (``Store.clear_results``) deletes the states and rows. One indexed query, whatever the session's length.
    """
    tp, ps = db.track_points, db.processor_states
    q = select(*(select(agg).where(table.c.session_id == session_id).scalar_subquery()
                 for table, agg in ((tp, func.count(tp.c.id)), (tp, func.max(tp.c.id)),
                                    (ps, func.count(ps.c.device_role)), (ps, func.max(ps.c.updated_at)))))
    with engine.connect() as conn:
        row = conn.execute(q).first()
    return tuple(row) if row is not None else ()


def _rows(points: list[Any]) -> list[dict[str, Any]]:
    """Stored track rows as dicts: the track columns (non-finite values as None), ``device``, ``provisional``."""
    return [{c: _clean(getattr(p, c)) for c in TRACK_COLUMNS} | {"device": p.device_role, "provisional": p.provisional}
            for p in points]


def next_after(seqs: Iterable[int], after: int | None) -> int | None:
    """The ``next_after`` of an answer: the largest number (``seq``) of its entries, else the ``after`` it was asked
    with.
    """
    return max(seqs, default=after)


def _clean(v: Any) -> Any:
    return None if isinstance(v, float) and not math.isfinite(v) else v


@bp.get("/<session_id>/track")
def track(session_id: str) -> Response:
    """The track, one row per step: ``?format=json|csv|geojson``, ``?device=ROLE|primary``, ``?since=T_S``,
    ``?after=SEQ``, ``?heading=causal|smoothed`` (module doc). Every form names each row's device (CSV: the last
    column).
    """
    user = current_user()
    svc = services()
    row = svc.store.session_row(session_id, user.id)
    only_query_parameters("format", "device", "since", "after", "heading")
    fmt = request.args.get("format", "json")
    if fmt not in ("json", "csv", "geojson"):
        raise APIError(400, f"unknown format '{fmt[:20]}'; use json, csv or geojson", details={"field": "format"})
    heading = parse_heading()
    since, after = parse_since(), parse_after()
    rows, smoothing, after_rows = track_points(session_id, parse_device(session_id), since, heading, after)
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow((*TRACK_COLUMNS, "device"))
        for r in rows:
            writer.writerow(["" if r[c] is None else (repr(r[c]) if isinstance(r[c], float) else r[c])
                             for c in (*TRACK_COLUMNS, "device")])
        return Response(buf.getvalue(), mimetype="text/csv",
                        headers={"Content-Disposition": f'attachment; filename="{session_id}.csv"'})
    if fmt == "geojson":
        return Response(json.dumps(_geojson(rows, row) | {"clock": session_clock(svc.store, row)}),
                        mimetype="application/geo+json")
    next_since = max(r["t_s"] for r in rows) if rows else since
    body: dict[str, Any] = {"session": session_id, "columns": list(TRACK_COLUMNS), "points": rows,
                            "count": len(rows), "next_since": next_since,
                            "next_after": after_rows, "heading": heading,
                            "clock": session_clock(svc.store, row)}
    return jsonify(body | (smoothing.fields() if smoothing else {}))


def _smoothed(points: list[Any]) -> tuple[list[dict[str, Any]], Smoothing]:
    """The stored track rows (one device or several; :func:`_rows`) with each device's steps smoothed, and what the
    smoother did.

    The smoother's inputs are the phone steps' own fields (:func:`server.store.step_fields`); a device whose steps
    lack them (foot sensors, the fused feet, sessions processed before they were stored) keeps its track.
    """
    rows = _rows(points)
    out: list[dict[str, Any]] = []
    notes: list[str] = []
    devices: list[str] = []
    for device in dict.fromkeys(r["device"] for r in rows):
        mine = [(r, p) for r, p in zip(rows, points, strict=True) if r["device"] == device]
        smoothed, note = smooth_track([step_fields(p) | r for r, p in mine])
        if note:
            notes.append(f"{device}: {note}")
        if smoothed and all(s.get("smoothed") for s in smoothed):
            devices.append(device)
        out += [r | {k: s[k] for k in ("east_m", "north_m", "heading_deg")}
                for (r, _), s in zip(mine, smoothed, strict=True)]
    return out, Smoothing(tuple(notes), tuple(devices))


def _geojson(rows: list[dict[str, Any]], session: Any) -> dict[str, Any]:
    """The track as RFC 7946 GeoJSON (:mod:`pdr.phone.track_geojson`); 409 when the session has no origin."""
    origin = None if session.origin_lat_deg is None else (session.origin_lat_deg, session.origin_lon_deg)
    try:
        return track_geojson(rows, origin, source=f"session {session.id}")
    except NotGeoReferenced as exc:
        raise APIError(409, f"{exc.message} (a session gets an origin from a log's surveyed origin, a Sensor Logger "
                            f"location reading or 'origin' when it is created); use ?format=json or csv",
                       code=NotGeoReferenced.code, details={"field": "format"}) from None


def _events(session_id: str, what: str) -> Response:
    user = current_user()
    svc = services()
    row = svc.store.session_row(session_id, user.id)
    only_query_parameters("since", "after")
    after = parse_after()
    rows = svc.store.events(session_id, EVENT_KINDS[what], parse_since(), previous=svc.store.rebuilding(session_id),
                            after_id=after)
    items = [{"t_s": r.t_s, "t_end_s": r.t_end_s, "label": r.label, "value": _clean(r.value),
              "device": r.device_role, "provisional": r.provisional, "seq": r.id, **json.loads(r.data or "{}")}
             for r in rows]
    return jsonify({"session": session_id, what: items, "count": len(items),
                    "next_since": items[-1]["t_s"] if items else parse_since(),
                    "next_after": next_after((r.id for r in rows), after), "clock": session_clock(svc.store, row)})


@bp.get("/<session_id>/steps")
def steps(session_id: str) -> Response:
    """The stored steps of every device in time order (``?since=T_S``, ``?after=SEQ``): the track columns,
    ``step_index`` (0, 1, ... per device), ``device``, ``provisional``, a phone step's other fields
    (:class:`pdr.phone.events.StepEvent`), a foot step's increment; ``label`` (the mode) and ``value`` (the step
    length, m) as the other event lists have.
    """
    user = current_user()
    svc = services()
    session = svc.store.session_row(session_id, user.id)
    only_query_parameters("since", "after")
    since, after = parse_since(), parse_after()
    rows = svc.store.steps(session_id, since, previous=svc.store.rebuilding(session_id), after_id=after)
    items = [{"t_s": r.t_s, "t_end_s": None, "label": r.mode, "value": _clean(r.step_length_m),
              "device": r.device_role, "provisional": r.provisional, "step_index": r.step_index}
             | {c: _clean(getattr(r, c)) for c in TRACK_COLUMNS} | step_fields(r) | json.loads(r.data or "{}")
             for r in rows]
    return jsonify({"session": session_id, "steps": items, "count": len(items),
                    "next_since": items[-1]["t_s"] if items else since,
                    "next_after": next_after((r.id for r in rows), after), "clock": session_clock(svc.store, session)})


@bp.get("/<session_id>/modes")
def modes(session_id: str) -> Response:
    return _events(session_id, "modes")


@bp.get("/<session_id>/landmarks")
def landmarks(session_id: str) -> Response:
    return _events(session_id, "landmarks")


@bp.get("/<session_id>/floors")
def floors(session_id: str) -> Response:
    return _events(session_id, "floors")
