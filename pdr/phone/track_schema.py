"""The track's columns: one row per step, written by ``pdr track`` (CSV), served by the API (``/track`` as JSON, CSV
and GeoJSON, ``/track/columns``) and stored by the service (``server.store.TrackRow``).

Units are SI except the user-facing heading (compass azimuth in degrees, :func:`pdr.frames.yaw_to_heading_deg`);
positions are local ENU metres from the start of the recording, times on the log's own clock.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrackColumn:
    """One column of the track.

    Attributes
    ----------
    name
        Column name (its unit is its suffix where it has one).
    unit
        Unit (``""``: a number without unit or a label).
    dtype
        ``"float"`` or ``"str"``; a stored row may hold null where a device does not measure it (a foot track's
        floor).
    csv_format
        Format specification of the value in ``pdr track``'s CSV (:func:`format`).
    description
        What the value is.
    """

    name: str
    unit: str
    dtype: str
    csv_format: str
    description: str


TRACK_SCHEMA: tuple[TrackColumn, ...] = (
    TrackColumn("t_s", "s", "float", ".3f", "end of the step, on the log's clock"),
    TrackColumn("east_m", "m", "float", ".3f", "position east of the start (ENU)"),
    TrackColumn("north_m", "m", "float", ".3f", "position north of the start (ENU)"),
    TrackColumn("up_m", "m", "float", ".2f", "height above the start (barometer, else 0)"),
    TrackColumn("floor", "", "float", "g", "floor number (the recording's initial floor plus the floor changes)"),
    TrackColumn("heading_deg", "deg", "float", ".1f", "walking direction, compass azimuth clockwise from north"),
    TrackColumn("step_length_m", "m", "float", ".3f", "horizontal length of the step"),
    TrackColumn("mode", "", "str", "s", "motion mode of the step (walking, stairs_up, ...)"),
)

#: The column names, in order.
TRACK_COLUMNS: tuple[str, ...] = tuple(c.name for c in TRACK_SCHEMA)


def csv_fields(row: dict[str, object]) -> list[object]:
    """The CSV fields of one track row (a step event or a dict with the columns' names), formatted per the schema;
    a label column is passed through as it is.
    """
    return [row[c.name] if c.dtype == "str" else format(row[c.name], c.csv_format) for c in TRACK_SCHEMA]
