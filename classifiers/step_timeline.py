"""The service's modes timeline of a whole recording, offline: what ``/modes`` lists for a phone that no installed
mode classifier takes (hand-held, torso, a swinging hand), and what ``pdr classify`` writes for one.

The phone pipeline (:class:`pdr.phone.pipeline.PdrPipeline`, placement from the log's metadata or detected online)
gives per-step modes, :class:`classifiers.timeline.StepModes` turns them into entries (a stairs entry needs a
flight), :class:`classifiers.timeline.StopTimeline` adds the stops and the elevator and escalator rides, placed
among the steps as the service places them (:func:`server.phone_processor.convert_events`). Each step takes the
label of the latest entry opened at or before its start (a stop or ride covers only its own interval).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from classifiers.timeline import ModeEntry, StepModes, StopTimeline
from pdr.phone.configure import pipeline_config, placement_group
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline
from pdr.recording import Recording


@dataclass(frozen=True)
class StepTimeline:
    """The service's step-mode timeline of one recording: step intervals and the label each step shows, the stop
    and ride entries, and every entry as ``/modes`` lists it (``opened``: ``(t_s, label)`` in time order).
    """

    step_t0_s: np.ndarray
    step_t1_s: np.ndarray
    step_label: np.ndarray
    entries: tuple[ModeEntry, ...]
    opened: tuple[tuple[float, str], ...] = ()
    #: The placement the pipeline used (given or detected; None before its first stride).
    placement: str | None = None

    def spans(self, t_end_s: float) -> list[tuple[float, float, str]]:
        """Every entry as ``(t_start_s, t_end_s, label)``: a stop or ride to its own end, any other to the next
        entry's start (the last one to ``t_end_s``, s).
        """
        own_end = {(en.t_start_s, en.label): en.t_end_s for en in self.entries}
        out = []
        for i, (t, label) in enumerate(self.opened):
            nxt = self.opened[i + 1][0] if i + 1 < len(self.opened) else max(t_end_s, t)
            out.append((t, min(nxt, own_end.get((t, label), nxt)), label))
        return out

    def label_at(self, t_s: np.ndarray) -> np.ndarray:
        """The timeline's label at each time (s): the latest entry opened at or before it (``""`` before any)."""
        times = np.array([t for t, _ in self.opened])
        names = np.array([lab for _, lab in self.opened] or [""], dtype=object)
        idx = np.searchsorted(times, np.asarray(t_s, dtype=np.float64), side="right") - 1
        return np.where(idx >= 0, names[np.clip(idx, 0, None)], "").astype(object)


#: A function giving a recording's step-mode timeline (to compute it once for several figures).
TimelineOf = Callable[[Recording], StepTimeline]


def step_timeline(rec: Recording, site: Site | None = None, placement: str | None = None) -> StepTimeline:
    """Run the pipeline over ``rec`` in one batch and build its step-mode timeline (module docstring); ``site``:
    the building's floor height or floor altitudes (None: the default floor height); ``placement``: the pipeline
    placement (``pocket``, ``hand``, ``torso``, ``swinging``, ``auto``; None: from the log's metadata, else auto).
    """
    pipe = PdrPipeline(pipeline_config(placement or placement_group(rec.device.placement)), site)
    stops = StopTimeline()
    events = pipe.update(rec)
    entries = list(stops.update(rec, events))
    tail = pipe.finish()
    entries += stops.finish(tail)
    events = list(events) + list(tail)
    modes = StepModes()
    steps: list[dict[str, Any]] = [dict(e) for e in events if e.get("type") == "step"]
    opened: list[tuple[float, str]] = []
    pending = sorted(entries, key=lambda m: m.t_start_s)
    for e in steps:  # as server.phone_processor.convert_events: an entry placed before the step after it
        t_start = float(e.get("t_start_s", e["t_s"]))
        while pending and pending[0].t_start_s <= t_start:
            en = pending.pop(0)
            opened.append((en.t_start_s, en.label))
            modes.entry(en.label, en.t_end_s)
        opened += modes.step(str(e.get("mode") or ""), t_start, float(e["t_s"]))
    opened += [(en.t_start_s, en.label) for en in pending]
    opened.sort()
    t0 = np.array([float(e.get("t_start_s", e["t_s"])) for e in steps])
    t1 = np.array([float(e["t_s"]) for e in steps])
    tl = StepTimeline(t0, t1, np.zeros(0, dtype=object), tuple(sorted(entries, key=lambda m: m.t_start_s)),
                      tuple(opened), pipe.placement)
    label = tl.label_at(t0 + 1e-9)
    for en in entries:  # a step inside a stop or ride shows that entry
        label[(t0 >= en.t_start_s) & (t1 <= en.t_end_s)] = en.label
    return replace(tl, step_label=label)
