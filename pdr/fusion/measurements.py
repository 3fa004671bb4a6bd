"""What agents send to the fusion centre: step summaries and range-type measurements, with their JSON form.

Seed 001 Sec. 3.3-3.4: per foot and step, the displacement ``dp`` (3, m, frame of the previous reset), the
heading change ``dpsi`` (rad) and their (4, 4) covariance (14 values on the wire); inter-agent ranges; and,
as range updates of the same kind (Sec. 4.3), ranges to anchors, position fixes and height differences from
pressure. Every event carries the time ``t_s`` (s, the group's common clock) at which it holds.

JSON objects (one per event, ``type`` selects the kind; unknown keys are rejected):

* ``{"type": "step", "agent", "foot", "t_s", "dp": [3], "dpsi", "cov": [[4 x 4]]}``
* ``{"type": "range", "agent_a", "agent_b", "t_s", "range_m"}`` (``agent_a`` reports it)
* ``{"type": "anchor_range", "agent", "t_s", "anchor_n": [3], "range_m", "gamma_m"?, "sigma_m"?}``
* ``{"type": "position_fix", "agent", "t_s", "pos_n": [2 or 3], "gamma_m", "sigma_m"}``
* ``{"type": "height_difference", "agent_a", "agent_b"?, "t_s", "dh_m" | ("pressure_hpa", "reference_pressure_hpa"),
  "reference_height_m"?, "gamma_m", "sigma_m"}`` (height of ``agent_a`` above ``agent_b`` or the reference)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.fusion.aiding import pressure_height_difference
from pdr.fusion.dead_reckoning import check_increment
from pdr.fusion.ranging import RangeModel
from pdr.json_number import json_number
from pdr.step_increment import StepIncrement

Array = NDArray[np.float64]

#: Largest displacement of one step summary along any axis, m, and square root of its largest covariance entry. A
#: stride is under 3 m and a standing unit resets every few seconds, so a larger one is corrupt; near the float range
#: (a dp of 1e160 m, a variance of 1e308) it overflows the fusion (the dual-foot separation constraint squares it)
#: when the step is fused, and every later update of its group then fails.
MAX_STEP_M = 100.0
#: Largest variance (m^2, m rad, rad^2) of anything a group fuses: a step's covariance entries, a joining agent's
#: initial pose covariance (``cov0``), the range variance of the Kalman reference; its square root,
#: :data:`MAX_STEP_M`, is the largest standard deviation of a range or position measurement (``sigma_m``). An
#: uncertainty of 100 m tells nothing of people walking metres apart, and a finite but absurd one (1e300, squared or
#: multiplied in the updates) breaks the fusion's covariances: an agent joined with cov0 1e300 had negative
#: variances and a track 1e15 m away after its first ranges.
MAX_VARIANCE = MAX_STEP_M**2
#: Largest coordinate or distance (m) of a group's local frame: positions, anchors, ranges and heights. A hundred
#: thousand kilometres holds any projected frame on Earth (UTM northings reach 1e7 m); a finite but absurd one (1e300,
#: squared in the updates) overflowed the fusion and failed every later update of the group.
MAX_COORDINATE_M = 1e8
#: Largest heading change of one step summary either way, rad (one turn): 1e308 rad overflowed the heading it is
#: added to, and every later update of the group failed.
MAX_STEP_TURN_RAD = 2.0 * math.pi


@dataclass(frozen=True)
class StepSummary:
    """One foot's step-wise dead-reckoning update (Algorithm 1 line 15)."""

    agent: str
    foot: str
    increment: StepIncrement

    @property
    def t_s(self) -> float:
        return float(self.increment.t_s)

    @property
    def agents(self) -> tuple[str, ...]:
        return (self.agent,)


@dataclass(frozen=True)
class InterAgentRange:
    """A range between the radios of ``agent_a`` (the reporter) and ``agent_b``, m."""

    t_s: float
    agent_a: str
    agent_b: str
    range_m: float

    @property
    def agents(self) -> tuple[str, ...]:
        return (self.agent_a, self.agent_b)


@dataclass(frozen=True)
class AnchorRange:
    """A range from an agent to an anchor at ``anchor_n`` (3, m, ENU); ``model`` None: the group's ranging."""

    t_s: float
    agent: str
    anchor_n: Array
    range_m: float
    model: RangeModel | None = None

    @property
    def agents(self) -> tuple[str, ...]:
        return (self.agent,)


