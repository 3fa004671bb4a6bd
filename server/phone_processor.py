"""The phone PDR pipeline (:class:`pdr.phone.pipeline.PdrPipeline`) and motion-mode classifier as a session processor.

Pipeline events (typed, :mod:`pdr.phone.events`) become results: each step is stored as it is, one track row
holding the whole :class:`~pdr.phone.events.StepEvent` (its fields include the inputs of the offline heading smoother,
:mod:`pdr.phone.heading_smoother`, for ``GET .../track?heading=smoothed``); elevator rides and site landmarks
``landmark`` events; floor changes ``floor`` events; notices session warnings. Motion modes
come from the streaming classifier (:class:`classifiers.streaming.StreamingClassifier`, one ``mode`` event per
window with its confidence) of the model for the placement the pipeline has found
(:func:`classifiers.installed.placement_model`: the shipped pocket model, or a hand-held/torso model when one is
installed); for placements without a model, or when the recording lacks a sensor the model needs, from the
pipeline's per-step modes, with the stops and elevator rides of :class:`classifiers.timeline.StopTimeline`
(``standing`` for 2 s or more without a step and with a still phone; ``elevator_up/down`` with the floor change).
The provisional tail (:meth:`PhoneProcessor.tail`) is what :meth:`PdrPipeline.finish` would add if the
session ended now, so a session's track equals ``pdr track --smoother off`` on the same data at any time, and
``?heading=smoothed`` equals ``pdr track`` -- with the session's processing options
(:mod:`server.processing_options`) as ``--site`` and ``--calibration``; a session naming an uploaded site with a
start (:mod:`server.sites`) runs the map matcher as a pipeline stage, as ``pdr track --site S --start E,N
--smoother off``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields

from classifiers.installed import PLACEMENT_MODELS, placement_model
from classifiers.streaming import StreamingClassifier
from classifiers.timeline import ModeEntry, StepModes, StopTimeline
from pdr import state_codec
from pdr.errors import InputError
from pdr.geomagnetic import field_at_fix
from pdr.phone.configure import pipeline_config, placement_group
from pdr.phone.events import (
    ElevatorEvent,
    FloorChangeEvent,
    LandmarkEvent,
    NoticeEvent,
    PipelineEvent,
    StairFlightEvent,
    StepEvent,
    to_rows,
)
from pdr.phone.pipeline import PdrPipeline
from pdr.recording import LOCATION_META, Recording
from server.processing import ProcessorOutput, SessionContext
from server.processing_options import session_options
from server.sites import session_site
from server.store import EventRow

#: Session warning: the first batch's ``meta.location`` has no date, so the session's origin gave the earth's field.
UNDATED_FIX_ORIGIN = ("meta.location has no unix_time_s (s since 1970, UTC): the earth's magnetic field is taken at "
                      "the session's origin, on the session's creation date, instead")
#: Session warning: a batch's ``meta.location`` has no date and no other fix gave the earth's field.
UNDATED_FIX_UNUSED = ("meta.location has no unix_time_s (s since 1970, UTC): the earth's magnetic field there is not "
                      "known, so the magnetometer is not checked against it; send the fix's time")


class PhoneProcessor:
    """Online phone PDR and motion modes of one session; its state is stored with :mod:`pdr.state_codec`."""

    def __init__(self, ctx: SessionContext, state: bytes | None) -> None:
        self.classifier: StreamingClassifier | None = None
        options = session_options(ctx.meta)
        named = session_site(options, ctx.site)
        self.stages = [] if named is None else named.stages()   # the map matcher when the session has a start
        self._session_fix: dict[str, float] | None = None
        if state:
            d = state_codec.loads(state)
            self.pipeline = PdrPipeline.from_state(d["pipeline"], stages=self.stages)
            self.step_modes = (StepModes.from_state(d["step_modes"]) if d.get("step_modes")
                               else StepModes(str(d.get("last_mode", ""))))
            self.classifier_status: str = d.get("classifier_status", "pending")
            if d.get("classifier") is not None:
                self.classifier = StreamingClassifier.from_state(d["classifier"])
            self.stops = StopTimeline.from_state(d["stops"]) if d.get("stops") else StopTimeline()
        else:
            self.stops = StopTimeline()
            config = pipeline_config(placement_group(ctx.placement), step_length=options.step_length)
            site = options.site if named is None else named.checked.site
            self.pipeline = PdrPipeline(config, site, stages=self.stages)
            # The session's origin: where the earth's field is taken unless the first batch has its own dated fix.
            self._session_fix = ctx.location
            self.step_modes = StepModes()
            self.classifier_status = "pending"

    def update(self, recording: Recording) -> ProcessorOutput:
        events: list[PipelineEvent] = []
        fix = recording.meta.get(LOCATION_META)
        undated = fix is not None and field_at_fix(fix) is None     # accepted: it geo-references, but no field
        origin_used = False
        if self._session_fix is not None:
            # A new session's first batch: its own dated fix (a log's GNSS, with the log's date) goes first.
            if fix is None or undated:
                events += self.pipeline.use_location(self._session_fix)
                origin_used = undated
            self._session_fix = None
        events += self.pipeline.update_events(recording)
        modes, notice = self._classify(recording)
        stops = self.stops.update(recording, to_rows(events))
        step_modes = self.classifier_status != "active"
        out = convert_events(events, self.step_modes, step_modes=step_modes, stops=stops if step_modes else ())
        out.events += modes
        if notice:
            out.warnings.append(notice)
        if origin_used:
            out.warnings.append(UNDATED_FIX_ORIGIN)
        elif undated and self.pipeline.attitude.config.earth_dip_deg is None:
            out.warnings.append(UNDATED_FIX_UNUSED)
        return out

    def _classify(self, recording: Recording) -> tuple[list[EventRow], str]:
        """Mode events of the windows this batch completes; a notice when the classifier is turned off."""
        if self.classifier_status == "off" or self.pipeline.placement is None:
            return [], ""
        name = placement_model(self.pipeline.placement)
        if name is None:
            self.classifier, self.classifier_status = None, "off"
            wanted = PLACEMENT_MODELS.get(self.pipeline.placement)
            # The session may name no placement: then say that the pipeline found it, not that it was given.
            how = ("detected as carried in the {} (the session names no placement)" if self.pipeline.auto_placement
                   else "carried in the {}").format(self.pipeline.placement)
            return [], (f"motion modes from step patterns only: no mode classifier is installed for a phone {how}"
                        + (f" (models/{wanted}; its model card says how to build it)" if wanted else ""))
        try:
            if self.classifier is None:
                self.classifier = StreamingClassifier(name)
            results = self.classifier.update(recording)
        except InputError as exc:
            self.classifier, self.classifier_status = None, "off"
            return [], f"motion modes from step patterns only: the mode classifier cannot use this data ({exc})"
        # Waiting for the first sample of a stream the model needs (a sensor the phone starts a batch late): the step
        # modes go on meanwhile (StreamingClassifier.update).
        self.classifier_status = "pending" if self.classifier.waiting else "active"
        return [EventRow("mode", r.t_start_s, t_end_s=r.t_end_s, label=r.mode, value=r.confidence,
                         data={"window_mode": r.window_mode}) for r in results], ""

    def tail(self) -> ProcessorOutput:
        copy = PdrPipeline.from_state(self.pipeline.state(), stages=self.stages)
        events = copy.finish_events()
        step_modes = self.classifier_status != "active"
        out = convert_events(events, StepModes.from_state(self.step_modes.state()), step_modes=step_modes,
                             stops=self.stops.pending(to_rows(events)) if step_modes else ())
        return out

    def to_bytes(self) -> bytes:
        return state_codec.dumps({"pipeline": self.pipeline.state(), "step_modes": self.step_modes.state(),
                                  "classifier_status": self.classifier_status,
                                  "classifier": None if self.classifier is None else self.classifier.state(),
                                  "stops": self.stops.state()})


def convert_events(events: Sequence[PipelineEvent], modes: StepModes | None = None, step_modes: bool = True,
                   stops: Sequence[ModeEntry] = ()) -> ProcessorOutput:
    """Results of pipeline events: the step events themselves (stored as they are), the other kinds as result
    events and warnings; ``modes`` (updated) is the timeline's step-mode state.

    ``step_modes``: also emit a ``mode`` event where the pipeline's per-step mode changes
    (:class:`classifiers.timeline.StepModes`: a stairs entry needs a flight of steps). ``stops``: stop and
    elevator entries (:class:`classifiers.timeline.StopTimeline`), each a ``mode`` event with its end, placed
    among the steps by time; the step after one emits its mode again.
    """
    modes = StepModes() if modes is None else modes
    out = ProcessorOutput()
    pending = sorted(stops, key=lambda m: m.t_start_s)
    for e in events:
        if isinstance(e, StepEvent):
            while pending and pending[0].t_start_s <= e.t_start_s:
                _stop_row(out, pending.pop(0), modes)
            out.track.append(e)
            for t, label in modes.step(e.mode, e.t_start_s, e.t_s):
                if step_modes:
                    out.events.append(EventRow("mode", t, label=label))
        elif isinstance(e, ElevatorEvent):
            out.events.append(EventRow("landmark", e.t_start_s, t_end_s=e.t_end_s, label="elevator",
                                       data=_scalars(e)))
        elif isinstance(e, LandmarkEvent):
            out.events.append(EventRow("landmark", e.t_s, label=e.mode or e.landmark or "landmark", data=_scalars(e)))
        elif isinstance(e, StairFlightEvent):
            out.events.append(EventRow("landmark", e.t_start_s, t_end_s=e.t_end_s, label="stair_flight",
                                       data=_scalars(e)))
        elif isinstance(e, FloorChangeEvent):
            out.events.append(EventRow("floor", e.t_s, value=float(e.floor), label="floor"))
        elif isinstance(e, NoticeEvent):
            out.warnings.append(e.message)
    while pending:
        _stop_row(out, pending.pop(0), modes)
    return out


def _scalars(e: ElevatorEvent | LandmarkEvent | StairFlightEvent) -> dict[str, str | int | float]:
    """The event's fields with a value (besides ``t_s``) as a landmark event's data."""
    values = {f.name: getattr(e, f.name) for f in fields(e) if f.name != "t_s"}
    return {k: v for k, v in values.items() if isinstance(v, str | int | float)}


def _stop_row(out: ProcessorOutput, m: ModeEntry, modes: StepModes) -> None:
    """Append the ``mode`` event of a stop or elevator entry, which then holds the timeline."""
    out.events.append(EventRow("mode", m.t_start_s, t_end_s=m.t_end_s, label=m.label, data=dict(m.data)))
    modes.entry(m.label, m.t_end_s)
