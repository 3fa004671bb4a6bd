"""Encode a :class:`Recording` as Sensor Logger HTTP-push messages (Android convention), e.g. to replay a log.

The inverse of :func:`pdr.io.sensor_logger.parse_push_message` for the streams the app sends: ``acc`` ->
``totalacceleration``, ``lin_acc`` -> ``accelerometer``, ``gravity``, ``gyro`` -> ``gyroscope``, ``mag`` ->
``magnetometer``, ``baro`` -> ``barometer.pressure``, ``orientation`` -> ``orientation`` (qw, qx, qy, qz),
uncalibrated variants. One message per ``period_s`` of data, with consecutive ``messageId`` from 0.
Timestamps are the streams' raw ``t_ns``, offset by ``epoch_offset_ns`` (Sensor Logger sends UTC epoch ns).
A log's location fix (``meta["location"]``) is not replayed: the messages carry sensor streams only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pdr.io.sensor_logger import READINGS
from pdr.recording import Recording

#: Stream kind -> reading name, for the readings the app can send.
STREAM_TO_READING = {kind: name for name, (kind, _) in READINGS.items()}


def to_push_messages(recording: Recording, *, session_id: str, device_id: str, period_s: float = 1.0,
                     epoch_offset_ns: int = 0) -> list[dict[str, Any]]:
    """Push messages covering the recording in consecutive windows of ``period_s`` seconds."""
    if period_s <= 0:
        raise ValueError("period_s must be positive")
    start_ns = min(int(s.t_ns[0]) for s in recording.streams.values() if len(s))
    period_ns = int(round(period_s * 1e9))
    per_window: dict[int, list[dict[str, Any]]] = {}
    for kind, stream in recording.streams.items():
        name = STREAM_TO_READING.get(kind)
        if name is None:
            continue
        comps = READINGS[name][1]
        windows = (stream.t_ns - start_ns) // period_ns
        times = (stream.t_ns + epoch_offset_ns).tolist()
        values = stream.values.tolist()
        for w, t, v in zip(windows.tolist(), times, values, strict=True):
            per_window.setdefault(w, []).append({"name": name, "time": t,
                                                  "values": dict(zip(comps, v, strict=True))})
    messages = []
    for message_id, w in enumerate(sorted(per_window)):
        payload = sorted(per_window[w], key=lambda r: r["time"])
        messages.append({"messageId": message_id, "sessionId": session_id, "deviceId": device_id,
                         "payload": payload})
    return messages


def window_count(recording: Recording, period_s: float) -> int:
    """Number of non-empty windows :func:`to_push_messages` would make (for progress reporting)."""
    start_ns = min(int(s.t_ns[0]) for s in recording.streams.values() if len(s))
    ws = np.concatenate([(s.t_ns - start_ns) // int(round(period_s * 1e9)) for s in recording.streams.values()])
    return int(np.unique(ws).size)
