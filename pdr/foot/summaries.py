"""The low-rate interface of a shoe unit: step-wise dead-reckoning summaries as JSON (``pdr-foot-steps/1``).

Instead of raw IMU samples, a shoe unit running the step-wise inertial navigation (seed 001 Sec. 3.2,
Algorithm 1) may upload one summary per reset: the displacement ``dp`` (3, m, in the frame of the previous
reset), the heading change ``dpsi`` (rad, counter-clockwise) and their (4, 4) covariance of eq. 8, at the time
``t_s`` of the reset (s, on the unit's own clock, like ``t_ns / 1e9`` of its raw samples). The receiver
composes them with eq. 7 (:class:`pdr.foot.stepwise.StepwiseDeadReckoning`).

Payload::

    {"format": "pdr-foot-steps/1", "batch_id": "...", "device": {"role": "left_foot", ...},
     "steps": [{"t_s": 12.5, "dp": [0.71, 0.02, 0.0], "dpsi": 0.01, "cov": [[...4...], ...], "index": 2500,
                "stride": true}]}

``stride`` (optional, true when absent) is false for a reset while the foot stands (the step-wise navigation resets
every ``c_max_s`` then, :mod:`pdr.foot.strides`): its increment is composed (a turn on the spot), but it is no step.

Each step is checked as the cooperative fusion's step events are (:func:`pdr.fusion.measurements.parse_event`):
finite numbers, a symmetric positive semi-definite covariance.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.step_increment import StepIncrement

FORMAT = "pdr-foot-steps/1"

_NUMBER = {"type": "number"}
_ROW4 = {"type": "array", "items": _NUMBER, "minItems": 4, "maxItems": 4}

#: Largest magnitude of a step's ``t_s``, s (292 years): the service stores times as int64 nanoseconds.
MAX_ABS_T_S = 9.2e9
#: Largest sample index of a reset (stored as int64).
MAX_INDEX = 2**63 - 1

#: JSON Schema (draft 2020-12) of a summaries payload.
SCHEMA: dict[str, Any] = {
    "type": "object",
    "required": ["format", "batch_id", "device", "steps"],
    "additionalProperties": False,
    "properties": {
        "format": {"const": FORMAT},
        "batch_id": {"type": "string", "minLength": 1, "maxLength": 200, "pattern": r"^[A-Za-z0-9._:\-]+$"},
        "session_id": {"type": "string", "maxLength": 200},
        "device": {"type": "object", "required": ["role"], "additionalProperties": False, "properties": {
            "role": {"enum": ["left_foot", "right_foot"]},
            "device_id": {"type": "string", "maxLength": 200},
            "model": {"type": "string", "maxLength": 200}}},
        "steps": {"type": "array", "minItems": 1, "maxItems": 100000, "items": {
            "type": "object", "required": ["t_s", "dp", "dpsi", "cov"], "additionalProperties": False,
            "properties": {
                "t_s": {"type": "number", "minimum": -MAX_ABS_T_S, "maximum": MAX_ABS_T_S,
                        "description": "time of the reset, s, on the unit's clock"},
                "dp": {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3,
                       "description": "displacement since the previous reset, m, frame of that reset"},
                "dpsi": {"type": "number", "description": "heading change, rad, counter-clockwise"},
                "cov": {"type": "array", "items": _ROW4, "minItems": 4, "maxItems": 4,
                        "description": "covariance of (dp, dpsi) (eq. 8), m^2, m rad, rad^2"},
                "index": {"type": "integer", "minimum": 0, "maximum": MAX_INDEX,
                          "description": "sample index of the reset"},
                "stride": {"type": "boolean", "description": "the reset closes a stride (true, the default), or is "
                           "a reset while the foot stands (false): composed, but not counted as a step"}}}},
    },
}


@dataclass(frozen=True)
class StepSummaryBatch:
    """A decoded summaries payload.

    Attributes
    ----------
    role
        ``left_foot`` or ``right_foot``.
    steps
        The increments in time order (``t_s`` on the unit's clock, s), each with whether it closes a stride
        (:attr:`pdr.step_increment.StepIncrement.stride`; False: a reset while the foot stands).
    warnings
        Problems found while reading (none so far: bad input raises).
    """

    role: str
    steps: tuple[StepIncrement, ...]
    warnings: tuple[str, ...] = ()

    @property
    def strides(self) -> tuple[bool, ...]:
        """Per step, whether it closes a stride."""
        return tuple(s.stride for s in self.steps)

    @property
    def t_first_ns(self) -> int:
        return int(round(self.steps[0].t_s * 1e9))

    @property
    def t_last_ns(self) -> int:
        return int(round(self.steps[-1].t_s * 1e9))


def steps_from_json(obj: Any, source: str = "steps") -> StepSummaryBatch:
    """Decode a ``pdr-foot-steps/1`` object; :class:`InputError` naming the step and field on bad input."""
    import jsonschema

    from pdr.fusion.measurements import StepSummary, parse_event

    error = next(iter(jsonschema.Draft202012Validator(SCHEMA).iter_errors(obj)), None)
    if error is not None:
        path = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in error.absolute_path).lstrip(".")
        raise InputError(error.message, source=source, field=path or None)
    role = obj["device"]["role"]
    steps = []
    for i, item in enumerate(obj["steps"]):
        increment = {k: v for k, v in item.items() if k != "stride"}
        ev = parse_event({"type": "step", "agent": "unit", "foot": role, **increment}, where=f"{source} steps[{i}]")
        assert isinstance(ev, StepSummary)
        steps.append(replace(ev.increment, stride=bool(item.get("stride", True))))
    t = np.array([s.t_s for s in steps])
    if np.any(np.diff(t) <= 0):
        i = int(np.argmax(np.diff(t) <= 0)) + 1
        raise InputError("step times must increase", source=source, field=f"steps[{i}].t_s")
    return StepSummaryBatch(role, tuple(steps))


def steps_to_json(steps: list[StepIncrement], role: str, batch_id: str) -> dict[str, Any]:
    """The payload of ``steps`` (inverse of :func:`steps_from_json`), each with its stride flag."""
    return {"format": FORMAT, "batch_id": batch_id, "device": {"role": role},
            "steps": [{"t_s": float(s.t_s), "dp": np.asarray(s.dp, dtype=np.float64).tolist(), "dpsi": float(s.dpsi),
                       "cov": np.asarray(s.cov, dtype=np.float64).tolist(), "index": int(s.index),
                       "stride": bool(s.stride)} for s in steps]}
