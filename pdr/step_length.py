"""Step length from acceleration signal patterns (seed 004 Sec. 3.3, eqs. 13-19).

Signal patterns of step ``k`` over ``t_s(k) <= t < t_e(k)`` (``a_n`` the low-passed acceleration norm,
``a_v`` the vertical specific force in the navigation frame, both m/s^2):

* ``p1 = 1 / (t_e - t_s)`` main frequency (eq. 13), Hz;
* ``p2 = var(a_n)`` (eq. 14); ``p3 = var(a_v)`` (eq. 15), m^2/s^4;
* ``p4 = integral |a_n - g| dt`` area (eq. 16), m/s;
* ``p5 = max a_n - min a_n`` (eq. 17); ``p6 = max a_v - min a_v`` (eq. 18), m/s^2.

Model (eq. 19): ``Delta s_k = K p_j(k)^q + b``. :func:`fit_model` fits ``K`` and ``b`` by linear least
squares on walked distances of known length (segments between landmarks: the sum over the segment's
steps of ``K p^q + b`` must equal the segment length), for each pattern ``j`` and exponent ``q``;
:func:`calibrate_k` rescales ``K`` for one user from one walk of known length (``pdr calibrate``).
On stairs the step is shorter: ``stairs_factor`` scales the horizontal step length there.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2

FloatArray = NDArray[np.float64]

PATTERNS: tuple[str, ...] = ("p1", "p2", "p3", "p4", "p5", "p6")
#: Exponents tried when fitting (raw, square, cube and fourth root; seed 004 Table 2).
EXPONENTS: tuple[float, ...] = (1.0, 0.5, 1.0 / 3.0, 0.25)


def step_patterns(a_n: FloatArray, a_v: FloatArray, rate_hz: float) -> FloatArray:
    """The six patterns (eqs. 13-18) of one step from its samples.

    Parameters
    ----------
    a_n, a_v
        (M,) acceleration norm and vertical specific force over the step (m/s^2), uniform at ``rate_hz``.

    Returns
    -------
    (6,) ``[p1, ..., p6]``.
    """
    m = a_n.size
    if m < 2:
        raise InputError("a step needs at least two samples", source="step length")
    dur = m / rate_hz
    dn = a_n - a_n.sum() / m
    dv = a_v - a_v.sum() / m
    return np.array([
        1.0 / dur,                                            # eq. 13
        float(dn @ dn) / m,                                   # eq. 14
        float(dv @ dv) / m,                                   # eq. 15
        float(np.sum(np.abs(a_n - GRAVITY_MPS2)) / rate_hz),  # eq. 16
        float(np.max(a_n) - np.min(a_n)),                     # eq. 17
        float(np.max(a_v) - np.min(a_v)),                     # eq. 18
    ])


@dataclass(frozen=True)
class StepLengthModel:
    """``Delta s = K p^q + b`` (eq. 19) on one pattern, with a shorter step on stairs.

    The default (``K = 0.452 * p1^0.5``, i.e. proportional to the square root of the step frequency) won on
    the IPIN 2023 hand-held development logs (``pdr calibrate --fit DIR``: median distance error 2.0 %
    leave-one-log-out; p4^0.25 3.1 %, p5^0.25 3.4 %, p2 and p3 worse). It is a population default; use
    ``pdr calibrate`` for a user or a different carriage. Those logs come from two phones (two actors): the
    SM-G930F logs (trials 21, 26, 52) need 0.66-0.70 m per detected step on the flat where the SM-A520F
    logs need 0.55-0.60 m, at the same cadence, and no pattern separates them (refitting K and b of every
    pattern and exponent leaving one route out, over the flat landmark intervals: the best worst-route
    error is 17 %, p1^1 with an offset, this pattern 21 %; at least 14 of 25 logs stay outside 3 %).
    Rescaling ``K`` for that walker on the other G930F routes (:func:`calibrate_k`, leaving the route out)
    brings their distance ratios over the flat landmark intervals from 0.82-0.86 to 0.96-1.03.

    Attributes
    ----------
    pattern
        ``p1`` ... ``p6``.
    k, q, b
        Scale (m per pattern unit^q), exponent, offset (m).
    stairs_factor
        Multiplier of the horizontal step length on stairs.
    min_m, max_m
        Clamp of a single step length (m).
    """

    pattern: str = "p1"
    k: float = 0.452
    q: float = 0.5
    b: float = 0.0
    stairs_factor: float = 0.6
    min_m: float = 0.2
    max_m: float = 1.4

    def __post_init__(self) -> None:
        if self.pattern not in PATTERNS:
            raise InputError(f"pattern must be one of {PATTERNS}", field="pattern", source="step length model")
        for name in ("k", "q", "b", "stairs_factor", "min_m", "max_m"):
            if not np.isfinite(getattr(self, name)):
                raise InputError("must be finite", field=name, source="step length model")

    def length(self, patterns: FloatArray, on_stairs: bool | FloatArray = False) -> FloatArray:
        """Step length(s) in m from (6,) or (K, 6) patterns."""
        p = np.asarray(patterns, dtype=np.float64)[..., PATTERNS.index(self.pattern)]
        s = self.k * np.maximum(p, 0.0) ** self.q + self.b
        s = np.where(on_stairs, s * self.stairs_factor, s)
        return np.clip(s, self.min_m, self.max_m)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StepLengthModel:
        try:
            kw: dict[str, Any] = {k: (str(v) if k == "pattern" else float(v)) for k, v in d.items()
                                  if k in cls.__dataclass_fields__}
            return cls(**kw)
        except (TypeError, ValueError) as exc:
            raise InputError(f"bad step-length model ({exc})", source="calibration") from None

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps({"step_length": self.to_dict()}, indent=2) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> StepLengthModel:
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(f"cannot read calibration ({exc})", source=str(path)) from None
        if not isinstance(d, dict) or not isinstance(d.get("step_length"), dict):
            raise InputError("expected an object with a 'step_length' object", source=str(path))
        return cls.from_dict(d["step_length"])


@dataclass(frozen=True)
class FitResult:
    """Fitted model and its fit quality: relative error of each segment's distance."""

    model: StepLengthModel
    rel_errors: FloatArray

    @property
    def rms_rel_error(self) -> float:
        return float(np.sqrt(np.mean(self.rel_errors**2)))


