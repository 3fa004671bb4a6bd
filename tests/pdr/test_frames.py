import numpy as np
import pytest

from pdr import frames


@pytest.mark.parametrize(("yaw", "heading"), [(0.0, 90.0), (np.pi / 2, 0.0), (np.pi, 270.0), (-np.pi / 2, 180.0)])
def test_yaw_heading_conversion(yaw, heading):
    assert frames.yaw_to_heading_deg(yaw) == pytest.approx(heading)
    assert frames.wrap_angle(frames.heading_deg_to_yaw(heading) - yaw) == pytest.approx(0.0, abs=1e-12)


def test_the_float_forms_give_the_array_forms_bits():
    """wrap_angle_float and yaw_to_heading_deg_float (the per-step stages' scalar forms) are the array functions bit
    for bit, on either side of every wrap, at the wraps themselves, on signed zeros and on non-finite angles."""
    rng = np.random.default_rng(7)
    special = [0.0, -0.0, np.pi, -np.pi, 2 * np.pi, -2 * np.pi, np.nextafter(np.pi, 0), np.nextafter(-np.pi, 0),
               np.pi / 2, -np.pi / 2, 1e-300, -1e-300, 1e300, -1e300, np.inf, -np.inf, np.nan]
    angles = np.concatenate([special, rng.uniform(-20.0, 20.0, 20000), rng.normal(0.0, 1e-3, 2000)])
    with np.errstate(invalid="ignore"):
        wrapped = frames.wrap_angle(angles)
        heading = frames.yaw_to_heading_deg(angles)
    assert np.array_equal(np.array([frames.wrap_angle_float(a) for a in angles.tolist()]).view(np.int64),
                          wrapped.view(np.int64))
    assert np.array_equal(np.array([frames.yaw_to_heading_deg_float(a) for a in angles.tolist()]).view(np.int64),
                          heading.view(np.int64))


def test_local_enu_round_trip_and_scale():
    en = frames.geodetic_to_local_enu(49.4620, 11.1110, 49.4611, 11.1110)
    assert en[1] == pytest.approx(100.19, abs=0.01)  # 0.0009 deg of latitude on the WGS-84 semi-major sphere
    lat, lon = frames.local_enu_to_geodetic(25.0, -40.0, 49.4611, 11.1110)
    np.testing.assert_allclose(frames.geodetic_to_local_enu(lat, lon, 49.4611, 11.1110), [25.0, -40.0], atol=1e-9)
    # the inverse is exact: the same sphere both ways (a mean-radius inverse once scaled tracks by 0.11 %)
    lat, lon = np.array([49.4611, 49.4625, 49.4590]), np.array([11.1110, 11.1131, 11.1092])
    en = frames.geodetic_to_local_enu(lat, lon, 49.46, 11.11)
    back = frames.local_enu_to_geodetic(en[:, 0], en[:, 1], 49.46, 11.11)
    np.testing.assert_allclose(back, (lat, lon), rtol=0, atol=1e-12)


def test_pressure_altitude_round_trip():
    h = frames.pressure_to_altitude_m(frames.altitude_to_pressure_hpa(3.0, 976.0), 976.0)
    assert h == pytest.approx(3.0)
    # About 0.12 hPa per metre near sea level.
    assert frames.altitude_to_pressure_hpa(0.0) - frames.altitude_to_pressure_hpa(1.0) == pytest.approx(0.12, abs=0.01)
