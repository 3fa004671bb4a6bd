"""Foot-mounted inertial navigation: zero-velocity detectors, ZUPT-aided INS, step-wise dead reckoning.

Modules: :mod:`~pdr.foot.detectors` (SHOE, angular-rate energy, moving variance, magnitude; adaptive
threshold), :mod:`~pdr.foot.zupt` (error-state Kalman filter of seed 001 eqs. 1-5 with the recursive step
segmentation of Algorithm 1), :mod:`~pdr.foot.stepwise` (step-wise dead reckoning, eqs. 7-8),
:mod:`~pdr.foot.dual` (dual-foot fusion, seed 001 Sec. 4.2), :mod:`~pdr.foot.filterbank` (jump Markov filter
bank, seed 002), :mod:`~pdr.foot.bc` (belief condensation, seed 000) and :mod:`~pdr.foot.navigate` (recording in,
track out); their accuracy figures are in :mod:`pdr.evaluation.foot_metrics`.
"""
