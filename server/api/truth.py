"""Ground truth of uploaded log files: ``GET /api/v1/sessions/{id}/truth`` (reference positions for the web page).

Only sessions created from an uploaded log file (``source == "upload"``) carry truth: it is read back from
the stored raw file (batches of format ``file:...``). Decoding a file costs as much as reading it, so the
positions are cached per stored batch; raw batches never change once stored (a different payload under the
same batch id is refused), which makes the cache safe without invalidation.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from typing import Any

from flask import Blueprint, Response, jsonify

from pdr.errors import InputError
from server.api import current_user, services
from server.processing import FILE_PREFIX, decode_batch
from server.session_clock import session_clock
from server.store import BatchRecord

bp = Blueprint("truth", __name__, url_prefix="/api/v1/sessions")

_CACHE_SIZE = 32
_cache: OrderedDict[tuple[str, int, str], dict[str, Any]] = OrderedDict()
_cache_lock = threading.Lock()


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def truth_of_batch(batch: BatchRecord) -> dict[str, Any]:
    """Truth positions of one stored file batch as JSON-ready rows (``points`` empty when it has none).

    ``t_s`` is on the recording's own time axis (seconds from its ``t0_ns``), the axis of the track rows of
    a processed upload; positions are local metres (east, north, up) of the recording's ``frame``.
    """
    out: dict[str, Any] = {"batch_id": batch.client_batch_id, "device": batch.device_role, "kind": None,
                           "frame": None, "t0_ns": None, "origin": None, "points": [], "error": None}
    try:
        recording = decode_batch(batch)
    except InputError as exc:
        out["error"] = str(exc)
        return out
    out["t0_ns"] = recording.origin_ns
    pos = recording.truth.positions
    if pos is None:
        return out
    floors = pos.floor if pos.floor is not None else [math.nan] * len(pos.t_s)
    out.update(kind=pos.kind, frame=pos.frame, origin=_origin(pos.origin_lat_lon_deg),
               points=[{"t_s": float(t), "east_m": float(p[0]), "north_m": float(p[1]), "up_m": float(p[2]),
                        "floor": _num(float(f))} for t, p, f in zip(pos.t_s, pos.pos_m, floors, strict=True)])
    return out


def _origin(lat_lon: tuple[float, float] | None) -> dict[str, float] | None:
    return None if lat_lon is None else {"lat_deg": float(lat_lon[0]), "lon_deg": float(lat_lon[1])}


def _cached_truth(batch: BatchRecord, database: str) -> dict[str, Any]:
    # The client batch id of an uploaded file embeds its content digest: the key names the content.
    key = (database, batch.id, batch.client_batch_id)
    with _cache_lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key]
    value = truth_of_batch(batch)
    with _cache_lock:
        _cache[key] = value
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    return value


@bp.get("/<session_id>/truth")
def truth(session_id: str) -> Response:
    """Reference positions of the session's uploaded log files: ``{"truth": [...], "count": N}``."""
    user = current_user()
    svc = services()
    row = svc.store.session_row(session_id, user.id)
    sets: list[dict[str, Any]] = []
    if row.source == "upload":
        listed = svc.store.batches(session_id, with_payload=False)
        if any(b.payload_format.startswith(FILE_PREFIX) for b in listed):
            for batch in svc.store.batches(session_id):
                if batch.payload_format.startswith(FILE_PREFIX):
                    sets.append(_cached_truth(batch, str(svc.store.engine.url)))
    return jsonify({"session": session_id, "truth": sets, "count": sum(len(s["points"]) for s in sets),
                    "clock": session_clock(svc.store, row)})
