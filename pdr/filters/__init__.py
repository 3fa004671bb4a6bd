"""Generic pieces of the recursive estimators: unscented transform and Kalman filter (attitude and heading filters),
Rauch-Tung-Striebel smoother, compiled small linear algebra and rotation kernels for the per-sample loops.
"""
