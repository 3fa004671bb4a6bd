"""Per-stride features of a thigh-carried phone: simulate a swinging, bobbing thigh and recover its motion."""

from __future__ import annotations

import numpy as np
import pytest

from classifiers.feature_kernels import rotate_to_first
from classifiers.features import FEATURE_GROUPS, extract_features, feature_names
from classifiers.stride_features import STRIDE_FEATURES, stride_features
from classifiers.windows import make_windows
from pdr import quaternion as quat
from pdr.recording import Recording, SensorStream

RATE = 50.0
N = 128  # a 2.56 s window
G = 9.81


def _rot_x(theta: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations about x by ``theta`` (rad): body -> world."""
    c, s = np.cos(theta), np.sin(theta)
    r = np.zeros((theta.size, 3, 3))
    r[:, 0, 0] = 1.0
    r[:, 1, 1], r[:, 1, 2], r[:, 2, 1], r[:, 2, 2] = c, -s, s, c
    return r


def _thigh(theta, z, x, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame specific force and rate of a phone pitched by ``theta(t)`` about body x (the hip's axis) and
    moved by ``z(t)`` up and ``x(t)`` forward (world y); the gyro is each interval's mean rate, as a box-
    averaged grid gives it, so the attitude integration is exact."""
    dt = t[1] - t[0]
    th = theta(t)
    acc_w = np.zeros((t.size, 3))
    acc_w[:, 2] = np.gradient(np.gradient(z(t), dt), dt) + G
    acc_w[:, 1] = np.gradient(np.gradient(x(t), dt), dt)
    f_b = np.einsum("nji,nj->ni", _rot_x(th), acc_w)  # R^T (a + g)
    gyro = np.zeros((t.size, 3))
    gyro[:, 0] = (theta(t + dt) - th) / dt
    return f_b, gyro


def _features(theta, z, x, period_s: float = 1.1) -> dict[str, float]:
    t = np.arange(N) / RATE
    f_b, gyro = _thigh(theta, z, x, t)
    out = stride_features(f_b[None], gyro[None], RATE)[0]
    return dict(zip(STRIDE_FEATURES, out, strict=True))


def test_rotation_kernel_matches_quaternion_reference() -> None:
    rng = np.random.default_rng(3)
    f = rng.normal(size=(4, 64, 3))
    g = rng.normal(size=(4, 64, 3))
    dt = 1.0 / RATE
    q = np.tile(quat.IDENTITY, (4, 1))
    ref = np.empty_like(f)
    for k in range(64):
        ref[:, k] = quat.rotate(q, f[:, k])
        q = quat.multiply(q, quat.from_rotvec(g[:, k] * dt))
    np.testing.assert_allclose(rotate_to_first(f, g, dt), ref, atol=1e-12)


def test_a_swinging_thigh_under_gravity_alone_has_no_vertical_motion() -> None:
    # The window-mean gravity projection would see the 0.5 rad swing as ~1.2 m/s^2 of vertical acceleration.
    swing = _features(lambda t: 0.5 * np.sin(2 * np.pi * t / 1.1), lambda t: 0 * t, lambda t: 0 * t)
    assert swing["stride_z_range_m"] < 1e-3
    assert swing["stride_h_range_m"] < 1e-3
    assert swing["stride_pitch_range_rad"] == pytest.approx(1.0, rel=0.05)


def test_period_excursions_and_pitch_are_recovered() -> None:
    period, a_z, a_x, theta0 = 1.1, 0.06, 0.12, 0.4
    w = 2 * np.pi / period
    f = _features(lambda t: theta0 * np.sin(w * t) + 0.2, lambda t: a_z * np.sin(w * t + 1.0),
                  lambda t: a_x * np.sin(w * t))
    assert f["stride_period_s"] == pytest.approx(period, abs=1.5 / RATE)
    assert f["stride_regularity"] > 0.5
    assert f["stride_z_range_m"] == pytest.approx(2 * a_z, rel=0.15)
    assert f["stride_h_range_m"] == pytest.approx(2 * a_x, rel=0.15)
    assert f["stride_pitch_range_rad"] == pytest.approx(2 * theta0, rel=0.1)
    assert f["stride_zh_log_disp"] == pytest.approx(np.log10(a_z / a_x), abs=0.1)
    assert f["stride_vh_log_energy"] == pytest.approx(2 * np.log10(a_z / a_x), abs=0.15)
    # More vertical than horizontal motion flips the sign of both ratios.
    g = _features(lambda t: theta0 * np.sin(w * t), lambda t: a_x * np.sin(w * t + 1.0),
                  lambda t: a_z * np.sin(w * t))
    assert g["stride_zh_log_disp"] > 0.2 and g["stride_vh_log_energy"] > 0.4


def test_time_reversal_flips_the_vertical_velocity_skew_and_the_swing_duty() -> None:
    # Short strong upward pushes (a climb's concentric phases); the same motion played backwards lowers the
    # body in short strong phases: the velocity's skewness changes sign.
    w = 2 * np.pi / 1.2
    z = lambda t: 0.05 * (np.sin(w * t) + 0.35 * np.sin(2 * w * t + 0.5))  # noqa: E731
    theta = lambda t: 0.4 * (np.sin(w * t) + 0.3 * np.sin(2 * w * t + 0.5))  # noqa: E731
    x = lambda t: 0.1 * np.sin(w * t + 0.3)  # noqa: E731
    fwd = _features(theta, z, x)
    back = _features(lambda t: theta(-t), lambda t: z(-t), lambda t: x(-t))
    assert abs(fwd["stride_vz_skew"]) > 0.2
    assert back["stride_vz_skew"] == pytest.approx(-fwd["stride_vz_skew"], abs=0.1)
    # The rate's fast direction is positive either way; a fast swing is a short one.
    assert fwd["stride_swing_duty"] < 0.5 and back["stride_swing_duty"] < 0.5


def test_stride_features_are_invariant_to_how_the_phone_sits_in_the_pocket() -> None:
    w = 2 * np.pi / 1.1
    t = np.arange(N) / RATE
    f_b, gyro = _thigh(lambda s: 0.5 * np.sin(w * s) + 0.3 * np.sin(2 * w * s), lambda s: 0.05 * np.sin(w * s),
                       lambda s: 0.1 * np.sin(w * s + 0.4), t)
    ref = stride_features(f_b[None], gyro[None], RATE)[0]
    # Any fixed mounting, including one that turns the hip axis around (the rate's sign flips).
    for c in (quat.to_rotmat(quat.from_rotvec([0.3, -1.1, 0.7])), np.diag([-1.0, -1.0, 1.0])):
        out = stride_features((f_b @ c.T)[None], (gyro @ c.T)[None], RATE)[0]
        np.testing.assert_allclose(out, ref, rtol=1e-6, atol=1e-6)


def test_stride_group_is_nan_without_gyro() -> None:
    t = np.arange(int(10 * RATE)) / RATE
    f_b, gyro = _thigh(lambda s: 0.4 * np.sin(2 * np.pi * s), lambda s: 0.04 * np.sin(2 * np.pi * s),
                       lambda s: 0.1 * np.sin(2 * np.pi * s), t)
    t_ns = (1e9 + t * 1e9).astype(np.int64)
    acc = SensorStream("acc", t_ns, f_b)
    both = make_windows(Recording({"acc": acc, "gyro": SensorStream("gyro", t_ns, gyro)}, t0_ns=int(t_ns[0])))
    only_acc = make_windows(Recording({"acc": acc}, t0_ns=int(t_ns[0])))
    assert FEATURE_GROUPS["stride"] == ("gyro", STRIDE_FEATURES)
    assert feature_names(("stride",)) == list(STRIDE_FEATURES)
    assert np.isfinite(extract_features(both, ("stride",))).all()
    assert np.isnan(extract_features(only_acc, ("stride",))).all()
