"""Conditioning a Gaussian state on information about a few of its components (seed 001 eq. 12).

With ``z = [z_1, z_2]`` Gaussian (eq. 11) and information ``pi`` depending on ``z_1`` only, the conditional
moments of the whole state follow from the conditional mean ``z_1|pi`` and second moment ``C_{z_1|pi}``
(eq. 12), with ``U = P_{z1z2}^T P_{z1}^{-1}``, ``V = z_2 - U z_1``, ``Z = U z_1|pi V^T + V z_1|pi^T U^T``:

``z_2|pi = V + U z_1|pi``
``P_{z1|pi} = C_{z1|pi} - z_1|pi z_1|pi^T``
``P_{z2|pi} = P_{z2} - U P_{z1z2} + V V^T + Z + U C_{z1|pi} U^T - z_2|pi z_2|pi^T``
``P_{z1z2|pi} = z_1|pi V^T + C_{z1|pi} U^T - z_1|pi z_2|pi^T``.

Substituting ``C_{z1|pi} = P_{z1|pi} + z_1|pi z_1|pi^T`` cancels the mean products exactly:
``P_{z2|pi} = P_{z2} - U P_{z1z2} + U P_{z1|pi} U^T`` and ``P_{z1z2|pi} = P_{z1|pi} U^T``. We evaluate that
central form: it is the same expression, but does not subtract products of large means (positions hundreds
of metres from the origin) to get covariances of a few centimetres. The caller therefore passes the
conditional *covariance* ``P_{z1|pi}`` (a sampler computes it about its own mean).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.fusion.transforms import SubsetTransform

Array = NDArray[np.float64]


def gain(cov_z1: Array, cov_z1z2: Array, atol: float = 1e-14) -> Array:
    """``U = P_{z1z2}^T P_{z1}^{-1}`` (eq. 12), (m - n1, n1).

    ``P_{z1}`` is inverted on its eigenvalues above ``max(atol, 1e-12 * largest)`` (units of ``z_1`` squared,
    m^2 for positions): directions of ``z_1`` known exactly (e.g. agents that start at surveyed points, or
    rounding residue of a covariance that is zero in exact arithmetic) carry no correlation to ``z_2``.
    """
    lam, q = np.linalg.eigh(0.5 * (cov_z1 + cov_z1.T))
    keep = lam > max(atol, 1e-12 * float(np.max(lam, initial=0.0)))
    if not np.any(keep):
        return np.zeros((cov_z1z2.shape[1], cov_z1.shape[0]))
    qk = q[:, keep]
    return np.asarray(((qk / lam[keep]) @ (qk.T @ cov_z1z2)).T)


def marginalize(z: Array, cov_z: Array, n1: int, z1_post: Array, cov_z1_post: Array) -> tuple[Array, Array]:
    """Conditional mean and covariance of ``z`` given the conditional moments of ``z_1`` (eq. 12).

    Parameters
    ----------
    z
        (m,) prior mean ``[z_1, z_2]``.
    cov_z
        (m, m) prior covariance (eq. 11).
    n1
        Size of ``z_1``.
    z1_post
        (n1,) conditional mean ``z_1|pi``.
    cov_z1_post
        (n1, n1) conditional covariance ``P_{z1|pi} = C_{z1|pi} - z_1|pi z_1|pi^T``.

    Returns
    -------
    z_post, cov_post
        (m,) and (m, m) conditional moments of ``z``.
    """
    m = z.size
    if not 0 < n1 <= m or cov_z.shape != (m, m):
        raise InputError(f"z_1 must be 1..{m} leading components of a state with a matching covariance",
                         field="n1")
    z1_post = np.asarray(z1_post, dtype=np.float64).reshape(n1)
    cov_z1_post = np.asarray(cov_z1_post, dtype=np.float64).reshape(n1, n1)
    p1 = cov_z[:n1, :n1]
    p12 = cov_z[:n1, n1:]
    u = gain(p1, p12)
    z_post = np.empty(m)
    z_post[:n1] = z1_post
    z_post[n1:] = z[n1:] + u @ (z1_post - z[:n1])                   # V + U z_1|pi
    cov_post = np.empty((m, m))
    cov_post[:n1, :n1] = cov_z1_post
    cross = cov_z1_post @ u.T                                         # P_{z1z2|pi}
    cov_post[:n1, n1:] = cross
    cov_post[n1:, :n1] = cross.T
    cov_post[n1:, n1:] = cov_z[n1:, n1:] - u @ p12 + u @ cross       # P_{z2} - U P_{z1z2} + U P_{z1|pi} U^T
    cov_post = 0.5 * (cov_post + cov_post.T)
    return z_post, cov_post


def condition_on_transformed(mean: Array, cov: Array, transform: SubsetTransform,
                             posterior: Callable[[Array, Array], tuple[Array, Array] | None]) -> tuple[Array, Array]:
    """Transform, condition ``z_1``, marginalise, transform back (Algorithms 2 and 3 of seed 001).

    ``z = T x``, ``P_z = T P T^T`` (line 1); ``posterior(z_1, P_{z1})`` returns the conditional moments of
    ``z_1`` (or ``None`` when the information leaves the prior unchanged); eq. 12 gives those of ``z``; and
    ``x = T^{-1} z``, ``P = T^{-1} P_z T^{-T}`` (last line). The moments of ``z_1`` are computed first, so
    information that changes nothing costs no full transformation (the inputs are then returned as they are).
    """
    post = posterior(*transform.leading(mean, cov))
    if post is None:
        return mean, cov
    z, cov_z = transform.forward(mean, cov)
    n1 = transform.n1
    z_post, cov_z_post = marginalize(z, cov_z, n1, post[0], post[1])
    x, p = transform.inverse(z_post, cov_z_post)
    return x, 0.5 * (p + p.T)
