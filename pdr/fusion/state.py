"""Global state of the cooperative fusion: position and heading of every foot of every agent.

Seed 001 Sec. 4 writes the global state as ``x = [x_alpha, chi_alpha, x_beta, chi_beta, ...]``: for each
foot (navigation point) its position ``x_j`` (3, m, ENU navigation frame) and its heading ``chi_j`` (rad,
counter-clockwise yaw from east, Sec. 3.2). Only the mean and the joint covariance are kept (Sec. 4: "the
high dimensionality is tackled by only propagating the mean and covariance estimates"). Each foot also
carries the time of its last step-wise dead-reckoning update and the number of updates applied, since the
feet are updated asynchronously (Sec. 4.2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Entries per foot in the global state: x, y, z (m) and heading chi (rad).
FOOT_DIM = 4
#: Offsets of the position and heading inside a foot's block.
POS = slice(0, 3)
HEADING = 3


@dataclass(frozen=True, order=True)
class FootKey:
    """Names one navigation point: ``agent`` (group-unique id) and ``foot`` (e.g. ``"left"``)."""

    agent: str
    foot: str

    def __str__(self) -> str:
        return f"{self.agent}/{self.foot}"


def as_cov(value: ArrayLike, n: int, field: str) -> Array:
    """A finite symmetric positive semi-definite (n, n) covariance, or InputError naming ``field``."""
    c = np.asarray(value, dtype=np.float64)
    if c.shape != (n, n) or not np.all(np.isfinite(c)):
        raise InputError(f"must be a finite ({n}, {n}) covariance, got shape {c.shape}", field=field)
    scale = max(1.0, float(np.max(np.abs(c)))) if c.size else 1.0
    if c.size and float(np.max(np.abs(c - c.T))) > 1e-9 * scale:
        raise InputError("covariance must be symmetric", field=field)
    if c.size and float(np.min(np.linalg.eigvalsh(c))) < -1e-9 * scale:
        raise InputError("covariance must be positive semi-definite", field=field)
    return 0.5 * (c + c.T)


def as_vector(value: ArrayLike, n: int, field: str) -> Array:
    """A finite (n,) float vector, or InputError naming ``field``."""
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise InputError(f"must be {n} finite numbers, got shape {v.shape}", field=field)
    return v.copy()


class GlobalState:
    """Mean and covariance of the positions and headings of a set of feet (seed 001 Sec. 4).

    The state vector is the concatenation of one ``FOOT_DIM`` block ``[x, y, z, chi]`` per foot in the
    order the feet were added. It is a mutable filter state: the update functions of :mod:`pdr.fusion`
    replace ``mean`` and ``cov`` in place.

    Attributes
    ----------
    feet
        Foot keys in state order.
    mean
        (4F,) state mean: per foot position (m, ENU) and heading (rad, CCW from east).
    cov
        (4F, 4F) state covariance (m^2, m rad, rad^2).
    t_s
        (F,) time of the last dead-reckoning update of each foot, s.
    steps
        (F,) number of dead-reckoning updates applied to each foot.
    """

    def __init__(self) -> None:
        self.feet: list[FootKey] = []
        self._index: dict[FootKey, int] = {}
        self.mean = np.zeros(0)
        self.cov = np.zeros((0, 0))
        self.t_s = np.zeros(0)
        self.steps = np.zeros(0, dtype=np.int64)

    @property
    def dim(self) -> int:
        """Length of the state vector."""
        return int(self.mean.size)

    def __contains__(self, key: object) -> bool:
        return key in self._index

    def add_foot(self, key: FootKey, pos_n: ArrayLike, heading: float, cov: ArrayLike, t_s: float) -> None:
        """Append a foot with initial position (m), heading (rad), (4, 4) covariance and time (s).

        The new foot is uncorrelated with the feet already in the state.
        """
        if key in self._index:
            raise InputError(f"foot {key} is already in the state", field="foot")
        block = np.concatenate([as_vector(pos_n, 3, "pos_n"), [float(heading)]])
        if not np.all(np.isfinite(block)) or not np.isfinite(t_s):
            raise InputError("initial heading and time must be finite", field="heading")
        c = as_cov(cov, FOOT_DIM, "cov")
        m = self.dim
        cov_new = np.zeros((m + FOOT_DIM, m + FOOT_DIM))
        cov_new[:m, :m] = self.cov
        cov_new[m:, m:] = c
        self._index[key] = len(self.feet)
        self.feet.append(key)
        self.mean = np.concatenate([self.mean, block])
        self.cov = cov_new
        self.t_s = np.append(self.t_s, float(t_s))
        self.steps = np.append(self.steps, 0)

    def foot(self, key: FootKey) -> int:
        """Position of ``key`` in :attr:`feet` (InputError when unknown)."""
        try:
            return self._index[key]
        except KeyError:
            raise InputError(f"unknown foot {key}", field="foot") from None

    def block(self, key: FootKey) -> IntArray:
        """(4,) state indices ``[x, y, z, chi]`` of a foot."""
        start = FOOT_DIM * self.foot(key)
        return np.arange(start, start + FOOT_DIM, dtype=np.int64)

    def position_indices(self, key: FootKey) -> IntArray:
        """(3,) state indices of a foot's position."""
        return self.block(key)[POS]

    def position(self, key: FootKey) -> Array:
        """(3,) position estimate of a foot, m, ENU."""
        return self.mean[self.position_indices(key)].copy()

    def heading(self, key: FootKey) -> float:
        """Heading estimate of a foot, rad (CCW from east)."""
        return float(self.mean[self.block(key)[HEADING]])

    def marginal(self, keys: list[FootKey]) -> tuple[Array, Array]:
        """Mean and covariance of the blocks of ``keys`` (in that order)."""
        idx = np.concatenate([self.block(k) for k in keys]) if keys else np.zeros(0, dtype=np.int64)
        return self.mean[idx].copy(), self.cov[np.ix_(idx, idx)].copy()

    def set_marginal(self, keys: list[FootKey], mean: ArrayLike, cov: ArrayLike) -> None:
        """Overwrite the mean and covariance of the blocks of ``keys``; their cross-covariances are kept."""
        idx = np.concatenate([self.block(k) for k in keys])
        self.mean[idx] = as_vector(mean, idx.size, "mean")
        self.cov[np.ix_(idx, idx)] = as_cov(cov, idx.size, "cov")

    def copy(self) -> GlobalState:
        """Deep copy."""
        out = GlobalState()
        out.feet = list(self.feet)
        out._index = dict(self._index)
        out.mean = self.mean.copy()
        out.cov = self.cov.copy()
        out.t_s = self.t_s.copy()
        out.steps = self.steps.copy()
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (lists of floats); :meth:`from_dict` restores it exactly."""
        return {"feet": [[k.agent, k.foot] for k in self.feet], "mean": self.mean.tolist(),
                "cov": self.cov.tolist(), "t_s": self.t_s.tolist(), "steps": self.steps.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GlobalState:
        """Inverse of :meth:`to_dict` (InputError on a malformed dict)."""
        try:
            feet = [FootKey(str(a), str(f)) for a, f in data["feet"]]
            mean = np.asarray(data["mean"], dtype=np.float64).reshape(-1)
            cov = np.asarray(data["cov"], dtype=np.float64).reshape(mean.size, mean.size)
            t_s = np.asarray(data["t_s"], dtype=np.float64).reshape(-1)
            steps = np.asarray(data["steps"], dtype=np.int64).reshape(-1)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed fusion state: {exc}", field="state") from None
        if mean.size != FOOT_DIM * len(feet) or t_s.size != len(feet) or steps.size != len(feet):
            raise InputError("fusion state sizes do not match its feet", field="state")
        out = cls()
        out.feet = feet
        out._index = {k: i for i, k in enumerate(feet)}
        out.mean, out.cov, out.t_s, out.steps = mean, cov, t_s, steps
        return out
