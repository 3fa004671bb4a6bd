"""The earth's field model (World Magnetic Model through pygeomag): its physics, units and refusals."""

import math

import pytest

from pdr.geomagnetic import decimal_year, earth_field, field_at_fix

MID_2023 = 1686732686.0     # 2023-06-14 UTC


def test_decimal_year():
    assert decimal_year(0.0) == 1970.0
    assert decimal_year(MID_2023) == pytest.approx(2023.45, abs=0.01)


def test_dip_points_down_in_the_north_up_in_the_south_and_is_level_near_the_magnetic_equator():
    north = earth_field(49.46, 11.11, MID_2023, 365.0)          # Nuremberg
    south = earth_field(-33.87, 151.21, MID_2023)               # Sydney
    equator = earth_field(9.0, 0.0, MID_2023)                   # West Africa, the dip equator
    pole = earth_field(85.0, 0.0, MID_2023)
    assert north is not None and south is not None and equator is not None and pole is not None
    assert 60.0 < north.inclination_deg < 70.0 and 45.0 < north.intensity_uT < 52.0      # uT, not nT
    assert 0.0 < north.declination_deg < 8.0                                              # east of north there
    assert -70.0 < south.inclination_deg < -60.0
    assert abs(equator.inclination_deg) < 15.0 and pole.inclination_deg > 85.0


def test_no_answer_outside_the_model():
    assert earth_field(49.46, 11.11, 1.0e9) is None              # 2001: before the shipped coefficient sets
    assert earth_field(math.nan, 11.11, MID_2023) is None
    assert earth_field(91.0, 11.11, MID_2023) is None


def test_field_at_a_recordings_location_fix():
    fix = {"lat_deg": 49.46, "lon_deg": 11.11, "unix_time_s": MID_2023, "alt_m": 365.0, "fixes": 3}
    assert field_at_fix(fix) == earth_field(49.46, 11.11, MID_2023, 365.0)
    assert field_at_fix({"lat_deg": 49.46, "lon_deg": 11.11}) is None                  # no date
    assert field_at_fix({"lat_deg": "north", "lon_deg": 11.11, "unix_time_s": MID_2023}) is None
    assert field_at_fix(None) is None
