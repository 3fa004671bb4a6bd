"""The clock of a session's times, stated in every API answer that carries times (``"clock"``).

Every ``t_s`` of a session's track, steps and events is in seconds on the log's own clock: the raw timestamps in
nanoseconds divided by 1e9, whatever they count from (Unix time for Sensor Logger and native pushes, the phone's
time since boot for Oxford, MobiFall and most Android files, the app's AppTimestamp for IPIN logs). So an Oxford
upload's track starts near 584 401 s (six days after boot) and an IPIN track near 0 s. ``t0_ns`` is where the
session's recording starts on that clock: the uploaded recording's origin (:attr:`pdr.recording.Recording.t0_ns`),
else the first stored sample. Truth positions (``GET .../truth``) count their ``t_s`` from their file's ``t0_ns``.
"""

from __future__ import annotations

from typing import Any

from server.store import Store

#: What every ``t_s`` of a session means, once for every answer.
CLOCK_NOTE = ("t_s: seconds on the log's own clock (its raw timestamps in ns / 1e9: Unix time for pushes, time "
              "since boot for most Android files, AppTimestamp for IPIN logs); the recording starts at t0_ns")


def session_clock(store: Store, row: Any) -> dict[str, Any]:
    """``{"t0_ns", "t0_s", "t_s"}`` of a session row: where it starts on its clock and what ``t_s`` means."""
    t0_ns = row.t0_ns if row.t0_ns is not None else store.first_sample_ns(row.id)
    return {"t0_ns": t0_ns, "t0_s": None if t0_ns is None else t0_ns / 1e9, "t_s": CLOCK_NOTE}
