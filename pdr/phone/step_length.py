"""Step length from acceleration signal patterns (seed 004 Sec. 3.3, eqs. 13-19).

Signal patterns of step ``k`` over ``t_s(k) <= t < t_e(k)`` (``a_n`` the low-passed acceleration norm,
``a_v`` the vertical specific force in the navigation frame, both m/s^2):

* ``p1 = 1 / (t_e - t_s)`` main frequency (eq. 13), Hz;
* ``p2 = var(a_n)`` (eq. 14); ``p3 = var(a_v)`` (eq. 15), m^2/s^4;
* ``p4 = integral |a_n - g| dt`` area (eq. 16), m/s;
* ``p5 = max a_n - min a_n`` (eq. 17); ``p6 = max a_v - min a_v`` (eq. 18), m/s^2.

Model (eq. 19): ``Delta s_k = K p_j(k)^q + b``, times the turn factor ``f(Delta psi_k)`` (below).
:func:`fit_model` fits ``K`` and ``b`` by linear least squares on walked distances of known length (segments
between landmarks: the sum over the segment's steps of ``(K p^q + b) f`` must equal the segment length), for each
pattern ``j`` and exponent ``q``; :func:`calibrate_k` rescales ``K`` for one user from one walk of known length
(``pdr calibrate``).
On stairs the step is shorter: one tread, ``stairs_m``, whoever walks.

Turns (not in seed 004): a step that turns the walking direction covers less ground. With ``Delta psi_k`` the change
of the step heading from the previous step of the same walk (the track rows' ``turn_deg``), the length is multiplied
by ``f = max(cos Delta psi, 0)^2`` (:func:`turn_factor`; 0.94 at 14 deg, 0.75 at 30 deg, 0.5 at 45 deg, 0 for a turn
of 90 deg or more on the spot). Why: at the same cadence the IPIN 2023 hand-held walker of the SM-A520F logs covers
less ground per step on turn-heavy routes, and eq. 19 alone over-reads the distance of the routes with many turning
steps; turning steps are not detected twice (their cadence is barely longer than straight walking's): the walker
pivots. With the factor the leave-one-route-out median distance error and the count of logs outside 3 % fell a little
with ``K`` fitted on the other routes, and clearly with ``K`` recalibrated on the phone's other routes, where every
pattern and exponent improved (issue history; ``pdr calibrate ../shared/data/ipin2023_t3/logfiles --fit --placement
hand`` prints the current errors per pattern and exponent). In an
offline study on the tracks' headings, a linear ``1 - c |Delta psi| / 90 deg`` chose ``c`` = 1.0-1.1 on every
held-out route and did as well as ``cos^2``; plain ``cos`` did worse. ``turn="none"`` turns the factor off (and is
what a model saved before it existed loads with). The pipeline measures turns for hand-held and torso phones only
(:mod:`pdr.phone.pipeline`): a pocket phone's per-step heading jitters with the thigh, and no data set here has the
distance of a pocket walk to check the factor on.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters.compiled import kernel
from pdr.filters.numpy_reductions import pairwise_sum
from pdr.frames import GRAVITY_MPS2

FloatArray = NDArray[np.float64]

PATTERNS: tuple[str, ...] = ("p1", "p2", "p3", "p4", "p5", "p6")
#: Exponents tried when fitting (raw, square, cube and fourth root; seed 004 Table 2).
EXPONENTS: tuple[float, ...] = (1.0, 0.5, 1.0 / 3.0, 0.25)
#: Turn factors (module doc): ``cos2`` or ``none``.
TURN_MODELS: tuple[str, ...] = ("cos2", "none")


def turn_factor(turn_rad: float | FloatArray, model: str = "cos2") -> FloatArray:
    """Fraction of the eq. 19 length a step covers when it turns the walking direction by ``turn_rad`` (rad).

    ``cos2``: ``max(cos turn, 0)^2``; ``none``: 1.
    """
    t = np.asarray(turn_rad, dtype=np.float64)
    if model == "none":
        return np.ones_like(t)
    return np.asarray(np.maximum(np.cos(t), 0.0) ** 2)


def turn_factor_float(turn_rad: float, model: str = "cos2") -> float:
    """:func:`turn_factor` of one turn (rad) as a Python float, bit for bit, without a 0-d array per step: numpy's
    cosine (its loop, whose SIMD form may differ from the C library's in the last bit), then ``np.maximum`` written
    out (a NaN passes) and the power of a numpy scalar, which is the C library's ``pow`` as Python's ``**`` (not one
    product: ``pow(c, 2)`` may differ from ``c * c`` in the last bit).
    """
    if model == "none":
        return 1.0
    c = float(np.cos(turn_rad))
    c = c if (c >= 0.0 or c != c) else 0.0
    return c ** 2


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
    dn, dv, area, range_n, range_v = _centred_area_ranges(a_n, a_v, GRAVITY_MPS2)
    # The products stay numpy's (BLAS's dot, whose order and fused multiply-adds a kernel would not reproduce).
    return np.array([
        1.0 / dur,                                            # eq. 13
        float(dn @ dn) / m,                                   # eq. 14
        float(dv @ dv) / m,                                   # eq. 15
        area / rate_hz,                                       # eq. 16
        range_n,                                              # eq. 17
        range_v,                                              # eq. 18
    ])


@kernel
def _centred_range(a: FloatArray) -> tuple[FloatArray, float]:  # pragma: no cover - compiled
    """``a - a.mean()`` and ``a.max() - a.min()`` of a step's samples (M,), with numpy's bits: its pairwise sum
    (:mod:`pdr.filters.numpy_reductions`), and a NaN taken as the maximum and the minimum as ``np.maximum`` and
    ``np.minimum`` propagate it.
    """
    n = a.shape[0]
    mean = pairwise_sum(a) / n
    d = np.empty(n)
    hi = lo = a[0]
    for i in range(n):
        x = a[i]
        d[i] = x - mean
        if x > hi or x != x:
            hi = x
        if x < lo or x != x:
            lo = x
    return d, hi - lo


@kernel
def _centred_area_ranges(a_n: FloatArray, a_v: FloatArray, g: float
                         ) -> tuple[FloatArray, FloatArray, float, float, float]:  # pragma: no cover - compiled
    """What :func:`step_patterns` took from numpy one call at a time, in one call: ``a_n`` and ``a_v`` centred (M,),
    ``sum |a_n - g|`` (the area of eq. 16 times the rate) and the ranges of eqs. 17-18, bit for bit.
    """
    dn, range_n = _centred_range(a_n)
    dv, range_v = _centred_range(a_v)
    dev = np.empty(a_n.shape[0])
    for i in range(a_n.shape[0]):
        dev[i] = abs(a_n[i] - g)
    return dn, dv, pairwise_sum(dev), range_n, range_v


@dataclass(frozen=True)
class StepLengthModel:
    """``Delta s = K p^q + b`` (eq. 19) on one pattern; on stairs a fixed, shorter horizontal step.

    Default ``K = 0.4742 * p1^0.5`` (step length proportional to the square root of the step frequency), with the
    ``cos2`` turn factor: ``K`` is the least-squares fit (relative error) over the landmark intervals on one floor
    of the 25 IPIN 2023 hand-held development logs (``pdr calibrate DIR --fit --placement hand``). Leaving each
    log's route out of the fit, p1^0.5 gives a median distance error of 3.2 % (13 of 25 logs outside 3 %, worst
    16 %; without the turn factor 3.5 %, 14, 18 %), and with ``K`` recalibrated on the phone's other routes 1.2 %
    (5 outside; without the turn factor 2.7 %, 11). p1^(1/3), p1^0.25 and p5^0.25 win the first column narrowly
    (10-11 outside) but not the second; p1^(1/3) also lengthened the MS indoor hand-held traces' 75th percentile
    error before (``pdr eval ms``: 4.66 -> 4.83 m), so p1^0.5 stays. p2-p6 and fits with an offset ``b`` do worse
    (offset fits turn ``K`` negative: a constant step). The turn factor took ``pdr eval ms DIR --placement hand``,
    whose traces took no part in any fit, from 2.78 / 4.57 m to 2.57 / 4.07 m (median / 75th percentile).

    It is a population default. The logs come from two phones, which stand for two actors: the SM-G930F
    logs (trials 21, 26, 52) need 0.64-0.69 m per detected step on the flat where the SM-A520F logs need
    0.52-0.63 m, at the same cadence, and no pattern separates them. Per-user calibration (:func:`calibrate_k`,
    ``pdr calibrate``) on the same phone's other routes moves those logs from 0.84-0.94 to 0.95-1.08
    (``pdr eval ipin DIR --calibrate cross``). The same walker's stride also differs between routes by a few
    percent at the same cadence, half of it explained by how much the route turns (turn factor, module doc).

    Stairs: seed 004 only says the step is "forced to be shorter". A step on stairs covers one tread, a
    property of the staircase rather than the walker, so its horizontal length is ``stairs_m`` (not scaled
    by ``K``; a per-user calibration leaves it alone). Default 0.33 m: the barometer gives 0.145-0.156 m of
    height per stairs step over the four flights of IPIN trial 52, and the stair step rule 2 R + T = 0.63 m
    then gives a tread T of 0.32-0.34 m. No data set here has the horizontal path on stairs, so this is not
    measured against truth.

    Attributes
    ----------
    pattern
        ``p1`` ... ``p6``.
    k, q, b
        Scale (m per pattern unit^q), exponent, offset (m).
    stairs_m
        Horizontal length of a step on stairs (m).
    min_m, max_m
        Clamp of a single step length on the flat (m), before the turn factor.
    turn
        Turn factor, one of :data:`TURN_MODELS` (module doc).
    """

    pattern: str = "p1"
    k: float = 0.4742
    q: float = 0.5
    b: float = 0.0
    stairs_m: float = 0.33
    min_m: float = 0.2
    max_m: float = 1.4
    turn: str = "cos2"

    def __post_init__(self) -> None:
        if self.pattern not in PATTERNS:
            raise InputError(f"pattern must be one of {PATTERNS}", field="pattern", source="step length model")
        if self.turn not in TURN_MODELS:
            raise InputError(f"turn must be one of {TURN_MODELS}", field="turn", source="step length model")
        for name in ("k", "q", "b", "stairs_m", "min_m", "max_m"):
            if not np.isfinite(getattr(self, name)):
                raise InputError("must be finite", field=name, source="step length model")

    def length(self, patterns: FloatArray, on_stairs: bool | FloatArray = False,
               turn_rad: float | FloatArray = 0.0) -> FloatArray:
        """Horizontal step length(s) in m from (6,) or (K, 6) patterns and the steps' turns (rad, module doc);
        ``stairs_m`` where ``on_stairs``.
        """
        p = np.asarray(patterns, dtype=np.float64)[..., PATTERNS.index(self.pattern)]
        s = np.clip(self.k * np.maximum(p, 0.0) ** self.q + self.b, self.min_m, self.max_m)
        return np.where(on_stairs, self.stairs_m, s * turn_factor(turn_rad, self.turn))

    def step_length(self, patterns: Sequence[float], on_stairs: bool, turn_rad: float) -> float:
        """:meth:`length` of one step (m): the same operations on Python floats, without the arrays of a batch.

        ``np.maximum``, ``np.clip`` and ``np.where`` are written out with their comparisons (NaN passes through
        the clamp as there); the power is the C library's ``pow`` in both, the turn factor :func:`turn_factor_float`.
        """
        if on_stairs:
            return float(self.stairs_m)
        p = float(patterns[PATTERNS.index(self.pattern)])
        p = p if (p >= 0.0 or p != p) else 0.0                      # np.maximum(p, 0.0)
        s = self.k * p ** self.q + self.b
        if s == s:                                                  # np.clip(s, min_m, max_m)
            s = s if s > self.min_m else self.min_m
            s = s if s < self.max_m else self.max_m
        return float(s * turn_factor_float(turn_rad, self.turn))

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StepLengthModel:
        try:
            kw: dict[str, Any] = {k: (str(v) if k in ("pattern", "turn") else float(v)) for k, v in d.items()
                                  if k in cls.__dataclass_fields__}
            # A model saved before the turn factor existed was calibrated without it.
            kw.setdefault("turn", "none")
            model = cls(**kw)
        except (TypeError, ValueError) as exc:
            raise InputError(f"bad step-length model ({exc})", source="calibration") from None
        # A given model must lengthen the step with the pattern and keep a range of lengths; k <= 0 would clamp
        # every step to min_m (eq. 19). The internal fits may pass through such values, a user's model may not.
        for name, ok, why in (("k", model.k > 0, "must be positive (the step lengthens with the pattern)"),
                              ("stairs_m", model.stairs_m > 0, "must be positive"),
                              ("min_m", 0 <= model.min_m < model.max_m, "must be >= 0 and below max_m")):
            if not ok:
                raise InputError(f"{why}, got {getattr(model, name)}", field=name, source="calibration")
        return model

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps({"step_length": self.to_dict()}, indent=2) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> StepLengthModel:
        try:
            d = json.loads(Path(path).read_text())
        # ValueError: invalid JSON, UTF-8 or an integer of more than 4300 digits; RecursionError: nested too deeply
        except (OSError, ValueError, RecursionError) as exc:
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


def step_sums(patterns: FloatArray, pattern: str, q: float, factors: FloatArray | None = None) -> tuple[float, float]:
    """``(sum f p^q, sum f)`` over steps: a walk's eq. 19 length is ``K`` times the first plus ``b`` times the second.

    ``patterns`` (K, 6); ``factors`` (K,) the steps' turn factors (:func:`turn_factor`; None: all 1).
    """
    p = np.maximum(np.asarray(patterns, dtype=np.float64)[:, PATTERNS.index(pattern)], 0.0) ** q
    f = np.ones(p.shape[0]) if factors is None else np.asarray(factors, dtype=np.float64)
    return float(f @ p), float(np.sum(f))


def fit_model(segments: list[tuple[FloatArray, float]], pattern: str, q: float, fit_offset: bool = True,
              factors: list[FloatArray] | None = None) -> FitResult:
    """Least-squares ``K`` (and ``b``) of eq. 19 from segments of known length.

    Parameters
    ----------
    segments
        (patterns (K_i, 6) of the steps walked, true length in m) per segment.
    pattern, q
        Pattern name and exponent.
    fit_offset
        Also fit ``b`` (else ``b = 0``).
    factors
        (K_i,) turn factors of each segment's steps (:func:`turn_factor`); None: no turn factor.

    The residual of each segment is weighted by 1 / length so the fit minimises relative error.
    """
    if not segments:
        raise InputError("no segments to fit", source="step length fit")
    rows, rhs = [], []
    for i, (pats, length) in enumerate(segments):
        if length <= 0 or pats.shape[0] == 0:
            continue
        sp, n = step_sums(pats, pattern, q, None if factors is None else factors[i])
        rows.append([sp / length, n / length] if fit_offset else [sp / length])
        rhs.append(1.0)
    if not rows:
        raise InputError("no usable segments (need steps and a positive length)", source="step length fit")
    a = np.array(rows)
    sol, *_ = np.linalg.lstsq(a, np.array(rhs), rcond=None)
    k = float(sol[0])
    b = float(sol[1]) if fit_offset else 0.0
    model = StepLengthModel(pattern=pattern, k=k, q=q, b=b, min_m=0.0, max_m=10.0)
    rel = a @ sol - 1.0
    return FitResult(model, rel)


def calibrate_k(model: StepLengthModel, patterns: FloatArray, walked_m: float,
                on_stairs: FloatArray | None = None, turn_rad: FloatArray | None = None) -> StepLengthModel:
    """Per-user calibration: rescale ``K`` so the walk's steps add up to ``walked_m`` (``b``, ``stairs_m`` kept).

    ``on_stairs`` (K,) bool marks steps on stairs: they count ``stairs_m`` each and do not inform ``K``.
    ``turn_rad`` (K,) the steps' turns (the ``turn_deg`` of the track rows, in rad; None: straight), weighted
    by the model's turn factor. The clamp ``min_m``/``max_m`` is not applied while solving.
    """
    if not walked_m > 0:
        raise InputError(f"walked distance must be positive, got {walked_m}", field="distance_m")
    pats = np.asarray(patterns, dtype=np.float64)
    stairs = np.zeros(pats.shape[0] if pats.ndim else 0, bool) if on_stairs is None else np.asarray(on_stairs, bool)
    flat = pats[~stairs] if pats.ndim == 2 else pats
    if flat.ndim != 2 or flat.shape[0] < 5:
        raise InputError(f"need at least 5 detected steps off stairs to calibrate, got "
                         f"{flat.shape[0] if flat.ndim else 0}", source="calibration")
    turns = np.zeros(stairs.size) if turn_rad is None else np.asarray(turn_rad, dtype=np.float64)
    if turns.shape != stairs.shape:
        raise InputError(f"turn_rad has shape {turns.shape}, the steps {stairs.shape}", field="turn_rad",
                         source="calibration")
    sp, n = step_sums(flat, model.pattern, model.q, turn_factor(turns[~stairs], model.turn))
    k = (walked_m - model.stairs_m * float(np.sum(stairs)) - model.b * n) / sp
    if not k > 0:
        raise InputError("calibration gives a non-positive scale; check the distance", field="distance_m")
    return StepLengthModel(**{**asdict(model), "k": k})
