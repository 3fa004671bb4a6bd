r"""A decoded :class:`~pdr.recording.Recording` as compact bytes, and back (the service stores uploads decoded once).

The bytes are a :mod:`pdr.state_codec` blob (a JSON header plus the raw little-endian arrays; no pickle), so
decoding costs about a memory copy plus the data model's vectorised construction checks (shape, finite,
increasing time): no text is parsed and no reader runs again. Round trips are exact for streams, device,
``t0_ns``, ground truth (positions, steps, labels, numeric and text extras), source, format and warnings;
``meta`` goes through JSON (tuples come back as lists, numpy values as numbers, other objects as text).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from typing import Any

import numpy as np

from pdr import state_codec
from pdr.errors import InputError
from pdr.recording import DeviceInfo, GroundTruth, Labels, PositionTruth, Recording, SensorStream

#: Version of the layout below, stored with every blob.
VERSION = 1
_TEXT = "__text__"


def dumps(recording: Recording) -> bytes:
    """``recording`` as bytes for :func:`loads` (:class:`TypeError` for a truth extra of an object dtype)."""
    truth = recording.truth
    state: dict[str, Any] = {
        "version": VERSION,
        "streams": {k: {"t_ns": s.t_ns, "values": s.values} for k, s in recording.streams.items()},
        "device": asdict(recording.device),
        "t0_ns": recording.origin_ns,
        "truth": {
            "positions": None if truth.positions is None else {
                "t_s": truth.positions.t_s, "pos_m": truth.positions.pos_m, "floor": truth.positions.floor,
                "kind": truth.positions.kind, "frame": truth.positions.frame,
                "origin_lat_lon_deg": truth.positions.origin_lat_lon_deg},
            "step_times_s": truth.step_times_s, "step_count": truth.step_count,
            "step_lengths_m": truth.step_lengths_m,
            "modes": _labels(truth.modes), "landmarks": _labels(truth.landmarks),
            "extra": {k: _extra(v) for k, v in truth.extra.items()},
        },
        "source": recording.source, "format": recording.format, "warnings": list(recording.warnings),
        "meta": json.loads(json.dumps(dict(recording.meta), default=_plain)),
    }
    return state_codec.dumps(state)


def loads(blob: bytes) -> Recording:
    """The :class:`Recording` that :func:`dumps` wrote; :class:`InputError` if ``blob`` is not one."""
    state = state_codec.loads(blob)
    if not isinstance(state, dict) or state.get("version") != VERSION:
        raise InputError("not a stored recording of a known version", source="decoded recording")
    t = state["truth"]
    pos = t["positions"]
    origin = pos and pos["origin_lat_lon_deg"]
    truth = GroundTruth(
        positions=None if pos is None else PositionTruth(
            pos["t_s"], pos["pos_m"], pos["floor"], kind=pos["kind"], frame=pos["frame"],
            origin_lat_lon_deg=None if origin is None else (float(origin[0]), float(origin[1]))),
        step_times_s=t["step_times_s"], step_count=t["step_count"], step_lengths_m=t["step_lengths_m"],
        modes=_from_labels(t["modes"]), landmarks=_from_labels(t["landmarks"]),
        extra={k: np.array(v[_TEXT]) if isinstance(v, dict) else v for k, v in t["extra"].items()})
    streams = {k: SensorStream(k, np.asarray(s["t_ns"]), np.asarray(s["values"])) for k, s in state["streams"].items()}
    return Recording(
        streams=streams,
        device=DeviceInfo(**state["device"]), t0_ns=int(state["t0_ns"]), truth=truth, source=state["source"],
        format=state["format"], warnings=tuple(state["warnings"]), meta=state["meta"])


def _extra(a: np.ndarray) -> Any:
    """A truth extra: numeric and boolean arrays as they are, text arrays as nested lists."""
    return {_TEXT: a.tolist()} if a.dtype.kind in "US" else a


def _plain(obj: Any) -> Any:
    """JSON form of what a reader put in ``meta`` beyond JSON types (numpy values, paths)."""
    if isinstance(obj, np.ndarray | np.generic):
        return obj.tolist()
    return str(obj)


def _labels(labels: Labels | None) -> dict[str, Any] | None:
    if labels is None:
        return None
    return {"t_start_s": labels.t_start_s, "t_end_s": labels.t_end_s, "label": list(labels.label)}


def _from_labels(d: dict[str, Any] | None) -> Labels | None:
    return None if d is None else Labels(d["t_start_s"], d["t_end_s"], tuple(d["label"]))
