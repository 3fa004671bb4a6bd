"""Units, frames, quaternions and time: the project's conventions, in one place.

Units
    SI inside: m/s^2, rad/s, uT, hPa, s, m. Degrees only at the JSON/CSV boundary, in fields named
    ``*_deg``. Readers convert foreign units at ingest (g -> m/s^2, deg/s -> rad/s, Gauss -> uT).

Body (device) frame
    Android sensor axes: x to the right of the screen, y up the screen, z out of the screen. iOS data
    is converted at ingest (units of g -> m/s^2 and the sign of accelerations flipped, since Core Motion
    reports acceleration as -specific force). Foot IMUs keep their own sensor frame.

Accelerometer
    Specific force **including gravity**: a phone lying face-up at rest reads about (0, 0, +9.81) m/s^2.
    Clients that split it (linear acceleration + gravity) are recombined at ingest.

Navigation frame
    ENU: x east, y north, z up. Gravity in ENU is (0, 0, -g); specific force at rest is (0, 0, +g).

Quaternions
    Hamilton, scalar first ``[w, x, y, z]``. ``q_nb`` rotates body vectors into the navigation frame
    (``v_n = q_nb * v_b * q_nb^-1``); :mod:`pdr.quaternion` implements them. ``q`` and ``-q`` are equal.

Heading
    Internal yaw is counter-clockwise from east (the ENU z rotation angle). The user-facing
    ``heading_deg`` is the compass azimuth, clockwise from north, in [0, 360). :func:`yaw_to_heading_deg`
    (:func:`yaw_to_heading_deg_float` for one Python float) and :func:`heading_deg_to_yaw` convert; nothing else
    does.

Time
    float64 seconds on the log's own clock inside (``t_s``, relative to a recording origin ``t0_ns``);
    the raw int64 nanoseconds are kept at ingest (see :mod:`pdr.recording`).

Names carry frame and unit where ambiguity is possible: ``acc_b``, ``q_nb``, ``t_s``, ``heading_deg``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

#: Standard gravity in m/s^2.
GRAVITY_MPS2 = 9.80665
#: Radius in m of the one sphere of the local projection, both ways (:func:`geodetic_to_local_enu`): the WGS-84
#: semi-major axis, as the IPIN reference scorer projects its landmarks.
EARTH_RADIUS_M = 6_378_137.0
#: Earth rotation rate in rad/s.
EARTH_RATE_RADPS = 7.2921150e-5
#: Specific force of a body at rest in ENU.
SPECIFIC_FORCE_AT_REST_N = np.array([0.0, 0.0, GRAVITY_MPS2])


def wrap_angle(a: ArrayLike) -> Array:
    """Wrap angle(s) in rad to [-pi, pi)."""
    a = np.asarray(a, dtype=np.float64)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def wrap_angle_float(a: float) -> float:
    """:func:`wrap_angle` of one angle (rad) as a Python float, bit for bit: Python's ``%`` on floats is numpy's
    remainder (``fmod``, plus the divisor when the signs differ, a zero taking the divisor's sign), without numpy's
    cost per call (the per-step stages).
    """
    return (float(a) + math.pi) % (2.0 * math.pi) - math.pi


def yaw_to_heading_deg(yaw_rad: ArrayLike) -> Array:
    """Internal yaw (rad, counter-clockwise from east) to compass heading in degrees [0, 360)."""
    return np.mod(90.0 - np.degrees(np.asarray(yaw_rad, dtype=np.float64)), 360.0)


def yaw_to_heading_deg_float(yaw_rad: float) -> float:
    """:func:`yaw_to_heading_deg` of one yaw (rad) as a Python float, bit for bit (``math.degrees`` multiplies by
    the same ``180 / pi`` as ``np.degrees``; ``%`` as in :func:`wrap_angle_float`).
    """
    return (90.0 - math.degrees(float(yaw_rad))) % 360.0


def heading_deg_to_yaw(heading_deg: ArrayLike) -> Array:
    """Compass heading in degrees (clockwise from north) to internal yaw in rad, in [-pi, pi)."""
    return wrap_angle(np.radians(90.0 - np.asarray(heading_deg, dtype=np.float64)))


def geodetic_to_local_enu(lat_deg: ArrayLike, lon_deg: ArrayLike, origin_lat_deg: float,
                          origin_lon_deg: float) -> Array:
    """Latitude/longitude (deg) to local (east, north) metres around an origin.

    Equirectangular projection on the sphere of :data:`EARTH_RADIUS_M`, the one Earth model of the project: every
    reader projects with it and every writer (GeoJSON, the map) projects back with :func:`local_enu_to_geodetic`,
    so a position survives the round trip exactly. Returns (..., 2).
    """
    radius_m = EARTH_RADIUS_M
    lat = np.radians(np.asarray(lat_deg, dtype=np.float64))
    lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
    lat0, lon0 = np.radians(origin_lat_deg), np.radians(origin_lon_deg)
    east = (lon - lon0) * np.cos(lat0) * radius_m
    north = (lat - lat0) * radius_m
    return np.stack([east, north], axis=-1)


def local_enu_to_geodetic(east_m: ArrayLike, north_m: ArrayLike, origin_lat_deg: float,
                          origin_lon_deg: float) -> tuple[Array, Array]:
    """Inverse of :func:`geodetic_to_local_enu` (the same sphere): (lat_deg, lon_deg)."""
    radius_m = EARTH_RADIUS_M
    lat0 = np.radians(origin_lat_deg)
    lat = origin_lat_deg + np.degrees(np.asarray(north_m, dtype=np.float64) / radius_m)
    lon = origin_lon_deg + np.degrees(np.asarray(east_m, dtype=np.float64) / (radius_m * np.cos(lat0)))
    return lat, lon


def pressure_to_altitude_m(p_hpa: ArrayLike, p0_hpa: float = 1013.25) -> Array:
    """Barometric altitude (m) of the international standard atmosphere relative to pressure ``p0_hpa``."""
    return 44330.0 * (1.0 - (np.asarray(p_hpa, dtype=np.float64) / p0_hpa) ** (1.0 / 5.255))


def altitude_to_pressure_hpa(h_m: ArrayLike, p0_hpa: float = 1013.25) -> Array:
    """Inverse of :func:`pressure_to_altitude_m`."""
    return p0_hpa * (1.0 - np.asarray(h_m, dtype=np.float64) / 44330.0) ** 5.255
