"""Turning stored raw batches into results: decoding payloads and driving each device's online processor.

A *processor* is the online algorithm of one device role of a session (the phone PDR pipeline, or foot
navigation for a shoe IMU): ``update(recording) -> ProcessorOutput`` and ``to_bytes()`` / ``from_bytes``
for its state, so that a new batch costs time proportional to the batch and any worker can resume it.
Batches of a session are processed in time order, one at a time; a batch that ends at or before what was
already processed (an out-of-order upload) triggers a rebuild of the session from its raw batches.

Control requests never wait for a processing pass. Deleting a session (:meth:`server.store.Store.delete_session`)
or clearing its results for a rebuild (:meth:`SessionProcessing.clear`: reprocess, new processing options) is one
short transaction, committed before the answer. A pass writes through a store fenced at the session's results epoch
(:meth:`server.store.Store.fenced`), which every clear increments: each of its writes (a batch marked processing, a
batch's results and processor state, a batch failed, the end of a rebuild, the session's status) checks the epoch in
its own transaction, so it lands wholly before the delete or clear (which then deletes or clears it too) or raises
:class:`~server.store.SessionChanged` and writes nothing. The pass then ends when the session is gone, or begins
again at the new epoch, with processors made anew from the session's options and states as they are now: the
batches a clear set pending, and those uploaded meanwhile, are all processed. This holds across processes (the epoch
is in the database, as are the foreign keys that keep a deleted session's rows from being written), so it holds for
the workers of the scale-out mode too.
"""

from __future__ import annotations

import json
import logging
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC
from typing import Any, Protocol

from pdr.errors import InputError
from pdr.foot.summaries import StepSummaryBatch
from pdr.recording import Recording
from server.errors import APIError
from server.processing_options import site_id_of
from server.site_store import SiteDocument, SiteStore
from server.store import PURGED, BatchRecord, EventRow, SessionChanged, Store, StoredStep

log = logging.getLogger(__name__)

#: Payload formats of stored batches.
NATIVE_JSON = "native-json"
SENSOR_LOGGER_JSON = "sensor-logger-json"
FOOT_STEPS_JSON = "foot-steps-json"  # step-wise dead-reckoning summaries (pdr.foot.summaries), not a Recording
FILE_PREFIX = "file:"


@dataclass
class ProcessorOutput:
    """What one processed batch adds: steps (track rows, :data:`server.store.StoredStep`), events and warnings for the
    user; a step event names its step by position in ``track`` (:class:`server.store.EventRow`).
    """

    track: list[StoredStep] = field(default_factory=list)
    events: list[EventRow] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


class Processor(Protocol):
    def update(self, recording: Recording) -> ProcessorOutput: ...

    def to_bytes(self) -> bytes: ...


class FinishingProcessor(Processor, Protocol):
    def tail(self) -> ProcessorOutput:
        """What ending the session now would add (without changing the processor's state)."""
        ...


@dataclass(frozen=True)
class SessionContext:
    """What a processor may know about its session when it is created."""

    session_id: str
    role: str
    placement: str | None
    meta: dict[str, Any]
    #: The session's copy of the uploaded site its options name (server.sites), or None.
    site: SiteDocument | None = None
    #: The session's origin as a location fix (``lat_deg``, ``lon_deg``; ``unix_time_s``: the session's creation),
    #: or None: the phone pipeline takes the earth's magnetic field there
    #: (:meth:`pdr.phone.pipeline.PdrPipeline.use_location`).
    location: dict[str, float] | None = None


ProcessorFactory = Callable[[SessionContext, bytes | None], Processor]


def decode_payload(batch: BatchRecord) -> Recording | StepSummaryBatch:
    """What a raw batch holds for its processor: a :class:`Recording`, or foot step summaries (the form decoded at
    ingest, else parsed from the raw payload of rows stored before that form was kept).
    """
    if batch.payload_format == FOOT_STEPS_JSON:
        if batch.decoded is not None:
            from pdr.foot import summaries_codec
            return summaries_codec.loads(batch.decoded)
        from pdr.foot.summaries import steps_from_json
        source = f"batch '{batch.client_batch_id}'"
        return steps_from_json(_json(batch.payload, source), source=source)
    return decode_batch(batch)


def decode_batch(batch: BatchRecord) -> Recording:
    """The :class:`Recording` stored in a batch: the one decoded at ingest, else read from the raw payload (rows
    stored before decoded forms were); :class:`InputError` if it cannot be read.
    """
    if batch.decoded is not None:
        from pdr import recording_codec
        return recording_codec.loads(batch.decoded)
    fmt = batch.payload_format
    source = f"batch '{batch.client_batch_id}'"
    if fmt == NATIVE_JSON:
        from pdr.io.native import batch_from_json
        return batch_from_json(_json(batch.payload, source), source=source)
    if fmt == SENSOR_LOGGER_JSON:
        from pdr.io.sensor_logger import parse_push_message
        return parse_push_message(_json(batch.payload, source), source=source)
    if fmt.startswith(FILE_PREFIX):
        return read_uploaded_file(batch.payload, fmt[len(FILE_PREFIX):])
    raise InputError(f"unknown stored payload format '{fmt}'", source=source)


