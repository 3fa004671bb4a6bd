"""The track as columns: ``GET /api/v1/sessions/{id}/track/columns`` (compact and fast, for the web page).

The same rows as ``/track`` (``?device=ROLE|primary``, ``?since=T_S``, ``?after=SEQ``, ``?heading=causal|smoothed``,
with its ``smoothed_devices``, ``heading_notes`` and ``next_after``), laid out as one
array per column instead of
one object per row: for a 2-hour walk (10 000+ steps) that halves the body and the server's time, which is
most of the page's first render.
"""

from __future__ import annotations

import json
import math
from typing import Any

from flask import Blueprint, Response

from pdr.phone.track_schema import TRACK_COLUMNS
from server.api import current_user, only_query_parameters, services
from server.api.results import next_after, parse_after, parse_device, parse_heading, parse_since, track_points

bp = Blueprint("track_columns", __name__, url_prefix="/api/v1/sessions")

#: Columns of the track (those of ``pdr track`` CSV output), the device role of each row and whether it is
#: provisional (the processor's tail: what ending the session now would add; replaced by the next batch).
COLUMNS = (*TRACK_COLUMNS, "device_role", "provisional")


def _finite(values: list[Any]) -> list[Any]:
    return [None if isinstance(v, float) and not math.isfinite(v) else v for v in values]


@bp.get("/<session_id>/track/columns")
def track_columns(session_id: str) -> Response:
    """``{"session", "count", "columns": {name: [...]}, "next_since", "next_after"}``; ``device`` is the device role
    per row.

    Provisional rows are replaced when the next batch is processed: a poller drops them and asks again
    from its last final row.
    """
    user = current_user()
    svc = services()
    svc.store.session_row(session_id, user.id)
    only_query_parameters("device", "since", "after", "heading")
    heading = parse_heading()
    since, after = parse_since(), parse_after()
    smoothing = None
    last = after
    if heading == "smoothed":
        points, smoothing, last = track_points(session_id, parse_device(session_id), since, heading, after)
        columns = {name: [p["device" if name == "device_role" else name] for p in points] for name in COLUMNS}
        count = len(points)
    elif rows := svc.store.track(session_id, parse_device(session_id), since,
                                 previous=svc.store.rebuilding(session_id), after_id=after):
        last = next_after((r.id for r in rows), after)
        fields = list(rows[0]._fields)
        transposed = list(zip(*rows, strict=True))
        columns = {name: list(transposed[fields.index(name)]) for name in COLUMNS}
        count = len(rows)
    else:
        columns = {name: [] for name in COLUMNS}
        count = 0
    columns["provisional"] = [bool(v) for v in columns["provisional"]]
    columns["device"] = columns.pop("device_role")
    body: dict[str, Any] = {"session": session_id, "count": count, "columns": columns,
                            "next_since": max(columns["t_s"]) if count else since, "next_after": last,
                            "heading": heading}
    if smoothing:
        body |= smoothing.fields()
    try:
        text = json.dumps(body, allow_nan=False)
    except ValueError:  # a non-finite value stored: null, as in /track
        body["columns"] = {k: _finite(v) for k, v in columns.items()}
        text = json.dumps(body)
    return Response(text, mimetype="application/json")
