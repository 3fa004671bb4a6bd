"""Unit quaternions, vectorised over leading axes.

Convention (see :mod:`pdr.frames`): Hamilton product, scalar first ``q = [w, x, y, z]``; ``q_nb``
rotates a body-frame vector into the navigation frame, ``v_n = q_nb * v_b * conj(q_nb)``.
``q`` and ``-q`` are the same rotation: compare with :func:`angle_between`, not element-wise.
Rotation vectors ``phi`` are axis * angle in radians.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def normalize(q: ArrayLike) -> Array:
    """Unit quaternion(s) with non-negative scalar part (sign canonicalised)."""
    arr = np.asarray(q, dtype=np.float64)
    unit = arr / np.linalg.norm(arr, axis=-1, keepdims=True)
    return np.where(unit[..., :1] < 0, -unit, unit)


def conjugate(q: ArrayLike) -> Array:
    """Inverse of a unit quaternion: ``q_bn = conjugate(q_nb)``."""
    q = np.asarray(q, dtype=np.float64)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def multiply(p: ArrayLike, q: ArrayLike) -> Array:
    """Hamilton product ``p * q`` (apply ``q`` first, then ``p``): ``q_ac = multiply(q_ab, q_bc)``."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def rotate(q: ArrayLike, v: ArrayLike) -> Array:
    """Rotate vector(s) ``v`` (..., 3) by ``q`` (..., 4): ``v_n = rotate(q_nb, v_b)``."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def from_rotvec(phi: ArrayLike) -> Array:
    """Exponential map: rotation vector(s) (..., 3) in rad to unit quaternion(s)."""
    phi = np.asarray(phi, dtype=np.float64)
    angle = np.linalg.norm(phi, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(a/2)/a with its Taylor series near zero to stay exact for tiny rotations.
    small = angle < 1e-8
    k = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half), k * phi], axis=-1)


def to_rotvec(q: ArrayLike) -> Array:
    """Logarithm map: unit quaternion(s) to rotation vector(s) in rad, angle in [0, pi]."""
    q = normalize(q)
    w = np.clip(q[..., :1], -1.0, 1.0)
    s = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-12
    # Each branch divides only where it is selected (np.where evaluates both): near identity w ~ 1.
    k = np.where(small, 2.0 / np.where(small, w, 1.0), angle / np.where(small, 1.0, s))
    return k * q[..., 1:]


def boxplus(q: ArrayLike, delta: ArrayLike) -> Array:
    """``q ⊞ delta``: perturb attitude ``q_nb`` by a navigation-frame rotation vector ``delta`` (rad)."""
    return multiply(from_rotvec(delta), q)


def boxminus(q: ArrayLike, p: ArrayLike) -> Array:
    """``q ⊟ p``: the navigation-frame rotation vector ``delta`` with ``p ⊞ delta = q`` (rad)."""
    return to_rotvec(multiply(q, conjugate(p)))


def angle_between(q: ArrayLike, p: ArrayLike) -> Array:
    """Rotation angle (rad, in [0, pi]) between two attitudes; sign-invariant."""
    d = np.abs(np.sum(normalize(q) * normalize(p), axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def to_rotmat(q: ArrayLike) -> Array:
    """Rotation matrix (..., 3, 3) ``C_nb`` of ``q_nb``: ``v_n = C_nb @ v_b``."""
    w, x, y, z = np.moveaxis(normalize(q), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def from_rotmat(c: ArrayLike) -> Array:
    """Unit quaternion(s) of rotation matrix(es) ``C_nb`` (..., 3, 3) (Shepperd's method)."""
    c = np.asarray(c, dtype=np.float64)
    tr = np.trace(c, axis1=-2, axis2=-1)
    cand = np.stack([
        np.stack([1 + tr, c[..., 2, 1] - c[..., 1, 2], c[..., 0, 2] - c[..., 2, 0], c[..., 1, 0] - c[..., 0, 1]], -1),
        np.stack([c[..., 2, 1] - c[..., 1, 2], 1 + 2 * c[..., 0, 0] - tr, c[..., 0, 1] + c[..., 1, 0],
                  c[..., 0, 2] + c[..., 2, 0]], -1),
        np.stack([c[..., 0, 2] - c[..., 2, 0], c[..., 0, 1] + c[..., 1, 0], 1 + 2 * c[..., 1, 1] - tr,
                  c[..., 1, 2] + c[..., 2, 1]], -1),
        np.stack([c[..., 1, 0] - c[..., 0, 1], c[..., 0, 2] + c[..., 2, 0], c[..., 1, 2] + c[..., 2, 1],
                  1 + 2 * c[..., 2, 2] - tr], -1),
    ], axis=-2)
    diag = np.stack([tr, c[..., 0, 0], c[..., 1, 1], c[..., 2, 2]], axis=-1)
    best = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    return normalize(q)


def from_euler(roll: ArrayLike, pitch: ArrayLike, yaw: ArrayLike) -> Array:
    """``q_nb`` from ZYX (yaw about up, then pitch, then roll) Euler angles in rad.

    Yaw is counter-clockwise about the navigation z axis (ENU: from east towards north).
    """
    r, p, y = (np.asarray(a, dtype=np.float64) for a in (roll, pitch, yaw))
    qz = np.stack([np.cos(y / 2), 0 * y, 0 * y, np.sin(y / 2)], axis=-1)
    qy = np.stack([np.cos(p / 2), 0 * p, np.sin(p / 2), 0 * p], axis=-1)
    qx = np.stack([np.cos(r / 2), np.sin(r / 2), 0 * r, 0 * r], axis=-1)
    return multiply(multiply(qz, qy), qx)


def to_euler(q: ArrayLike) -> tuple[Array, Array, Array]:
    """ZYX Euler angles (roll, pitch, yaw) in rad of ``q_nb``; inverse of :func:`from_euler`."""
    w, x, y, z = np.moveaxis(normalize(q), -1, 0)
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def from_two_vectors(a: ArrayLike, b: ArrayLike) -> Array:
    """Shortest rotation taking direction ``a`` onto direction ``b`` (both (..., 3))."""
    ua = np.asarray(a, dtype=np.float64)
    ub = np.asarray(b, dtype=np.float64)
    ua = ua / np.linalg.norm(ua, axis=-1, keepdims=True)
    ub = ub / np.linalg.norm(ub, axis=-1, keepdims=True)
    w = 1.0 + np.sum(ua * ub, axis=-1, keepdims=True)
    xyz = np.cross(ua, ub)
    # Opposite vectors: rotate by pi about any axis orthogonal to a.
    opposite = w[..., 0] < 1e-12
    if np.any(opposite):
        alt = np.cross(ua, np.array([1.0, 0.0, 0.0]))
        alt = np.where(np.linalg.norm(alt, axis=-1, keepdims=True) < 1e-6, np.cross(ua, [0.0, 1.0, 0.0]), alt)
        xyz = np.where(opposite[..., None], alt, xyz)
        w = np.where(opposite[..., None], 0.0, w)
    return normalize(np.concatenate([w, xyz], axis=-1))


def average(q: ArrayLike, weights: ArrayLike | None = None) -> Array:
    """Weighted mean attitude of quaternions (N, 4): principal eigenvector of sum w q q^T (Markley 2007)."""
    q = np.asarray(q, dtype=np.float64)
    w = np.ones(q.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    m = np.einsum("n,ni,nj->ij", w, q, q)
    _, vecs = np.linalg.eigh(m)
    return normalize(vecs[:, -1])


def integrate_gyro(q0: ArrayLike, gyro_b: ArrayLike, dt_s: ArrayLike) -> Array:
    """Attitude sequence from body angular rates: ``q_k+1 = q_k * exp(omega_k dt_k)``.

    Parameters
    ----------
    q0
        (4,) initial ``q_nb``.
    gyro_b
        (N, 3) angular rate in rad/s, body frame, held over each interval.
    dt_s
        (N,) interval lengths in s.

    Returns
    -------
    (N + 1, 4) attitudes, the first being ``q0``.
    """
    dq = from_rotvec(np.asarray(gyro_b, dtype=np.float64) * np.asarray(dt_s, dtype=np.float64)[:, None])
    out = np.empty((dq.shape[0] + 1, 4))
    out[0] = normalize(q0)
    for k in range(dq.shape[0]):
        out[k + 1] = multiply(out[k], dq[k])
    return normalize(out)
