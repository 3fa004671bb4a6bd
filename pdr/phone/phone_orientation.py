"""The phone's own fused attitude (the log's ``orientation`` stream, e.g. Android's rotation vector or an AHRS):
on the pipeline's grid, and as a yaw measurement of the attitude filter.

Frames: ``q_nb`` body -> ENU, Hamilton, scalar first (:mod:`pdr.frames`), as the readers give it.

- :func:`sign_continuous`: ``q`` and ``-q`` are one attitude; flipping the sign of each sample towards its
  predecessor makes the component-wise linear interpolation of the grid (:class:`pdr.phone.grid.OnlineGrid`),
  renormalised (:func:`grid_attitudes`), the normalised linear interpolation (nlerp) of the attitudes: the
  shorter arc, within 0.5 % of slerp's angle for the 10-20 ms sample spacing of a phone's sensors.
- :func:`yaw_difference`: the rotation about the navigation up axis that takes one attitude to another (the twist
  of ``q_a * conj(q_b)`` about up, rad), defined for any tilt of the device.
- :func:`phone_yaw_update`: the phone's yaw as a pseudo-measurement of the attitude filter's ``q``: a small
  navigation-frame rotation ``dpsi`` about up moves ``q`` by ``0.5 dpsi g``, ``g = [0, 0, 0, 1] * q`` (as in
  :func:`pdr.phone.heading.yaw_variance`), so the row is ``dpsi = 2 g^T dq``, linear to first order; the
  innovation is :func:`yaw_difference` (phone, ours). The row is gated against the filter's prediction: an
  innovation beyond ``gate_sigma`` standard deviations of ``4 g^T P g + var`` is not used, so a phone heading that
  is wrong (a disturbed field the phone's fusion follows) cannot drag a confident filter; with a large yaw
  covariance (the start of a walk) the phone's heading is taken.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.frames import wrap_angle

FloatArray = NDArray[np.float64]


def sign_continuous(q: FloatArray, prev: FloatArray | None = None) -> FloatArray:
    """``q`` (N, 4) with each sample's sign flipped so that consecutive quaternions (and the first with ``prev``,
    the sample before the batch) have a non-negative dot product.
    """
    q = np.array(q, dtype=np.float64, copy=True)
    if q.shape[0] == 0:
        return q
    dots = np.einsum("ij,ij->i", q[1:], q[:-1])
    flips = np.concatenate([[prev is not None and float(np.dot(q[0], prev)) < 0], dots < 0])
    # A flip of sample i flips every later sample's relation to its predecessor: cumulative parity.
    sign = np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)
    return q * sign[:, None]


def grid_attitudes(q: FloatArray) -> FloatArray:
    """The grid's linearly interpolated quaternions (N, 4) renormalised (nlerp); rows of zero norm become NaN."""
    n = np.linalg.norm(q, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n[:, None] > 1e-9, q / n[:, None], np.nan)


def yaw_difference(q_a: FloatArray, q_b: FloatArray) -> FloatArray:
    """Rotation (rad, counter-clockwise about up) taking attitude ``q_b`` to ``q_a``: the twist of
    ``d = q_a * conj(q_b)`` about the navigation up axis, ``2 atan2(d_z, d_w)`` wrapped to (-pi, pi].
    Works on (4,) or (N, 4).
    """
    a = np.asarray(q_a, dtype=np.float64)
    b = np.asarray(q_b, dtype=np.float64)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], -b[..., 1], -b[..., 2], -b[..., 3]
    dw = aw * bw - ax * bx - ay * by - az * bz
    dz = aw * bz + ax * by - ay * bx + az * bw
    return np.asarray(wrap_angle(2.0 * np.arctan2(dz, dw)))


def phone_yaw_update(q: FloatArray, p: FloatArray, q_phone: FloatArray, var: float, gate_sigma: float
                     ) -> tuple[FloatArray, FloatArray, bool]:
    """One yaw pseudo-measurement of the phone's attitude ``q_phone`` on the filter's ``q`` (4,) and ``P`` (4, 4).

    ``var``: the phone yaw's variance (rad^2); ``gate_sigma``: the largest innovation in standard deviations of
    the predicted innovation. Returns the updated (normalised) ``q``, ``P`` and whether the row was used.
    """
    q = np.asarray(q, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    if not np.all(np.isfinite(q_phone)):
        return q, p, False
    w, x, y, z = (float(v) for v in q)
    h = 2.0 * np.array([-z, -y, x, w])               # d psi / d q (module doc)
    ph = p @ h
    s = float(h @ ph) + var
    innov = float(yaw_difference(q_phone, q))
    if not s > 0 or innov * innov > gate_sigma * gate_sigma * s:
        return q, p, False
    k = ph / s
    q_new = q + k * innov
    p_new = p - np.outer(k, k) * s
    vals, vecs = np.linalg.eigh(0.5 * (p_new + p_new.T))
    p_new = (vecs * np.maximum(vals, 1e-12)) @ vecs.T
    return q_new / math.sqrt(float(q_new @ q_new)), 0.5 * (p_new + p_new.T), True
