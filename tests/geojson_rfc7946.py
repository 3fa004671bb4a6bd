"""Checks of a GeoJSON document against RFC 7946 (the parts a track uses), for the CLI's and the API's tests."""

from __future__ import annotations

import math
from typing import Any

import jsonschema

_POSITION = {"type": "array", "minItems": 2, "maxItems": 3, "items": {"type": "number"}}
_GEOMETRY = {"oneOf": [
    {"type": "object", "required": ["type", "coordinates"],
     "properties": {"type": {"const": "Point"}, "coordinates": _POSITION}},
    {"type": "object", "required": ["type", "coordinates"],    # section 3.1.4: two or more positions
     "properties": {"type": {"const": "LineString"}, "coordinates": {"type": "array", "minItems": 2,
                                                                     "items": _POSITION}}},
]}
#: Section 3.2 (Feature) and 3.3 (FeatureCollection); "crs" was removed from GeoJSON (section 4).
SCHEMA = {"type": "object", "required": ["type", "features"], "not": {"required": ["crs"]},
          "properties": {"type": {"const": "FeatureCollection"}, "features": {"type": "array", "items": {
              "type": "object", "required": ["type", "geometry", "properties"], "not": {"required": ["crs"]},
              "properties": {"type": {"const": "Feature"}, "geometry": _GEOMETRY,
                             "properties": {"type": ["object", "null"]}}}}}}


def positions(doc: dict[str, Any]) -> list[list[float]]:
    """Every position of the document's features."""
    out: list[list[float]] = []
    for f in doc["features"]:
        g = f["geometry"]
        out += [g["coordinates"]] if g["type"] == "Point" else g["coordinates"]
    return out


def check_rfc7946(doc: dict[str, Any]) -> None:
    """AssertionError unless ``doc`` is a valid RFC 7946 FeatureCollection of Points and LineStrings whose positions
    are longitude, latitude in degrees (section 3.1.1)."""
    jsonschema.validate(doc, SCHEMA)
    for lon, lat, *_ in positions(doc):
        assert math.isfinite(lon) and -180 <= lon <= 180, lon
        assert math.isfinite(lat) and -90 <= lat <= 90, lat
