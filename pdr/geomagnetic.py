"""The earth's magnetic field at a place and date, from the World Magnetic Model (:mod:`pygeomag`).

A magnetometer indoors sees the earth's field bent and weakened by the building's steel; where the local field's
dip (its angle below the horizontal) departs far from the earth's, its horizontal direction is not north either.
The model gives the dip a location should see, which the attitude filter's magnetometer gate compares the measured
field with (:attr:`pdr.phone.attitude.AttitudeConfig.earth_dip_deg`).
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class EarthField:
    """The main geomagnetic field at a point (WMM).

    Attributes
    ----------
    inclination_deg
        Dip: angle of the field below the local horizontal (deg, positive down: northern hemisphere).
    declination_deg
        Angle of the field's horizontal part east of true north (deg).
    intensity_uT
        Total intensity (uT).
    """

    inclination_deg: float
    declination_deg: float
    intensity_uT: float


def decimal_year(unix_time_s: float) -> float:
    """The UTC calendar year of a Unix time as a decimal (2023.45 is mid-June 2023)."""
    t = dt.datetime.fromtimestamp(unix_time_s, tz=dt.UTC)
    start = dt.datetime(t.year, 1, 1, tzinfo=dt.UTC)
    end = dt.datetime(t.year + 1, 1, 1, tzinfo=dt.UTC)
    return t.year + (t - start) / (end - start)


def earth_field(lat_deg: float, lon_deg: float, unix_time_s: float, alt_m: float = 0.0) -> EarthField | None:
    """The WMM field at WGS-84 ``lat_deg``, ``lon_deg`` and height ``alt_m`` (m) at ``unix_time_s``, or None where
    the model does not answer: a position off the globe, a non-finite value, or a date outside the coefficient sets
    the package ships (WMM 2010 to 2025: 2010-2030).
    """
    values = (lat_deg, lon_deg, unix_time_s, alt_m)
    if not all(math.isfinite(v) for v in values) or abs(lat_deg) > 90 or abs(lon_deg) > 360:
        return None
    from pygeomag import GeoMag  # small and pure Python; imported when a recording has a location
    try:
        year = decimal_year(unix_time_s)
        result = GeoMag(base_year=year).calculate(glat=lat_deg, glon=lon_deg, alt=alt_m / 1000.0, time=year)
    except (ValueError, OverflowError, OSError):
        return None
    return EarthField(float(result.i), float(result.d), float(result.f) / 1000.0)


def field_at_fix(fix: object) -> EarthField | None:
    """:func:`earth_field` at a recording's location fix (``meta["location"]``, :data:`pdr.recording.LOCATION_META`:
    ``lat_deg``, ``lon_deg``, ``unix_time_s``, optional ``alt_m``), or None without a usable fix.
    """
    if not isinstance(fix, Mapping):
        return None
    try:
        lat, lon, t = float(fix["lat_deg"]), float(fix["lon_deg"]), float(fix["unix_time_s"])
        alt = float(fix.get("alt_m") or 0.0)
    except (KeyError, TypeError, ValueError):
        return None
    return earth_field(lat, lon, t, alt)
