"""The track schema (pdr.phone.track_schema): one definition for the CLI's CSV, the API and the storage."""

from __future__ import annotations

import csv
import dataclasses
import math

import pytest

from pdr.cli.track import write_csv
from pdr.phone.track_schema import TRACK_COLUMNS, TRACK_SCHEMA, csv_fields
from server.api.track_columns import COLUMNS
from server.store import TrackRow

ROW = {"t_s": 12.34567, "east_m": -1.23456, "north_m": 2.0, "up_m": 0.126, "floor": 1.0, "heading_deg": 359.96,
       "step_length_m": 0.6549, "mode": "stairs_up", "placement": "hand"}


def test_columns_carry_their_unit_in_their_name():
    assert TRACK_COLUMNS == ("t_s", "east_m", "north_m", "up_m", "floor", "heading_deg", "step_length_m", "mode")
    for c in TRACK_SCHEMA:
        assert c.dtype in ("float", "str")
        if c.unit:
            assert c.name.endswith("_" + c.unit), c.name


def test_csv_fields_follow_the_schema_formats():
    assert csv_fields(ROW) == ["12.346", "-1.235", "2.000", "0.13", "1", "360.0", "0.655", "stairs_up"]
    assert csv_fields({**ROW, "floor": -0.5})[4] == "-0.5"
    with pytest.raises(KeyError, match="step_length_m"):
        csv_fields({k: v for k, v in ROW.items() if k != "step_length_m"})


def test_pdr_track_csv_has_the_schema_columns(tmp_path):
    out = tmp_path / "t.csv"
    write_csv([ROW, {**ROW, "t_s": 13.0, "east_m": math.pi}], out)
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == TRACK_COLUMNS
    assert rows[2][:2] == ["13.000", "3.142"]


def test_the_service_stores_and_serves_the_same_columns():
    assert tuple(f.name for f in dataclasses.fields(TrackRow)) == TRACK_COLUMNS
    assert COLUMNS[: len(TRACK_COLUMNS)] == TRACK_COLUMNS