def fit_model(segments: list[tuple[FloatArray, float]], pattern: str, q: float, fit_offset: bool = True,
              stairs_factor: float = 0.6) -> FitResult:
    """Least-squares ``K`` (and ``b``) of eq. 19 from segments of known length.

    Parameters
    ----------
    segments
        (patterns (K_i, 6) of the steps walked, true length in m) per segment.
    pattern, q
        Pattern name and exponent.
    fit_offset
        Also fit ``b`` (else ``b = 0``).

    The residual of each segment is weighted by 1 / length so the fit minimises relative error.
    """
    if not segments:
        raise InputError("no segments to fit", source="step length fit")
    j = PATTERNS.index(pattern)
    rows, rhs = [], []
    for pats, length in segments:
        if length <= 0 or pats.shape[0] == 0:
            continue
        sp = float(np.sum(np.maximum(pats[:, j], 0.0) ** q))
        rows.append([sp / length, pats.shape[0] / length] if fit_offset else [sp / length])
        rhs.append(1.0)
    if not rows:
        raise InputError("no usable segments (need steps and a positive length)", source="step length fit")
    a = np.array(rows)
    sol, *_ = np.linalg.lstsq(a, np.array(rhs), rcond=None)
    k = float(sol[0])
    b = float(sol[1]) if fit_offset else 0.0
    model = StepLengthModel(pattern=pattern, k=k, q=q, b=b, stairs_factor=stairs_factor, min_m=0.0, max_m=10.0)
    rel = a @ sol - 1.0
    return FitResult(model, rel)


def calibrate_k(model: StepLengthModel, patterns: FloatArray, walked_m: float,
                on_stairs: FloatArray | None = None) -> StepLengthModel:
    """Per-user calibration: rescale ``K`` so the walk's steps add up to ``walked_m`` (b kept).

    ``on_stairs`` (K,) bool marks steps whose length the model shortens by ``stairs_factor``.
    """
    if not walked_m > 0:
        raise InputError(f"walked distance must be positive, got {walked_m}", field="distance_m")
    pats = np.asarray(patterns, dtype=np.float64)
    if pats.ndim != 2 or pats.shape[0] < 5:
        raise InputError(f"need at least 5 detected steps to calibrate, got {pats.shape[0] if pats.ndim else 0}",
                         source="calibration")
    j = PATTERNS.index(model.pattern)
    f = np.ones(pats.shape[0]) if on_stairs is None else np.where(np.asarray(on_stairs, bool), model.stairs_factor, 1.0)
    sp = float(np.sum(f * np.maximum(pats[:, j], 0.0) ** model.q))
    k = (walked_m - model.b * float(np.sum(f))) / sp
    if not k > 0:
        raise InputError("calibration gives a non-positive scale; check the distance", field="distance_m")
    return StepLengthModel(**{**asdict(model), "k": k})
