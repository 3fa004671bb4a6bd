"""Unit-mistake detection: simulate data in each unit, then recover the unit; ambiguous data is rejected."""

from __future__ import annotations

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2
from pdr.recording import Recording, SensorStream
from pdr.units import (
    check_units,
    detect_acc_unit,
    detect_gyro_unit,
    detect_mag_unit,
    detect_pressure_unit,
    tilt_rate_ratio,
)

RATE_HZ = 100.0
EARTH_FIELD_N_UT = np.array([0.0, 20.0, -40.0])  # ENU, ~45 uT, dipping down (northern hemisphere)


def _motion(seconds: float = 30.0, tilt_radps: float = 0.4, seed: int = 0, lin_acc_mps2: float = 1.5):
    """Smoothly tumbling device: (t_s, gyro rad/s, acc m/s^2 incl. gravity and step-frequency linear
    acceleration, mag uT), all in the body frame."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE_HZ)
    freqs = rng.uniform(0.2, 0.8, size=3)
    phases = rng.uniform(0, 2 * np.pi, size=3)
    gyro = tilt_radps * np.sin(2 * np.pi * freqs * t[:, None] + phases)
    q = quat.integrate_gyro(quat.IDENTITY, gyro[:-1], np.diff(t))
    q_bn = quat.conjugate(q)
    lin_n = np.zeros((t.size, 3))
    lin_n[:, 0] = lin_acc_mps2 * np.sin(2 * np.pi * 2.0 * t)
    lin_n[:, 2] = lin_acc_mps2 * np.sin(2 * np.pi * 2.0 * t + 1.0)
    acc = quat.rotate(q_bn, np.array([0.0, 0.0, GRAVITY_MPS2]) + lin_n) + 0.05 * rng.standard_normal((t.size, 3))
    mag = quat.rotate(q_bn, EARTH_FIELD_N_UT) + 0.3 * rng.standard_normal((t.size, 3))
    gyro_meas = gyro + 0.003 * rng.standard_normal((t.size, 3))
    return t, gyro_meas, acc, mag


def _recording(t, **streams) -> Recording:
    t_ns = np.round(t * 1e9).astype(np.int64)
    return Recording({k: SensorStream(k, t_ns, v) for k, v in streams.items()}, source="synthetic")


@pytest.mark.parametrize(("unit", "scale"), [("m/s^2", 1.0), ("g", 1 / GRAVITY_MPS2), ("mg", 1000 / GRAVITY_MPS2)])
def test_acc_unit_recovered_from_walking_and_static(unit, scale):
    _, _, acc, _ = _motion()
    assert detect_acc_unit(acc * scale) == unit
    static = np.tile([0.1, 0.2, GRAVITY_MPS2], (200, 1))
    assert detect_acc_unit(static * scale) == unit


def test_acc_unit_undecided_for_linear_acceleration_only():
    rng = np.random.default_rng(1)
    assert detect_acc_unit(3.0 * rng.standard_normal((500, 3))) is None


@pytest.mark.parametrize(("unit", "scale"), [("uT", 1.0), ("G", 0.01), ("nT", 1000.0)])
def test_mag_unit_recovered(unit, scale):
    _, _, _, mag = _motion()
    assert detect_mag_unit(mag * scale) == unit
    assert detect_mag_unit(mag * scale + 3.0 * scale * np.array([40.0, -30.0, 10.0])) == unit  # hard iron


@pytest.mark.parametrize(("unit", "scale"), [("hPa", 1.0), ("kPa", 0.1), ("Pa", 100.0)])
@pytest.mark.parametrize("p_hpa", [1013.25, 850.0, 1040.0])
def test_pressure_unit_recovered(unit, scale, p_hpa):
    p = p_hpa + 0.05 * np.random.default_rng(2).standard_normal(300)
    assert detect_pressure_unit(p * scale) == unit
    assert detect_pressure_unit((p * scale)[:, None]) == unit


def test_pressure_nonsense_undecided():
    assert detect_pressure_unit(np.full(10, 5.0)) is None


def test_tilt_rate_ratio_is_one_for_rad_s_and_pi_over_180_for_deg_s():
    t, gyro, acc, _ = _motion()
    r = tilt_rate_ratio(t, gyro, t, acc)
    assert r == pytest.approx(1.0, rel=0.3)
    r_deg = tilt_rate_ratio(t, np.degrees(gyro), t, acc)
    assert r_deg == pytest.approx(np.pi / 180, rel=0.3)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_gentle_motion_gyro_unit_recovered_via_accelerometer(seed):
    t, gyro, acc, _ = _motion(seed=seed, tilt_radps=0.4)
    # magnitude alone cannot tell: 0.4 rad/s is 23 deg/s, plausible in either unit
    assert detect_gyro_unit(np.degrees(gyro)) is None
    assert detect_gyro_unit(gyro, t, t, acc) == "rad/s"
    assert detect_gyro_unit(np.degrees(gyro), t, t, acc / GRAVITY_MPS2) == "deg/s"  # acc unit is irrelevant


def test_fast_motion_in_deg_s_recovered_from_magnitude_alone():
    _, gyro, _, _ = _motion(tilt_radps=3.0)
    assert detect_gyro_unit(np.degrees(gyro)) == "deg/s"
    assert detect_gyro_unit(gyro) is None


def test_static_gyro_undecided():
    rng = np.random.default_rng(4)
    t = np.arange(0, 20, 0.01)
    gyro = 0.002 * rng.standard_normal((t.size, 3)) + 0.01
    acc = np.tile([0.0, 0.0, GRAVITY_MPS2], (t.size, 1)) + 0.02 * rng.standard_normal((t.size, 3))
    assert detect_gyro_unit(gyro, t, t, acc) is None
    assert detect_gyro_unit(np.degrees(gyro), t, t, acc) is None


def test_check_units_converts_clear_mistakes_with_warnings():
    t, gyro, acc, mag = _motion()
    truth = _recording(t, acc=acc, gyro=gyro, mag=mag)
    wrong = _recording(t, acc=acc / GRAVITY_MPS2, gyro=np.degrees(gyro), mag=mag / 100.0)
    fixed = check_units(wrong)
    for k in ("acc", "gyro", "mag"):
        np.testing.assert_allclose(fixed.values(k), truth.values(k), rtol=1e-12, atol=1e-12)
    assert len(fixed.warnings) == 3
    assert any("'gyro'" in w and "deg/s" in w for w in fixed.warnings)
    assert any("'acc'" in w and "look like g" in w for w in fixed.warnings)


def test_check_units_leaves_si_data_unchanged():
    t, gyro, acc, mag = _motion()
    rec = _recording(t, acc=acc, gyro=gyro, mag=mag)
    assert check_units(rec) is rec


def test_check_units_static_gyro_needs_a_fallback():
    t = np.arange(0, 10, 0.01)
    rng = np.random.default_rng(5)
    acc = np.tile([0.0, 0.0, GRAVITY_MPS2], (t.size, 1)) + 0.02 * rng.standard_normal((t.size, 3))
    rec = _recording(t, acc=acc, gyro=0.001 * rng.standard_normal((t.size, 3)))
    with pytest.raises(InputError, match=r"stream 'gyro'.*cannot tell the unit"):
        check_units(rec)
    assert check_units(rec, fallback={"gyro": "rad/s"}) is rec
    as_deg = check_units(rec, fallback={"gyro": "deg/s"})
    np.testing.assert_allclose(as_deg.values("gyro"), np.radians(rec.values("gyro")))
    assert as_deg.warnings


def test_check_units_ambiguous_acc_is_rejected():
    t = np.arange(0, 5, 0.01)
    rec = _recording(t, acc=np.tile([0.0, 0.0, 3.0], (t.size, 1)))
    with pytest.raises(InputError, match=r"stream 'acc'.*median norm 3"):
        check_units(rec)


def test_check_units_bad_arguments():
    t = np.arange(0, 5, 0.01)
    rec = _recording(t, acc=np.tile([0.0, 0.0, 9.8], (t.size, 1)))
    with pytest.raises(InputError, match="cannot check the unit"):
        check_units(rec, kinds=["orientation"])
    with pytest.raises(InputError, match="unknown fallback unit"):
        check_units(rec, fallback={"gyro": "rpm"})


def test_detectors_reject_bad_shapes():
    with pytest.raises(InputError, match="accelerometer"):
        detect_acc_unit(np.zeros((0, 3)))
    with pytest.raises(InputError, match="magnetometer"):
        detect_mag_unit(np.zeros((5, 2)))


# ------------------------------------------------------------------------------ real recordings

REAL_RAD_S = [
    ("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt"),  # hand-held
    ("ms_indoor_location", "site2", "F3", "path_data_files", "5dd51a7650e04e0006f5642c.txt.gz"),  # hand-held
    ("mobifall_v2_pocket", "sub2", "ADL", "WAL", "WAL_acc_2_1.txt.gz"),  # trouser pocket
    ("pyshoe_vicon", "2017-11-22-11-22-03.mat"),  # foot
]


@pytest.mark.data
@pytest.mark.parametrize("parts", REAL_RAD_S, ids=lambda p: p[0])
def test_real_gyros_in_rad_s_are_recognised_and_would_be_caught_in_deg_s(parts):
    from pdr.io.registry import read_recording
    from tests.conftest import data_path

    rec = read_recording(data_path(*parts))
    o = rec.origin_ns
    g, a = rec.stream("gyro"), rec.stream("acc")
    assert detect_gyro_unit(g.values, g.t_s(o), a.t_s(o), a.values) == "rad/s"
    assert detect_gyro_unit(np.degrees(g.values), g.t_s(o), a.t_s(o), a.values) == "deg/s"
    assert detect_acc_unit(a.values) == "m/s^2"
    assert detect_acc_unit(a.values / GRAVITY_MPS2) == "g"
    assert check_units(rec) is rec  # SI data passes untouched
    wrong = rec.with_streams({"gyro": SensorStream("gyro", g.t_ns, np.degrees(g.values)),
                              "acc": SensorStream("acc", a.t_ns, a.values / GRAVITY_MPS2)})
    fixed = check_units(wrong)
    np.testing.assert_allclose(fixed.values("gyro"), g.values, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(fixed.values("acc"), a.values, rtol=1e-12)


def test_absurd_magnitudes_are_no_unit_and_raise_no_overflow():
    # Finite values whose squares overflow (a fuzzed batch's 1e200) are told apart without a floating-point error.
    huge = np.full((20, 3), 1e200)
    assert detect_acc_unit(huge) is None and detect_mag_unit(huge) is None
    assert detect_gyro_unit(huge) == "deg/s"            # beyond any human motion in rad/s, as before
