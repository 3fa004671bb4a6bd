"""The phone recordings of the shared datasets that the evaluations walk through: which are walking and which carry
a placement label.

Walking: ``sensor_logger_walks`` (every walk), ``oxford_step_counter`` (every trial), ``mobifall_v2_pocket`` WAL,
STU and STN (walking, stairs up and down), ``ms_indoor_location`` (every trace), ``ipin2023_t3`` (every log),
``attitude_smartphones`` (every recording; RunningPocket is running). Not walking: MobiFall CSI and CSO (getting
into and out of a car), SCH (sitting down on a chair), STD (standing) and JUM (jumping).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

#: MobiFall activity codes (folder names) of walking and of activities with no step.
MOBIFALL_WALKING = ("WAL", "STU", "STN")
MOBIFALL_NOT_WALKING = ("CSI", "CSO", "SCH", "STD", "JUM")


def recordings(data: Path) -> Iterator[tuple[str, Path, bool]]:
    """(dataset, path, walking) of every phone recording of the shared datasets under ``data`` (module doc)."""
    for d in sorted((data / "sensor_logger_walks").glob("*-steps-*")):
        yield "sensor_logger_walks", d, True
    for d in sorted((data / "oxford_step_counter" / "optimisation" / "data").glob("*")):
        if d.is_dir() and any(d.glob("accelerometer.csv*")):
            yield "oxford_step_counter", d, True
    for code in MOBIFALL_WALKING + MOBIFALL_NOT_WALKING:
        for f in sorted((data / "mobifall_v2_pocket").glob(f"sub*/ADL/{code}/{code}_acc_*.txt*")):
            yield f"mobifall {code}", f, code in MOBIFALL_WALKING
    for f in sorted((data / "ms_indoor_location").rglob("path_data_files/*.txt*")):
        yield "ms_indoor_location", f, True
    for f in sorted((data / "ipin2023_t3" / "logfiles").glob("*.txt")):
        yield "ipin2023_t3", f, True
    for d in sorted((data / "attitude_smartphones" / "android").glob("*")):
        if d.is_dir():
            yield "attitude_smartphones", d, True
