"""The stored form of a foot step: the mode of its track row and the step increment its event carries (the mode,
also the event's label, is the stored form of the increment's stride flag).

Written by the foot processor (:mod:`server.foot_processor`), read back by the dual-foot fusion stage
(:mod:`server.fused_feet`) and the groups' session feed (:mod:`server.group_feed`); apart from them so that
none imports another.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.step_increment import StepIncrement

#: Mode of a foot track row that closes a stride (foot navigation does not classify the motion further).
MODE = "walking"
#: Mode of a foot track row that closes no stride: a reset of the step-wise navigation while the foot stands
#: (:attr:`pdr.foot.online.FootStep.stride`); kept for its increment (a turn on the spot), not counted as a step.
#: A fused update of such a reset (device role :data:`FUSED`; :attr:`pdr.foot.dual.FusedStep.stride`) has it too.
STAND_MODE = "standing"
#: Device role of the session's fused dual-foot track (:mod:`server.fused_feet`).
FUSED = "fused"


def mode_of(stride: bool) -> str:
    """The track row mode (and step event label) of a step that closes a stride (:data:`MODE`) or not
    (:data:`STAND_MODE`; :attr:`pdr.step_increment.StepIncrement.stride`).
    """
    return MODE if stride else STAND_MODE


def increment_to_json(inc: StepIncrement) -> dict[str, Any]:
    """The step increment of eqs. 7-8 as stored in a step event: what the dual-foot fusion stage reads back."""
    return {"index": int(inc.index), "dp_m": [float(x) for x in inc.dp], "dpsi_rad": float(inc.dpsi),
            "cov": np.asarray(inc.cov, dtype=np.float64).tolist()}


def increment_from_json(t_s: float, data: dict[str, Any], label: str | None = MODE) -> StepIncrement:
    """Inverse of :func:`increment_to_json` for a step event at ``t_s`` (s) with ``label`` (its mode: the
    increment's stride flag, :func:`mode_of`); InputError when absent.
    """
    d = data.get("increment")
    if not isinstance(d, dict):
        raise InputError("a foot step event without its increment (stored by an older version): reprocess the "
                         "session", field="increment")
    return StepIncrement(float(t_s), int(d["index"]), np.asarray(d["dp_m"], dtype=np.float64), float(d["dpsi_rad"]),
                         np.asarray(d["cov"], dtype=np.float64), label != STAND_MODE)


def step_increments(rows: Iterable[Any], role: str, after_s: float | None = None,
                    provisional: bool = False) -> list[StepIncrement]:
    """The increments of the stored step events ``rows`` of device ``role`` after ``after_s`` (s), final ones or
    (``provisional``) the provisional tail's.
    """
    return [increment_from_json(r.t_s, json.loads(r.data or "{}"), r.label) for r in rows
            if r.device_role == role and bool(r.provisional) == provisional and (after_s is None or r.t_s > after_s)]
