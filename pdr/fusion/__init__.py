"""Cooperative localization: central fusion of several agents' step-wise dead reckoning and ranges (seed 001).

Architecture of seed 001 Sec. 3.3: each foot unit runs the step-wise inertial navigation (:mod:`pdr.foot`)
and sends one displacement / heading-change summary per step; each agent's device runs the step-wise dead
reckoning of its feet (:mod:`~pdr.fusion.agent`); a fusion centre (:mod:`~pdr.fusion.centre`, fed through the
time-ordering buffer of :mod:`~pdr.fusion.group` with the events of :mod:`~pdr.fusion.measurements`) keeps
the joint state of all feet of all agents (:mod:`~pdr.fusion.state`), propagates it with each summary
(:mod:`~pdr.fusion.dead_reckoning`, eqs. 7-8) and conditions it by state transformation
(:mod:`~pdr.fusion.transforms`, eq. 14) and marginalisation (:mod:`~pdr.fusion.marginalization`, eq. 12) on
the dual-foot separation constraint (:mod:`~pdr.fusion.constraints`, Algorithm 2), robust inter-agent ranges
(:mod:`~pdr.fusion.ranging`, Algorithm 3) and anchors, position fixes and pressure (:mod:`~pdr.fusion.aiding`).
Corrections flow back to the agents. :mod:`~pdr.fusion.simulation` reproduces the seed's simulations and
:mod:`pdr.evaluation.coop` computes the figures of ``pdr eval coop``.
"""
