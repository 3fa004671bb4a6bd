"""Pedestrian dead reckoning and foot-mounted navigation library.

Conventions (units, frames, quaternions, time) are written once, in :mod:`pdr.frames`.
"""

from pdr.errors import InputError, UnknownFormatError
from pdr.recording import DeviceInfo, GroundTruth, Labels, PositionTruth, Recording, SensorStream

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
