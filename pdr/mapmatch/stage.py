"""The map matcher as a stage of the phone pipeline (:class:`pdr.phone.stage.StepStage`): online, step by step.

Each step event's length and heading move the particles (:class:`pdr.mapmatch.particles.MapMatcher`); the step is
emitted at the particles' estimate on the floor plan, and the pipeline's track is moved there, so that the positions
the pipeline goes on from and the positions it emits agree. The floors of the step events are relative to the walk's
first step; the stage adds them to the site floor the walk starts on, as :func:`pdr.mapmatch.rows.match_rows` does.
Its state (the matcher's, of fixed size, and that first step's floor) resumes bit-identically.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from pdr.mapmatch.particles import MapMatchConfig, MapMatcher, step_input
from pdr.phone.events import NoticeEvent, PipelineEvent, StepEvent
from pdr.phone.track import TrackState
from pdr.site.plan import SitePlan

#: Position variance (m^2) given to the pipeline's track when it is moved to the matched position.
MATCHED_VAR_M2 = 1.0


class MapMatchStage:
    """Map matching on ``site`` from a known ``start_en`` (m, site frame) on site floor ``floor``."""

    name = "map_match"

    def __init__(self, site: SitePlan, start_en: tuple[float, float], floor: int,
                 config: MapMatchConfig | None = None, source: str = "start") -> None:
        self.site, self.start_en, self.start_floor = site, start_en, int(floor)
        self.config = config or MapMatchConfig()
        self.matcher = MapMatcher(site, start_en, floor, self.config, source=source)
        self.first_step_floor: int | None = None

    def step(self, event: StepEvent, track: TrackState) -> tuple[StepEvent, list[PipelineEvent]]:
        """The step at its matched position (and floor), the track moved there, and the matcher's notices."""
        if self.first_step_floor is None:
            self.first_step_floor = int(round(float(event.floor)))
        s = step_input(event.t_s, event.step_length_m, event.heading_deg, event.floor, event.gyro_heading_deg,
                       self.start_floor - self.first_step_floor)
        (m,), notices = self.matcher.update([s])
        track.fix(m.east_m, m.north_m, MATCHED_VAR_M2)
        matched = replace(event, east_m=m.east_m, north_m=m.north_m, floor=float(m.floor))
        return matched, [NoticeEvent(message=n) for n in notices]

    def state(self) -> dict[str, Any]:
        return {"matcher": self.matcher.state(), "first_step_floor": self.first_step_floor}

    def from_state(self, d: dict[str, Any]) -> MapMatchStage:
        """A stage like this one (site, start, configuration) with the saved state ``d``."""
        out = MapMatchStage.__new__(MapMatchStage)
        out.site, out.start_en, out.start_floor, out.config = self.site, self.start_en, self.start_floor, self.config
        out.matcher = MapMatcher.from_state(self.site, d["matcher"], self.config)
        out.first_step_floor = None if d["first_step_floor"] is None else int(d["first_step_floor"])
        return out
