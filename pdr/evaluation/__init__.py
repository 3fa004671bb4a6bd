"""Evaluation and benchmarks: figures against ground truth and speed, apart from the product code.

Product modules (``pdr`` outside this package and :mod:`pdr.cli`, ``classifiers``, ``server``) never import it;
the ``pdr eval`` and ``pdr bench`` commands do. Modules: :mod:`~pdr.evaluation.scoring` (landmark, waypoint,
distance and step-count errors of phone tracks), :mod:`~pdr.evaluation.error_budget` (how much of a track's
error heading and step-length scale explain), :mod:`~pdr.evaluation.phone_bench` (``pdr bench phone``),
:mod:`~pdr.evaluation.foot_metrics` (foot navigation against VICON, loop closure and footprints),
:mod:`~pdr.evaluation.foot_crossval` (two-fold learning study of the filter bank and BC),
:mod:`~pdr.evaluation.foot_speed` (foot navigators' CPU cost and memory) and :mod:`~pdr.evaluation.coop`
(``pdr eval coop``, cooperative localisation), :mod:`~pdr.evaluation.heading`
(``pdr eval heading``, walking direction and attitude against motion capture).
"""