def _json(payload: bytes, source: str) -> Any:
    try:
        return json.loads(payload)
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid JSON ({exc})", source=source) from None


def read_uploaded_file(payload: bytes, descriptor: str) -> Recording:
    """Read an uploaded log file; ``descriptor`` is ``FORMAT/FILENAME`` (the name keeps suffixes like .gz).

    The reader runs in a resource-limited child process (:mod:`server.sandbox`): a file that crashes a
    parser or exhausts memory is an :class:`InputError`, not the end of the service.
    """
    from server.sandbox import read_isolated

    fmt, _, filename = descriptor.partition("/")
    return read_isolated(payload, filename, fmt or None)[1]


class SessionLocks:
    """One lock per session: one processing pass of a session at a time (within this process). Control requests do
    not take it (the results epoch fences a pass, :meth:`server.store.Store.fenced`). A session's lock lives while
    someone holds or waits for it (a weak mapping), so a long-running server keeps none for the sessions it processed.
    """

    def __init__(self) -> None:
        self._locks: weakref.WeakValueDictionary[str, threading.Lock] = weakref.WeakValueDictionary()
        self._guard = threading.Lock()

    def get(self, session_id: str) -> threading.Lock:
        with self._guard:
            return self._locks.setdefault(session_id, threading.Lock())


