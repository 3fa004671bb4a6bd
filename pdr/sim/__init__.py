"""Simulator: deterministic synthetic recordings with ground truth (phones in pocket, torso, hand; shoe IMUs).

``simulate(scenario, seed) -> Recording``; scenarios are JSON (:func:`load_scenario`,
:func:`parse_scenario`). See :mod:`pdr.sim.simulate` for what the ground truth holds; :func:`site_document`
gives a scenario's site description (its stairs, elevators and escalators as :class:`pdr.phone.landmarks.Site` JSON).
"""

from pdr.sim.scenario import Scenario, load_scenario, parse_scenario
from pdr.sim.simulate import simulate
from pdr.sim.site import site_document

__all__ = ["Scenario", "load_scenario", "parse_scenario", "simulate", "site_document"]
