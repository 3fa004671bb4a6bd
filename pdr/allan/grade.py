"""Sensor quality grade from the indicative specifications of seed 004 Table 1.

Table 1 gives orders of magnitude for navigation, tactical and consumer grade IMUs ("should not be
used as a definition"); a measured value is assigned the grade whose indicative value is nearest on
a log scale (boundaries at the geometric means). Values more than ten times worse than the
consumer figure are called ``below consumer``. The grade of a sensor is the worst over its graded
parameters and axes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

GRADES: tuple[str, ...] = ("navigation", "tactical", "consumer")
#: The paper of Table 1 (seed 004), as a reader of a report can look it up.
REFERENCE = ("J. Collin, P. Davidson, M. Kirkko-Jaakkola, H. Leppäkoski: Inertial Sensors and Their Applications. "
             "In: Handbook of Signal Processing Systems, 3rd ed., Springer (2019)")
#: Short form of :data:`REFERENCE` for table captions.
REFERENCE_SHORT = "Collin et al. (2019)"
BELOW = "below consumer"

#: Seed 004 Table 1: (sensor, parameter) -> (unit, navigation, tactical, consumer).
TABLE1: Mapping[tuple[str, str], tuple[str, float, float, float]] = {
    ("gyro", "bias_instability"): ("deg/h", 0.003, 0.1, 20.0),
    ("gyro", "angular_random_walk"): ("deg/sqrt(h)", 0.002, 0.1, 0.5),
    ("gyro", "scale_factor_error"): ("%", 0.0005, 0.01, 1.0),
    ("acc", "noise_density"): ("ug/sqrt(Hz)", 10.0, 50.0, 100.0),
    ("acc", "scale_factor_error"): ("%", 0.01, 0.03, 1.0),
    ("acc", "pre_calibration_bias"): ("mg", 0.03, 1.0, 30.0),
}


@dataclass(frozen=True)
class GradeCall:
    """Grade of one measured parameter against Table 1."""

    parameter: str
    value: float
    unit: str
    grade: str
    table: Mapping[str, float]
    axis: str = ""


def grade_value(sensor: str, parameter: str, value: float, axis: str = "") -> GradeCall:
    """Grade one value (in the Table 1 unit of ``(sensor, parameter)``) measured on ``axis`` (x, y, z)."""
    unit, *refs = TABLE1[(sensor, parameter)]
    table = dict(zip(GRADES, (float(r) for r in refs), strict=True))
    logs = np.log10(np.array(refs, dtype=float))
    v = float(value)
    if v <= 0 or not np.isfinite(v):
        grade = GRADES[0] if v <= 0 else BELOW
    else:
        lv = np.log10(v)
        bounds = (logs[:-1] + logs[1:]) / 2.0
        grade = GRADES[int(np.searchsorted(bounds, lv))]
        if v > 10.0 * refs[-1]:
            grade = BELOW
    return GradeCall(parameter=parameter, value=v, unit=str(unit), grade=grade, table=table, axis=axis)


def worst(calls: list[GradeCall]) -> str | None:
    """The lowest grade among ``calls`` (``None`` if empty)."""
    order = (*GRADES, BELOW)
    return max((c.grade for c in calls), key=order.index) if calls else None