class SessionProcessing:
    """Processes the pending batches of sessions with the processors made by ``factory``."""

    #: Exceptions that are not the batch's fault (lost database connection, lost lease): re-raised for the
    #: caller to retry instead of marking the batch failed. Empty in the embedded default.
    transient: tuple[type[BaseException], ...] = ()

    @property
    def _passed_on(self) -> tuple[type[BaseException], ...]:
        """What the handling of a batch's or stage's failure re-raises: the session changed, or a transient error."""
        return (SessionChanged, *self.transient)

    def __init__(self, store: Store, factory: ProcessorFactory) -> None:
        self.store = store
        self.factory = factory
        self.locks = SessionLocks()

    def process_session(self, session_id: str) -> None:
        """Process every pending batch of the session, in time order; rebuild if one arrived late. Begin again when the
        session's results were cleared meanwhile; end when it was deleted (:class:`SessionChanged`).
        """
        with self.locks.get(session_id):
            processed = False
            while (epoch := self.store.results_epoch(session_id)) is not None:
                store = self.store.fenced(session_id, epoch)
                try:
                    if self._process_pending(store, session_id):
                        processed = True
                        continue
                    if processed:
                        self._fuse_feet(store, session_id)
                    store.end_rebuild(session_id)      # no batch pending: a rebuild's results are complete
                    self.finish(session_id, store)
                    return
                except SessionChanged as exc:
                    log.info("%s; processing it again from its stored batches if it still exists", exc)

    def _process_pending(self, store: Store, session_id: str) -> bool:
        """One pass over the session's pending batches (or the clear of a rebuild when one arrived late); False when
        none is pending.
        """
        pending = store.batches(session_id, ["pending"])
        if not pending:
            return False
        if self._arrived_late(store, session_id, pending):
            log.info("session %s: out-of-order batch, rebuilding from raw data", session_id)
            store.clear_results(session_id)
            return True
        last_of_role = {b.device_role: b.id for b in pending}
        live: dict[str, Processor] = {}  # processors kept between the batches of this pass
        for batch in pending:
            self._process_batch(store, session_id, batch, with_tail=last_of_role[batch.device_role] == batch.id,
                                live=live)
        return True

    def refuse_unrebuildable(self, session_id: str) -> None:
        """409 when the retention policy deleted raw batches of the session: its results could not be rebuilt."""
        if self.store.batch_summary(session_id).get(PURGED):
            raise APIError(409, "the raw data of this session was deleted by the retention policy "
                                "(PDR_RETENTION_DAYS): its results cannot be rebuilt")

    def clear(self, session_id: str) -> None:
        """Forget the session's results so that processing rebuilds them from raw batches (409 when it could not,
        :meth:`refuse_unrebuildable`). A pass running now writes nothing more.
        """
        self.refuse_unrebuildable(session_id)
        self.store.clear_results(session_id)

    @staticmethod
    def _arrived_late(store: Store, session_id: str, pending: list[BatchRecord]) -> bool:
        """Whether a pending batch ends at or before what its role has processed (it must go before): a batch that only
        starts there (a stream the phone sends a batch late, a sender that repeats the end of its last batch) goes on
        from it, as its processor merges each stream in time order.
        """
        for role in {b.device_role for b in pending}:
            _, watermark = store.load_state(session_id, role)
            lasts = [b.t_last_ns for b in pending if b.device_role == role and b.t_last_ns is not None]
            if watermark is not None and lasts and min(lasts) <= watermark:
                return True
        return False

    def _context(self, session_id: str, role: str) -> SessionContext:
        try:
            row = self.store.session_row(session_id)
        except APIError:    # its 404
            raise SessionChanged(f"session {session_id} was deleted during processing") from None
        placement = row.placement
        for dev in self.store.devices(session_id):
            if dev.role == role and dev.placement:
                placement = dev.placement
        meta = json.loads(row.meta or "{}")
        site = SiteStore(self.store.engine).session_site(session_id) if site_id_of(meta) else None
        location = None
        if row.origin_lat_deg is not None and row.origin_lon_deg is not None:
            created = row.created_at if row.created_at.tzinfo else row.created_at.replace(tzinfo=UTC)
            location = {"lat_deg": float(row.origin_lat_deg), "lon_deg": float(row.origin_lon_deg),
                        "unix_time_s": created.timestamp()}
        return SessionContext(session_id, role, placement, meta, site, location)

    def _process_batch(self, store: Store, session_id: str, batch: BatchRecord, with_tail: bool = True,
                       live: dict[str, Processor] | None = None) -> None:
        """Process one batch, writing through the pass's ``store``; ``live`` caches processors by role so that a pass
        restores each state once.
        """
        live = {} if live is None else live
        store.set_batch_status(batch.id, "processing")
        role = batch.device_role
        try:
            recording = decode_payload(batch)
            processor = live.pop(role, None)
            if processor is None:
                state, _ = store.load_state(session_id, role)
                processor = self.factory(self._context(session_id, role), state)
            if isinstance(recording, StepSummaryBatch):
                if not hasattr(processor, "update_steps"):
                    raise InputError(f"device role '{role}' does not take step summaries")
                out, last_t_ns = processor.update_steps(recording), recording.t_last_ns
            else:
                out = processor.update(recording)
                last_t_ns = max(int(s.t_ns[-1]) for s in recording.streams.values() if len(s))
            tail = processor.tail() if with_tail and hasattr(processor, "tail") else ProcessorOutput()
            store.commit_results(session_id, role, batch.id, processor.to_bytes(), last_t_ns,
                                 out.track, out.events, tail_track=tail.track, tail_events=tail.events)
            live[role] = processor  # only a processor whose state was committed is reused
            store.add_session_warnings(session_id, list(recording.warnings) + out.warnings)
            if (isinstance(recording, Recording) and recording.truth.positions is not None
                    and recording.truth.positions.origin_lat_lon_deg):
                lat, lon = recording.truth.positions.origin_lat_lon_deg
                store.set_session(session_id, origin_lat_deg=lat, origin_lon_deg=lon)
        except self._passed_on:
            raise
        except InputError as exc:
            store.set_batch_status(batch.id, "failed", str(exc))
        except Exception as exc:  # a processing bug must not lose the raw batch or stop the worker
            log.exception("processing batch %s of session %s failed", batch.id, session_id)
            store.set_batch_status(batch.id, "failed", f"internal processing error: {type(exc).__name__}: {exc}")

    def _fuse_feet(self, store: Store, session_id: str) -> None:
        """Session-level stages after a pass: the fused dual-foot track (role ``fused``, :mod:`server.fused_feet`),
        then the steps of the group agents that follow the session (:mod:`server.group_feed`).
        """
        from server.fused_feet import fuse_session  # on first use: only sessions with two feet need it
        from server.group_feed import feed_groups

        for what, stage in (("fused foot track", fuse_session), ("group feed", feed_groups)):
            try:
                stage(store, session_id)
            except self._passed_on:
                raise
            except InputError as exc:
                store.add_session_warnings(session_id, [f"{what}: {exc}"])
            except Exception as exc:  # a fusion bug must not stop the worker; the feet's own tracks stay
                log.exception("%s of session %s failed", what, session_id)
                store.add_session_warnings(session_id, [f"{what}: internal error: {type(exc).__name__}"])

    def finish(self, session_id: str, store: Store | None = None) -> None:
        """Set the session's status from its batches' (failed if one failed or is a dead letter); ``store``: the
        pass's (:meth:`server.store.Store.fenced`).
        """
        store = self.store if store is None else store
        summary = store.batch_summary(session_id)
        status = "failed" if summary.get("failed") or summary.get("dead") else ("done" if summary else "empty")
        store.set_session(session_id, status=status)
