"""Map matching: a particle filter over the phone pipeline's step events against a site's floor plans.

:mod:`pdr.mapmatch.particles` holds the online filter (``update(steps)``, bounded resumable state) and the
offline smoother over a whole walk, :mod:`pdr.mapmatch.kernel` its compiled per-step loop, :mod:`pdr.mapmatch.rows`
its application to a finished track's rows. It consumes the pipeline's output (one :class:`StepInput` per step
event), so that it can become a pipeline stage without changes to the filter.
"""

from pdr.mapmatch.particles import MapMatchConfig, MapMatcher, MatchedStep, StepInput, smooth_walk, steps_from_rows

__all__ = ["MapMatchConfig", "MapMatcher", "MatchedStep", "StepInput", "smooth_walk", "steps_from_rows"]
