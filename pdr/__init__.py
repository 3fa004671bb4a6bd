"""Pedestrian dead reckoning and foot-mounted navigation library.

Conventions (units, frames, quaternions, time) are written once, in :mod:`pdr.frames`.

The data model's classes (:mod:`pdr.recording`) are exported here but imported on first use, so that importing a
subpackage (``pdr --help`` imports :mod:`pdr.cli`) does not load numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pdr.errors import InputError, UnknownFormatError

if TYPE_CHECKING:
    from pdr.recording import DeviceInfo, GroundTruth, Labels, PositionTruth, Recording, SensorStream

#: Names exported from :mod:`pdr.recording`, imported by :func:`__getattr__` when first asked for.
_RECORDING_NAMES = frozenset({"DeviceInfo", "GroundTruth", "Labels", "PositionTruth", "Recording", "SensorStream"})

__all__ = [
    "DeviceInfo",
    "GroundTruth",
    "InputError",
    "Labels",
    "PositionTruth",
    "Recording",
    "SensorStream",
    "UnknownFormatError",
]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    """The data model's classes on first use (module doc)."""
    if name in _RECORDING_NAMES:
        from pdr import recording
        return getattr(recording, name)
    raise AttributeError(f"module 'pdr' has no attribute {name!r}")