@dataclass(frozen=True)
class PositionFix:
    """A position fix (2 values: horizontal; 3: full), m ENU, with its error bounds ``model``."""

    t_s: float
    agent: str
    pos_n: Array
    model: RangeModel

    @property
    def agents(self) -> tuple[str, ...]:
        return (self.agent,)


@dataclass(frozen=True)
class HeightDifference:
    """Height of ``agent_a`` above ``agent_b`` (or above ``reference_height_m`` when ``agent_b`` is None), m."""

    t_s: float
    agent_a: str
    agent_b: str | None
    dh_m: float
    model: RangeModel
    reference_height_m: float = 0.0

    @property
    def agents(self) -> tuple[str, ...]:
        return (self.agent_a,) if self.agent_b is None else (self.agent_a, self.agent_b)


Event = StepSummary | InterAgentRange | AnchorRange | PositionFix | HeightDifference

_KEYS: dict[str, tuple[set[str], set[str]]] = {            # required, optional
    "step": ({"agent", "foot", "t_s", "dp", "dpsi", "cov"}, {"index"}),
    "range": ({"agent_a", "agent_b", "t_s", "range_m"}, set()),
    "anchor_range": ({"agent", "t_s", "anchor_n", "range_m"}, {"gamma_m", "sigma_m"}),
    "position_fix": ({"agent", "t_s", "pos_n", "gamma_m", "sigma_m"}, set()),
    "height_difference": ({"agent_a", "t_s", "gamma_m", "sigma_m"},
                          {"agent_b", "dh_m", "pressure_hpa", "reference_pressure_hpa", "reference_height_m"}),
}


def _number(obj: Mapping[str, Any], key: str, where: str, minimum: float | None = None) -> float:
    value = json_number(obj.get(key), where, key)
    if minimum is not None and value < minimum:
        raise InputError(f"must be >= {minimum:g}", source=where, field=key)
    return value


def _name(obj: Mapping[str, Any], key: str, where: str) -> str:
    value = obj.get(key)
    if not isinstance(value, str) or not value or len(value) > 200:
        raise InputError("must be a non-empty name (at most 200 characters)", source=where, field=key)
    return value


def _vector(obj: Mapping[str, Any], key: str, where: str, sizes: tuple[int, ...]) -> Array:
    try:
        v = np.asarray(obj.get(key), dtype=np.float64)
    except (TypeError, ValueError):
        v = np.zeros(0)
    if v.ndim != 1 or v.size not in sizes or not np.all(np.isfinite(v)):
        raise InputError(f"must be a list of {' or '.join(map(str, sizes))} finite numbers", source=where, field=key)
    return v


def _model(obj: Mapping[str, Any], where: str) -> RangeModel:
    return RangeModel(_number(obj, "gamma_m", where, 0.0), _number(obj, "sigma_m", where, 1e-9))


