"""Decoded step summaries (:class:`pdr.foot.summaries.StepSummaryBatch`) as compact bytes, and back.

The service decodes and validates a ``pdr-foot-steps/1`` payload once, at ingest, and stores this form with the raw
payload, so that processing never parses or validates the JSON again (as :mod:`pdr.recording_codec` does for
recordings). The bytes are a :mod:`pdr.state_codec` blob: arrays ``t_s`` (n,) s, ``index`` (n,), ``dp`` (n, 3) m,
``dpsi`` (n,) rad, ``cov`` (n, 4, 4) (eq. 8), ``stride`` (n,) bool (from version 2; version 1 blobs, stored before
the flag, read as all strides); round trips are bit-exact.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pdr import state_codec
from pdr.errors import InputError
from pdr.foot.summaries import StepSummaryBatch
from pdr.step_increment import StepIncrement

#: Version of the layout below, stored with every blob.
VERSION = 2
KIND = "foot-step-summaries"


def dumps(batch: StepSummaryBatch) -> bytes:
    """``batch`` as bytes for :func:`loads`."""
    s = batch.steps
    state: dict[str, Any] = {
        "kind": KIND, "version": VERSION, "role": batch.role, "warnings": list(batch.warnings),
        "t_s": np.array([x.t_s for x in s], dtype=np.float64),
        "index": np.array([x.index for x in s], dtype=np.int64),
        "dp": np.array([np.asarray(x.dp, dtype=np.float64) for x in s]).reshape(len(s), 3),
        "dpsi": np.array([x.dpsi for x in s], dtype=np.float64),
        "cov": np.array([np.asarray(x.cov, dtype=np.float64) for x in s]).reshape(len(s), 4, 4),
        "stride": np.array(batch.strides, dtype=bool),
    }
    return state_codec.dumps(state)


def loads(blob: bytes) -> StepSummaryBatch:
    """The :class:`StepSummaryBatch` that :func:`dumps` wrote; :class:`InputError` if ``blob`` is not one."""
    state = state_codec.loads(blob)
    if not isinstance(state, dict) or state.get("kind") != KIND or state.get("version") not in (1, VERSION):
        raise InputError("not stored step summaries of a known version", source="decoded step summaries")
    strides = state["stride"] if "stride" in state else np.ones(len(state["t_s"]), dtype=bool)
    steps = tuple(StepIncrement(float(t), int(i), dp.copy(), float(dpsi), cov.copy(), bool(f))
                  for t, i, dp, dpsi, cov, f in zip(state["t_s"], state["index"], state["dp"], state["dpsi"],
                                                    state["cov"], strides, strict=True))
    return StepSummaryBatch(str(state["role"]), steps, tuple(state["warnings"]))
