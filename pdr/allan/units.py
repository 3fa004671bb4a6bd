"""SI and datasheet units of the IEEE noise terms.

SI (as fitted, :mod:`pdr.allan.noise_model`) for a gyro / an accelerometer:
Q rad / m/s, N rad/sqrt(s) / m/s/sqrt(s), B rad/s / m/s^2, K rad/s/sqrt(s) / m/s^2/sqrt(s),
R rad/s^2 / m/s^3. Datasheets quote N as angle / velocity random walk per sqrt(hour) and as a noise
density, B in deg/h or micro-g, K per sqrt(hour). ``1/sqrt(s) = 60/sqrt(h)``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2

DEG = 180.0 / np.pi
SQRT_H = 60.0  # sqrt(3600 s / h)
UG = 1e6 / GRAVITY_MPS2  # micro-g per m/s^2

#: SI unit of each term per sensor.
SI_UNITS: Mapping[str, Mapping[str, str]] = {
    "gyro": {"Q": "rad", "N": "rad/s/sqrt(Hz)", "B": "rad/s", "K": "rad/s/sqrt(s)", "R": "rad/s^2"},
    "acc": {"Q": "m/s", "N": "m/s^2/sqrt(Hz)", "B": "m/s^2", "K": "m/s^2/sqrt(s)", "R": "m/s^3"},
}

#: term -> list of (datasheet unit, factor from SI).
_DATASHEET: Mapping[str, Mapping[str, tuple[tuple[str, float], ...]]] = {
    "gyro": {
        "Q": (("deg", DEG), ("arcsec", DEG * 3600.0)),
        "N": (("deg/sqrt(h)", DEG * SQRT_H), ("deg/s/sqrt(Hz)", DEG)),
        "B": (("deg/h", DEG * 3600.0), ("deg/s", DEG)),
        "K": (("deg/h/sqrt(h)", DEG * 3600.0 * SQRT_H),),
        "R": (("deg/h^2", DEG * 3600.0**2),),
    },
    "acc": {
        "Q": (("m/s", 1.0),),
        "N": (("m/s/sqrt(h)", SQRT_H), ("ug/sqrt(Hz)", UG)),
        "B": (("ug", UG), ("mg", UG * 1e-3)),
        "K": (("m/s^2/sqrt(h)", SQRT_H), ("ug/sqrt(h)", UG * SQRT_H)),
        "R": (("ug/h", UG * 3600.0),),
    },
}


def check_sensor(sensor: str) -> str:
    if sensor not in SI_UNITS:
        raise InputError(f"unknown sensor '{sensor}'; expected one of {sorted(SI_UNITS)}", field="sensor")
    return sensor


def to_datasheet(sensor: str, term: str, value_si: float | None) -> dict[str, float | None]:
    """``{unit: value}`` of one term in every datasheet unit (values ``None`` when ``value_si`` is)."""
    check_sensor(sensor)
    return {unit: (None if value_si is None else float(value_si) * f) for unit, f in _DATASHEET[sensor][term]}


def headline_unit(sensor: str, term: str) -> str:
    """The first (headline) datasheet unit of a term."""
    return _DATASHEET[check_sensor(sensor)][term][0][0]
