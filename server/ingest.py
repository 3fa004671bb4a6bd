"""The one ingest service every upload endpoint calls: store the raw batch (idempotent), note the device, queue.

Views decode and validate their body once (one JSON parse, or one sandboxed reader for a file), then hand the
decoded result here, which is stored with the raw batch so that the worker never decodes or validates the payload
again; the order (commit the raw batch before answering, register the device only for a new batch, queue the
session) is written once.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pdr import recording_codec
from pdr.foot import summaries_codec
from pdr.foot.summaries import StepSummaryBatch
from pdr.recording import DeviceInfo, Recording

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from server.api import Services


@dataclass(frozen=True)
class Accepted:
    """The stored batch's id and whether it is new (``False``: a replay of a batch already stored)."""

    id: int
    created: bool


def store_batch(svc: Services, session_id: str, *, client_batch_id: str, payload_format: str, payload: bytes,
                t_first_ns: int | None, t_last_ns: int | None, device: DeviceInfo, content: Any = None,
                recording: Recording | StepSummaryBatch | None = None) -> Accepted:
    """Persist a raw batch of ``session_id`` from ``device`` (its role names the processor) and queue the session
    when the batch is new.

    ``content`` is the payload's decoded JSON (JSON payloads): a re-send with the same content in other
    whitespace is a replay (:meth:`server.store.Store.add_batch`). ``recording`` is what the view decoded from
    the payload (a recording, or a shoe unit's step summaries): it is stored with the batch and processing reads it
    instead of decoding the payload again.
    Raises the 409 of a different payload under an existing ``client_batch_id``.
    """
    role = device.role
    bid, created = svc.store.add_batch(session_id, device_role=role, client_batch_id=client_batch_id,
                                       payload_format=payload_format, payload=payload, t_first_ns=t_first_ns,
                                       t_last_ns=t_last_ns, content=content, decoded=encoded(recording))
    if created:
        svc.store.upsert_device(session_id, role, device_id=device.device_id, platform=device.platform,
                                model=device.model, placement=device.placement)
        svc.worker.submit(session_id)
    return Accepted(bid, created)


def encoded(recording: Recording | StepSummaryBatch | None) -> bytes | None:
    """``recording`` as stored bytes (:mod:`pdr.recording_codec`, :mod:`pdr.foot.summaries_codec` for step
    summaries); ``None`` when there is none or it holds what the codec cannot store (then processing reads the raw
    payload, as for rows stored before decoded forms).
    """
    if recording is None:
        return None
    if isinstance(recording, StepSummaryBatch):
        return summaries_codec.dumps(recording)
    try:
        return recording_codec.dumps(recording)
    except TypeError as exc:
        log.warning("decoded recording not stored (%s); processing will read the raw payload", exc)
        return None
