"""A track (rows of :mod:`pdr.phone.track_schema`) as GeoJSON (RFC 7946), for ``pdr track --geojson`` and the API.

RFC 7946 positions are WGS-84 longitude, latitude in degrees (section 3.1.1), so a track is GeoJSON only when it is
geo-referenced: its local east/north metres are projected about the recording's origin (:func:`pdr.recording.
geo_origin`) with :func:`pdr.frames.local_enu_to_geodetic`. A track without an origin has no GeoJSON
(:class:`NotGeoReferenced`); its CSV holds the local metres. One feature per device: a ``LineString`` of its steps
(at least two positions, section 3.1.4), or a ``Point`` when it has one step. The third coordinate is left out: the
track's ``up_m`` counts from the start, not from the ellipsoid (section 3.1.1); it is in the ``properties`` with the
times, floors and modes, one per position.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from pdr.errors import InputError
from pdr.frames import local_enu_to_geodetic


class NotGeoReferenced(InputError):
    """The track has no geodetic origin, so it has no RFC 7946 GeoJSON."""

    code = "not_geo_referenced"


#: Decimal places of the degrees written (1e-7 deg is about 1 cm).
DEGREE_DECIMALS = 7


def require_origin(origin: tuple[float, float] | None, source: str = "track") -> tuple[float, float]:
    """``origin``; :class:`NotGeoReferenced` naming ``source`` when there is none."""
    if origin is None:
        raise NotGeoReferenced("the track is not geo-referenced (no geodetic origin: no GPS fix or surveyed origin); "
                               "GeoJSON (RFC 7946) needs longitude and latitude: use the CSV's local metres",
                               source=source)
    return origin


def track_geojson(rows: Sequence[Mapping[str, Any]], origin: tuple[float, float] | None,
                  source: str = "track") -> dict[str, Any]:
    """The FeatureCollection of a track's rows (their ``device`` key, when present, splits them into features).

    Parameters
    ----------
    rows
        Track rows: ``east_m``, ``north_m`` (local ENU, m), ``up_m``, ``t_s``, ``floor``, ``mode``.
    origin
        (lat, lon) in degrees of the rows' local origin; None raises :class:`NotGeoReferenced`.
    source
        What the track is, for the error.
    """
    origin = require_origin(origin, source)
    features = []
    for device in dict.fromkeys(str(r.get("device", "")) for r in rows):
        mine = [r for r in rows if str(r.get("device", "")) == device]
        lat, lon = local_enu_to_geodetic([r["east_m"] for r in mine], [r["north_m"] for r in mine], *origin)
        coords = [[round(float(lo), DEGREE_DECIMALS), round(float(la), DEGREE_DECIMALS)]
                  for lo, la in zip(lon, lat, strict=True)]
        geometry = ({"type": "LineString", "coordinates": coords} if len(coords) >= 2
                    else {"type": "Point", "coordinates": coords[0]})
        props: dict[str, Any] = {"steps": len(mine), **({"device": device} if device else {})}
        props.update({k: [r.get(k) for r in mine] for k in ("t_s", "up_m", "floor", "mode")})
        features.append({"type": "Feature", "geometry": geometry, "properties": props})
    return {"type": "FeatureCollection", "features": features}