def parse_event(obj: Any, where: str = "event") -> Event:
    """An event from its JSON object (InputError naming ``where`` and the field on any problem)."""
    if not isinstance(obj, Mapping):
        raise InputError("an event must be a JSON object", source=where)
    kind = obj.get("type")
    if kind not in _KEYS:
        raise InputError(f"type must be one of {', '.join(sorted(_KEYS))}", source=where, field="type")
    required, optional = _KEYS[kind]
    missing = sorted(required - set(obj))
    if missing:
        raise InputError(f"missing {', '.join(missing)}", source=where, field=missing[0])
    unknown = sorted(set(obj) - required - optional - {"type"})
    if unknown:
        raise InputError(f"unknown key {unknown[0]}", source=where, field=unknown[0])
    t = _number(obj, "t_s", where)
    if kind == "step":
        try:
            cov = np.asarray(obj["cov"], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("must be a 4 x 4 list of numbers", source=where, field="cov") from None
        index = obj.get("index", 0)
        if isinstance(index, bool) or not isinstance(index, int):
            raise InputError("must be an integer", source=where, field="index")
        inc = StepIncrement(t, index, _vector(obj, "dp", where, (3,)), _number(obj, "dpsi", where), cov)
        if float(np.max(np.abs(inc.dp))) > MAX_STEP_M:
            raise InputError(f"a step's displacement must be at most {MAX_STEP_M:g} m along each axis, got "
                             f"{float(np.max(np.abs(inc.dp))):g} m", source=where, field="dp")
        if abs(inc.dpsi) > MAX_STEP_TURN_RAD:
            raise InputError(f"a step's heading change must be at most one turn ({MAX_STEP_TURN_RAD:.6g} rad) either "
                             f"way, got {inc.dpsi:g} rad", source=where, field="dpsi")
        if cov.size and float(np.max(np.abs(cov))) > MAX_VARIANCE:     # before the checks, which overflow
            raise InputError(f"a step's covariance entries must be at most {MAX_VARIANCE:g} (m^2, m rad, rad^2: a "
                             f"standard deviation of {MAX_STEP_M:g} m), got {float(np.max(np.abs(cov))):g}",
                             source=where, field="cov")
        try:
            check_increment(inc)
        except InputError as exc:
            raise InputError(exc.message, source=where, field=exc.field) from None
        return StepSummary(_name(obj, "agent", where), _name(obj, "foot", where), inc)
    if kind == "range":
        a, b = _name(obj, "agent_a", where), _name(obj, "agent_b", where)
        if a == b:
            raise InputError("a range needs two different agents", source=where, field="agent_b")
        return InterAgentRange(t, a, b, _number(obj, "range_m", where, 0.0))
    if kind == "anchor_range":
        model = _model(obj, where) if "gamma_m" in obj or "sigma_m" in obj else None
        return AnchorRange(t, _name(obj, "agent", where), _vector(obj, "anchor_n", where, (3,)),
                           _number(obj, "range_m", where, 0.0), model)
    if kind == "position_fix":
        return PositionFix(t, _name(obj, "agent", where), _vector(obj, "pos_n", where, (2, 3)), _model(obj, where))
    # height difference: directly in m, or from the pressures of agent_a and of the reference (agent_b or ground)
    agent_b = _name(obj, "agent_b", where) if obj.get("agent_b") is not None else None
    if "dh_m" in obj:
        dh = _number(obj, "dh_m", where)
    elif "pressure_hpa" in obj and "reference_pressure_hpa" in obj:
        dh = pressure_height_difference(_number(obj, "pressure_hpa", where, 1e-3),
                                        _number(obj, "reference_pressure_hpa", where, 1e-3))
    else:
        raise InputError("needs dh_m, or pressure_hpa and reference_pressure_hpa", source=where, field="dh_m")
    ref = _number(obj, "reference_height_m", where) if "reference_height_m" in obj else 0.0
    return HeightDifference(t, _name(obj, "agent_a", where), agent_b, dh, _model(obj, where), ref)


def _model_dict(model: RangeModel | None) -> dict[str, float]:
    return {} if model is None else {"gamma_m": model.gamma_m, "sigma_m": model.sigma_m}


def event_to_dict(event: Event) -> dict[str, Any]:
    """The JSON object of an event (inverse of :func:`parse_event`)."""
    if isinstance(event, StepSummary):
        inc = event.increment
        return {"type": "step", "agent": event.agent, "foot": event.foot, "t_s": float(inc.t_s),
                "index": int(inc.index), "dp": np.asarray(inc.dp, dtype=np.float64).tolist(), "dpsi": float(inc.dpsi),
                "cov": np.asarray(inc.cov, dtype=np.float64).tolist()}
    if isinstance(event, InterAgentRange):
        return {"type": "range", "agent_a": event.agent_a, "agent_b": event.agent_b, "t_s": event.t_s,
                "range_m": event.range_m}
    if isinstance(event, AnchorRange):
        return {"type": "anchor_range", "agent": event.agent, "t_s": event.t_s, "anchor_n": event.anchor_n.tolist(),
                "range_m": event.range_m, **_model_dict(event.model)}
    if isinstance(event, PositionFix):
        return {"type": "position_fix", "agent": event.agent, "t_s": event.t_s, "pos_n": event.pos_n.tolist(),
                **_model_dict(event.model)}
    return {"type": "height_difference", "agent_a": event.agent_a, "agent_b": event.agent_b, "t_s": event.t_s,
            "dh_m": event.dh_m, "reference_height_m": event.reference_height_m, **_model_dict(event.model)}
