"""Sigma points and weights of the unscented transform (seed 003 eqs. 35-37)."""

import math

import numpy as np

from pdr.filters.ukf import SigmaPoints


def test_sigma_point_weights_sum_to_one():
    wm, wc = SigmaPoints(4).weights()
    assert math.isclose(wm.sum(), 1.0, abs_tol=1e-6)
    sp = SigmaPoints(2, alpha=0.5)
    x, p = np.array([1.0, 2.0]), np.array([[2.0, 0.3], [0.3, 1.0]])
    wm, wc = sp.weights()
    sig = sp.sigma_points(x, p)
    d = sig - wm @ sig
    assert np.allclose(wm @ sig, x) and np.allclose((d * wc[:, None]).T @ d, p)
