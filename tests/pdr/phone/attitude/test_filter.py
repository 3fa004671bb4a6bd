"""Attitude filter (the driver over the compiled kernel): analytic truth (stationary, constant rate), UKF vs EKF,
gyro bias, state round trip and chunked runs."""

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2
from pdr.phone.attitude import AttitudeConfig, AttitudeFilter, AttitudeState, gyro_compensated, yaw_of_axis
from pdr.phone.attitude.config import FloatArray

FS = 50.0
H_ENU = np.array([0.0, 20.0, -44.0])  # magnetic field (uT), north and down


def body_measurements(q_nb, n, rng=None, noise=0.0):
    g_b = quat.rotate(quat.conjugate(q_nb), np.array([0.0, 0.0, GRAVITY_MPS2]))
    m_b = quat.rotate(quat.conjugate(q_nb), H_ENU)
    acc = np.tile(g_b, (n, 1))
    mag = np.tile(m_b, (n, 1))
    if rng is not None:
        acc = acc + rng.normal(0, noise, acc.shape)
        mag = mag + rng.normal(0, 10 * noise, mag.shape)
    return acc, mag


@pytest.mark.parametrize("method", ["ukf", "ekf"])
@pytest.mark.parametrize("rpy_deg", [(0, 0, 30), (20, -10, 135), (-35, 25, -100)])
def test_stationary_attitude_from_gravity_and_field(method, rpy_deg):
    q_true = quat.from_euler(*np.radians(rpy_deg))
    rng = np.random.default_rng(1)
    acc, mag = body_measurements(q_true, 500, rng, 0.02)
    cfg = AttitudeConfig(mag_when_static=True)
    q, used = AttitudeFilter(FS, cfg, method=method).run(acc, np.zeros((500, 3)), mag)
    assert math.degrees(quat.angle_between(q[-1], q_true)) < 1.0
    assert np.all(np.abs(np.linalg.norm(q, axis=1) - 1) < 1e-9)
    assert (used[-100:] & 1).all() and (used[-100:] & 2).all()


@pytest.mark.parametrize("method", ["ukf", "ekf"])
def test_constant_rate_yaw_follows_gyro(method):
    n, rate = 250, 0.4  # 5 s at 0.4 rad/s about up, device flat
    t = np.arange(n) / FS
    q_true = quat.from_euler(np.zeros(n), np.zeros(n), 0.3 + rate * (t + 1 / FS))
    acc = np.tile([0.0, 0.0, GRAVITY_MPS2], (n, 1))
    gyro = np.tile([0.0, 0.0, rate], (n, 1))
    f = AttitudeFilter(FS, method=method)
    f.state.q[:] = quat.from_euler(0.0, 0.0, 0.3)
    f.state.aux[9] = 1  # skip the initial alignment (no magnetometer here)
    q, _ = f.run(acc, gyro, None)
    err = np.degrees(quat.angle_between(q, q_true))
    assert err.max() < 0.5


def test_gyro_bias_estimated_when_stationary():
    n = int(30 * FS)
    q_true = quat.from_euler(0.1, -0.2, 1.0)
    acc, mag = body_measurements(q_true, n)
    bias = np.array([0.01, -0.02, 0.015])
    f = AttitudeFilter(FS)
    q, used = f.run(acc, np.tile(bias, (n, 1)), mag)
    assert np.allclose(f.state.bias, bias, atol=1e-3)
    assert (used & 4).any()


def trembling_hand(n, rng):
    """A standing user's hand-held phone: slow drift and 7 Hz tremor of the attitude; body rates (rad/s)."""
    t = np.arange(n) / FS
    rv = np.column_stack([0.05 * np.sin(2 * np.pi * 0.3 * t) + 0.02 * t / 30,
                          0.04 * np.sin(2 * np.pi * 0.5 * t + 1),
                          0.3 + 0.06 * t / 30 + 0.004 * np.sin(2 * np.pi * 7 * t)])
    q_true = quat.normalize(quat.multiply(quat.from_rotvec(rv), quat.from_euler(0.3, -0.4, 0.0)))
    omega = 2 * quat.multiply(quat.conjugate(q_true), np.gradient(q_true, 1 / FS, axis=0))[:, 1:]
    acc = quat.rotate(quat.conjugate(q_true), np.array([0.0, 0.0, GRAVITY_MPS2]))
    mag = quat.rotate(quat.conjugate(q_true), H_ENU)
    return q_true, omega, acc + rng.normal(0, 0.02, acc.shape), mag + rng.normal(0, 0.3, mag.shape)


def test_gyro_bias_of_a_trembling_hand_held_phone():
    """The phone rotates slowly while the user stands: the mean gyro is biased, the least squares is not."""
    rng = np.random.default_rng(5)
    n = int(30 * FS)
    _, omega, acc, mag = trembling_hand(n, rng)
    bias = np.array([0.01, -0.02, 0.015])
    gyro = omega + bias + rng.normal(0, 0.005, (n, 3))
    f = AttitudeFilter(FS)
    _, used = f.run(acc, gyro, mag)
    assert (used & 4).mean() > 0.9
    assert np.abs(f.state.bias - bias).max() < 0.5e-3
    assert np.abs(gyro.mean(axis=0) - bias).max() > 1e-3      # what a plain average would get


def test_gyro_bias_and_attitude_kept_in_a_moving_field():
    """A user standing in an elevator cabin that moves through the building's field: the device does not
    rotate, but the field (scaled by the cabin) drifts in magnitude and direction. The bias component about
    the vertical comes from the gyro mean, not from the field; the bias and the attitude stay put.
    """
    rng = np.random.default_rng(3)
    n0, n1 = int(4 * FS), int(16 * FS)
    n = n0 + n1
    q_true = quat.from_euler(0.4, -0.2, 1.1)
    s = np.r_[np.zeros(n0), np.linspace(0.0, 1.0, n1)]
    field_n = 0.55 * H_ENU + s[:, None] * np.array([9.0, -4.0, 5.0])
    mag = quat.rotate(quat.conjugate(q_true), field_n) + rng.normal(0, 0.3, (n, 3))
    acc = np.tile(quat.rotate(quat.conjugate(q_true), np.array([0.0, 0.0, GRAVITY_MPS2])), (n, 1))
    acc = acc + rng.normal(0, 0.02, acc.shape)
    bias = np.array([0.004, -0.006, 0.008])
    gyro = bias + rng.normal(0, 0.005, (n, 3))
    f = AttitudeFilter(FS)
    q, used = f.run(acc, gyro, mag)
    assert (used[n0:] & 4).all()
    assert np.abs(f.state.bias - bias).max() < 1e-3            # field rows in the bias: 0.04 rad/s off
    assert math.degrees(quat.angle_between(q[-1], q_true)) < 2.0  # field rows in the bias: 28 degrees off


def test_a_stand_in_a_moving_cabin_does_not_calibrate_the_gyro():
    """A rider holds the phone (a trembling hand) 20 s on the ground, then 30 s in a cabin that moves along its shaft,
    where the building's field turns by 20 degrees about the vertical, keeping its magnitude and dip (so the stand's
    disturbance test cannot see it). Taken for a stand, the field's rows read the field's turn as a gyro bias about
    the vertical; with the cabin's samples marked ``carried`` (the barometric altitude moving) the bias learnt on the
    ground stays.
    """
    rng = np.random.default_rng(4)
    n0, n1 = int(20 * FS), int(30 * FS)
    n = n0 + n1
    q_true, omega, acc, _ = trembling_hand(n, rng)
    turn = np.r_[np.zeros(n0), np.linspace(0.0, math.radians(20.0), n1)]
    field_n = quat.rotate(quat.from_euler(np.zeros(n), np.zeros(n), turn), H_ENU)
    mag = quat.rotate(quat.conjugate(q_true), field_n) + rng.normal(0, 0.3, (n, 3))
    bias = np.array([0.004, -0.006, 0.008])
    gyro = omega + bias + rng.normal(0, 0.005, (n, 3))
    up_b = quat.rotate(quat.conjugate(q_true[-1]), np.array([0.0, 0.0, 1.0]))
    carried = np.r_[np.zeros(n0, dtype=bool), np.ones(n1, dtype=bool)]
    f = AttitudeFilter(FS)
    _, used = f.run(acc, gyro, mag, carried)
    assert (used[n0:] & 4).mean() > 0.9                            # the rider stands still
    assert abs(float(up_b @ (f.state.bias - bias))) < 1e-3         # about the vertical, rad/s
    taken = AttitudeFilter(FS)
    taken.run(acc, gyro, mag)
    assert abs(float(up_b @ (taken.state.bias - bias))) > 4e-3     # the field's turn (0.012 rad/s) taken for bias
    with pytest.raises(InputError, match="carried"):
        AttitudeFilter(FS).run(acc, gyro, mag, carried[:-1])


@pytest.mark.parametrize("method", ["ukf", "ekf"])
def test_heading_recovers_from_a_disturbed_start(method):
    """20 s standing where the field is turned by 60 degrees and 30 % stronger, then 60 s of walking-like
    motion (vertical bounce, slow turn) in the earth field: the walk's magnetometer rows fix the yaw, the
    standing samples (one disturbed spot) do not lock it.
    """
    n1, n2 = int(20 * FS), int(60 * FS)
    yaw0, rate = 0.5, 0.02
    q1 = quat.from_euler(0.2, -0.3, yaw0)
    g_b = quat.rotate(quat.conjugate(q1), np.array([0.0, 0.0, GRAVITY_MPS2]))
    h_bad = 1.3 * quat.rotate(quat.from_euler(0.0, 0.0, math.radians(60)), H_ENU)
    acc1 = np.tile(g_b, (n1, 1))
    mag1 = np.tile(quat.rotate(quat.conjugate(q1), h_bad), (n1, 1))
    t = np.arange(1, n2 + 1) / FS
    q2 = quat.from_euler(np.full(n2, 0.2), np.full(n2, -0.3), yaw0 + rate * t)
    bounce = np.column_stack([np.zeros(n2), np.zeros(n2), GRAVITY_MPS2 + 2.0 * np.sin(2 * np.pi * 2.0 * t)])
    acc2 = quat.rotate(quat.conjugate(q2), bounce)
    mag2 = quat.rotate(quat.conjugate(q2), np.tile(H_ENU, (n2, 1)))
    gyro = np.zeros((n1 + n2, 3))
    gyro[n1:] = quat.rotate(quat.conjugate(q2), np.array([0.0, 0.0, rate]))
    q, used = AttitudeFilter(FS, method=method).run(np.vstack([acc1, acc2]), gyro, np.vstack([mag1, mag2]))
    assert not (used[n1 // 2:n1] & 2).any()                  # no magnetometer rows while standing
    err = math.degrees(quat.angle_between(q[-1], q2[-1]))
    assert err < 3.0


def _tilted_walk(n: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``n`` samples of a tilted phone turning slowly (0.02 rad/s) with a 2 Hz step bounce (never quasi-static):
    times (s), true attitudes, specific force and angular rate (device frame)."""
    t = np.arange(1, n + 1) / FS
    rate = 0.02
    q_true = quat.from_euler(np.full(n, 0.2), np.full(n, -0.3), 0.5 + rate * t)
    bounce = np.column_stack([np.zeros(n), np.zeros(n), GRAVITY_MPS2 + 2.0 * np.sin(2 * np.pi * 2.0 * t)])
    acc = quat.rotate(quat.conjugate(q_true), bounce)
    gyro = quat.rotate(quat.conjugate(q_true), np.array([0.0, 0.0, rate]))
    return t, q_true, acc, gyro


def test_a_field_stronger_than_the_earths_is_never_north():
    """Walking-like motion past a magnet whose field ramps up slowly to 4 times the earth's, turned by 70 degrees:
    the reference magnitude would follow a slow ramp, but no field above the geomagnetic maximum is used, and the
    yaw is carried on the gyro through it. Without the bound the magnet's rows turn the yaw.
    """
    n = int(60 * FS)
    t, q_true, acc, gyro = _tilted_walk(n)
    ramp = np.clip((t - 20.0) / 10.0, 0.0, 1.0) * np.clip((50.0 - t) / 5.0, 0.0, 1.0)    # 20-30 s up, 45-50 s down
    magnet = 3.0 * quat.rotate(quat.from_euler(0.0, 0.0, math.radians(70)), H_ENU)
    field = H_ENU + ramp[:, None] * magnet
    mag = quat.rotate(quat.conjugate(q_true), field)
    strong = np.linalg.norm(field, axis=1) > AttitudeConfig().earth_field_max_uT
    assert strong.sum() > 10 * FS
    q, used = AttitudeFilter(FS).run(acc, gyro, mag)
    assert not (used[strong] & 2).any()
    bounded = math.degrees(quat.angle_between(q[int(45 * FS)], q_true[int(45 * FS)]))
    q_old, used_old = AttitudeFilter(FS, replace(AttitudeConfig(), earth_field_max_uT=math.inf)).run(acc, gyro, mag)
    unbounded = math.degrees(quat.angle_between(q_old[int(45 * FS)], q_true[int(45 * FS)]))
    assert (used_old[strong] & 2).any() and bounded < 3.0 < unbounded


def test_state_round_trip_and_bad_input():
    f = AttitudeFilter(FS)
    acc, mag = body_measurements(quat.IDENTITY, 20)
    f.run(acc, np.zeros((20, 3)), mag)
    st = AttitudeState.from_state(f.state.state())
    assert np.array_equal(st.q, f.state.q) and np.array_equal(st.P, f.state.P)
    with pytest.raises(InputError, match="acc must be"):
        f.run(np.zeros((5, 2)))
    with pytest.raises(InputError, match="method"):
        AttitudeFilter(FS, method="kalman")
    with pytest.raises(InputError, match="attitude state"):
        AttitudeState.from_state({"q": [1, 0, 0]})


def test_a_state_saved_before_the_stand_timer_resumes_with_no_time_stood():
    from pdr.phone.attitude.state import AUX_NO_FIELD_S, AUX_SIZE, AUX_SIZE_V4

    f = AttitudeFilter(FS)
    acc, mag = body_measurements(quat.IDENTITY, 20)
    f.run(acc, np.zeros((20, 3)), mag)
    old = f.state.state()
    old["aux"] = old["aux"][:AUX_SIZE_V4]
    st = AttitudeState.from_state(old)
    assert st.aux.shape == (AUX_SIZE,) and st.aux[AUX_NO_FIELD_S] == 0.0
    assert np.array_equal(st.aux[:AUX_SIZE_V4], f.state.aux[:AUX_SIZE_V4])
    with pytest.raises(InputError, match="attitude state"):
        AttitudeState.from_state({**old, "aux": old["aux"][:AUX_SIZE_V4 - 1]})


def test_chunked_run_equals_one_batch():
    rng = np.random.default_rng(3)
    n = 400
    acc, mag = body_measurements(quat.from_euler(0.2, 0.1, -0.5), n, rng, 0.3)
    gyro = rng.normal(0, 0.05, (n, 3))
    q1, _ = AttitudeFilter(FS).run(acc, gyro, mag)
    f = AttitudeFilter(FS)
    parts = [f.run(acc[a:b], gyro[a:b], mag[a:b])[0] for a, b in ((0, 7), (7, 150), (150, 151), (151, n))]
    assert np.array_equal(np.concatenate(parts), q1)


def test_yaw_of_axis_convention():
    q = quat.from_euler(0.0, 0.0, math.radians(30))
    assert math.isclose(float(yaw_of_axis(q[None], np.array([0.0, 1.0, 0.0]))[0]), math.radians(120), abs_tol=1e-12)


def test_yaw_reopens_after_the_first_stand_that_gives_the_bias_not_after_a_short_blip():
    """The yaw variance is reopened once, when the first stand long enough to estimate the gyro bias ends.

    A stand shorter than one bias block (here 0.6 s past the 1 s stillness test) gives no bias rows; if it
    counted, the reopening (and so the walk's heading) would depend on where the recording happens to start.
    """
    from pdr.phone.heading import yaw_variance

    rng = np.random.default_rng(3)
    q_true = quat.from_euler(0.1, -0.2, 1.0)
    bias = np.array([0.01, -0.02, 0.015])
    f = AttitudeFilter(FS)

    def stand(seconds):
        n = int(seconds * FS)
        acc, mag = body_measurements(q_true, n, rng, 0.02)
        f.run(acc, bias + rng.normal(0, 0.002, (n, 3)), mag)

    def move(seconds):  # the phone shaken: |a| far from g, so no stillness and no gravity rows
        n = int(seconds * FS)
        acc, mag = body_measurements(q_true, n)
        f.run(acc + rng.normal(0, 3.0, acc.shape), np.tile(bias, (n, 1)), mag)
        return yaw_variance(f.state.q, f.state.P)

    sigma_reopen = math.radians(AttitudeConfig().init_yaw_sigma_deg)
    stand(1.6)
    assert move(2.0) < 0.02 * sigma_reopen**2      # a blip: not reopened
    stand(6.0)
    assert move(0.1) > 0.1 * sigma_reopen**2       # the first real stand: reopened (field rows shrink it)
    assert np.allclose(f.state.bias, bias, atol=3e-3)
    stand(6.0)
    var_before = yaw_variance(f.state.q, f.state.P)
    assert move(0.1) < max(2 * var_before, 0.02 * sigma_reopen**2)   # only once


def test_gyro_compensated_needs_an_os_bias_estimate_at_shared_sample_times():
    rng = np.random.default_rng(3)
    t = np.arange(200) / FS
    gyro = rng.normal(0, 0.3, (200, 3))
    estimate = np.array([0.0085, -0.004, 0.069])          # the Nexus 5's OS estimate (rad/s)
    assert gyro_compensated(t, gyro, t, gyro + estimate)
    assert not gyro_compensated(t, gyro, t, gyro.copy())   # a phone that reports no estimate
    assert not gyro_compensated(t, gyro, t + 0.5 / FS, gyro + estimate)   # no common sample: no evidence


def test_compensated_prior_holds_a_short_stand_back_and_yields_to_a_long_one():
    """The ridge of a compensated gyro is a prior on its residual bias: a stand as long as the ridge moves the
    estimate part of the way, a long stand all the way (the prior weighs a few seconds of rows)."""
    rng = np.random.default_rng(5)
    bias = np.array([0.01, -0.02, 0.015])
    cfg = AttitudeConfig()
    cfg = replace(cfg, bias_prior_s=cfg.compensated_bias_prior_s)
    est = {}
    for seconds in (4, 120):
        n = int(seconds * FS)
        _, omega, acc, mag = trembling_hand(n, rng)
        walk = int(2 * FS)           # a step-like shake ends the stand, so its last complete block enters
        acc = np.vstack([acc, acc[-1] + rng.normal(0, 3.0, (walk, 3))])
        gyro = np.vstack([omega, np.zeros((walk, 3))]) + bias + rng.normal(0, 0.005, (n + walk, 3))
        mag = np.vstack([mag, np.tile(mag[-1], (walk, 1))])
        f = AttitudeFilter(FS, cfg)
        f.run(acc, gyro, mag)
        est[seconds] = f.state.bias.copy()
    short = np.linalg.norm(est[4]) / np.linalg.norm(bias)
    long_ = np.linalg.norm(est[120]) / np.linalg.norm(bias)
    assert 0.05 < short < 0.75
    assert abs(long_ - 1) < 0.15


def test_gravity_rows_while_moving_bring_a_swinging_phones_tilt_back():
    """A phone swinging with an arm (60 deg peak to peak at the stride frequency, 0.9 Hz) with the limb's periodic
    accelerations (4 m/s^2 horizontal, 3 m/s^2 vertical, zero mean over a stride), its tilt 10 deg off after a
    stand: eq. 12 accepts none of the swinging samples, so seed 003's gate alone leaves the tilt where it was;
    gravity rows while moving (``sigma_a_moving``) average the limb's accelerations out and bring the tilt back.
    """
    n = int(60 * FS)
    t = np.arange(1, n + 1) / FS
    w = 2 * np.pi * 0.9
    q_true = quat.from_euler(math.radians(30) * np.sin(w * t), np.zeros(n), np.full(n, 0.7))
    rate_b = np.column_stack([math.radians(30) * w * np.cos(w * t), np.zeros(n), np.zeros(n)])
    limb = np.column_stack([4.0 * np.sin(w * t + 0.3), 1.0 * np.cos(w * t), 3.0 * np.sin(2 * w * t)])
    acc = quat.rotate(quat.conjugate(q_true), limb + np.array([0.0, 0.0, GRAVITY_MPS2]))
    stand = int(3 * FS)
    acc_stand = np.tile(quat.rotate(quat.conjugate(q_true[0]), np.array([0.0, 0.0, GRAVITY_MPS2])), (stand, 1))

    def run(sigma_a_moving: float) -> tuple[float, NDArray[np.int64]]:
        f = AttitudeFilter(FS, replace(AttitudeConfig(), sigma_a_moving=sigma_a_moving))
        f.run(acc_stand, np.zeros((stand, 3)), None)           # the stand: gravity's magnitude and the tilt
        f.state.q[:] = quat.multiply(quat.from_euler(math.radians(10), 0.0, 0.0), f.state.q)
        q, used = f.run(acc, rate_b, None)
        last = slice(n - int(10 * FS), n)               # the last 10 s: the tilt error's mean over 9 strides
        up_true = quat.rotate(quat.conjugate(q_true[last]), np.array([0.0, 0.0, 1.0]))
        up_est = quat.rotate(quat.conjugate(q[last]), np.array([0.0, 0.0, 1.0]))
        return float(np.degrees(np.arccos(np.clip(np.sum(up_true * up_est, axis=1), -1.0, 1.0))).mean()), used

    gate_alone, used_gate = run(0.0)
    moving, used_moving = run(1.5)
    assert not (used_gate[int(FS):] & 1).any()          # eq. 12 rejects every swinging sample
    assert (used_moving & 1).all()
    assert gate_alone > 8.0 and moving < 1.6


def _walk_with_gyro_bias(field_turn_deg: FloatArray, bias_z_dps: float) -> tuple[FloatArray, FloatArray, FloatArray,
                                                                                   FloatArray, int]:
    """A 3 s stand, then 120 s of a flat phone turning slowly (0.05 rad/s) with a step bounce (not quasi-static),
    its gyro biased by ``bias_z_dps`` about the vertical after the stand, in a field turned by ``field_turn_deg``
    (per sample) about the vertical. Returns acc, gyro, mag, the true attitudes and the stand's length."""
    stand, n = int(3 * FS), int(123 * FS)
    t = np.arange(1, n + 1) / FS
    rate = np.where(np.arange(n) < stand, 0.0, 0.05)
    yaw = 0.4 + np.cumsum(rate) / FS
    q_true = quat.from_euler(np.zeros(n), np.zeros(n), yaw)
    bounce = np.column_stack([np.zeros(n), np.zeros(n), GRAVITY_MPS2 + np.where(np.arange(n) < stand, 0.0,
                                                                                  2.5 * np.sin(2 * np.pi * 1.8 * t))])
    acc = quat.rotate(quat.conjugate(q_true), bounce)
    field = quat.rotate(quat.from_euler(np.zeros(n), np.zeros(n), np.radians(field_turn_deg)), H_ENU)
    mag = quat.rotate(quat.conjugate(q_true), field)
    gyro = np.column_stack([np.zeros(n), np.zeros(n), rate])
    gyro[stand:, 2] += math.radians(bias_z_dps)
    return acc, gyro, mag, q_true, stand


def test_the_field_learns_a_residual_gyro_bias_while_walking_but_not_from_a_disturbance():
    """A gyro biased by 0.4 deg/s about the vertical after the stand that set its bias: the field's rows alone
    leave the yaw lagging by the bias times their time constant; the integral term (``mag_bias_gain``) learns the
    bias and removes the lag. A field that swings back and forth by 25 deg (a walk past disturbances every 3 s)
    teaches it no bias: the innovation is not steady."""
    n = int(123 * FS)
    acc, gyro, mag, q_true, stand = _walk_with_gyro_bias(np.zeros(n), 0.4)
    last = slice(n - int(20 * FS), n)

    def run(gain: float, m: FloatArray) -> tuple[float, float]:
        f = AttitudeFilter(FS, replace(AttitudeConfig(), mag_bias_gain=gain))
        q, _ = f.run(acc, gyro, m)
        yaw_err = np.degrees(quat.angle_between(q[last], q_true[last]))   # a flat phone: the yaw error
        return float(yaw_err.mean()), math.degrees(float(f.state.bias[2]))

    lag_alone, _ = run(0.0, mag)
    lag_learnt, bias_learnt = run(0.0025, mag)
    assert lag_alone > 2.0 and lag_learnt < 0.5 * lag_alone
    assert bias_learnt == pytest.approx(0.4, abs=0.1)
    t = np.arange(1, n + 1) / FS
    swing = np.where(np.arange(n) < stand, 0.0, 25.0 * np.sign(np.sin(2 * np.pi * t / 6.0)))
    acc_d, gyro_d, mag_d, _, _ = _walk_with_gyro_bias(swing, 0.0)
    f = AttitudeFilter(FS, replace(AttitudeConfig(), mag_bias_gain=0.0025))
    f.run(acc_d, gyro_d, mag_d)
    assert abs(math.degrees(float(f.state.bias[2]))) < 0.1


def test_the_turn_a_nearing_magnet_gave_the_yaw_is_taken_back_when_it_is_seen():
    """A phone carried towards a magnet soon after the start (its yaw still open to the field's rows): for 8 s its
    field strengthens and turns (below the earth's maximum, so the gates, whose reference follows the field, let the
    rows through and they turn the yaw), then it exceeds the earth's maximum. At that first stronger sample the rows'
    recent turn is undone (``magnet_undo_tau_s``) and the gyro carries the yaw on; without the undo the magnet's
    approach stays in the yaw. A field that weakens and turns (no magnet near) is not undone."""
    n = int(25 * FS)
    t, q_true, acc, gyro = _tilted_walk(n)
    ramp = np.clip((t - 5.0) / 8.0, 0.0, 1.0) ** 3                   # a dipole's 1/r^3 as the phone nears it
    magnet = quat.rotate(quat.from_euler(0.0, 0.0, math.radians(-90)), H_ENU)
    field = H_ENU + ramp[:, None] * magnet
    strong = np.linalg.norm(field, axis=1) > AttitudeConfig().earth_field_max_uT
    first = int(np.argmax(strong))
    assert 5 * FS < first < 13 * FS
    after = slice(first + int(FS), first + int(3 * FS))

    def yaw_error(cfg: AttitudeConfig, f_n: FloatArray) -> float:
        q, _ = AttitudeFilter(FS, cfg).run(acc, gyro, quat.rotate(quat.conjugate(q_true), f_n))
        return float(np.degrees(quat.angle_between(q[after], q_true[after])).mean())

    undone = yaw_error(AttitudeConfig(), field)
    kept = yaw_error(replace(AttitudeConfig(), magnet_undo_tau_s=0.0), field)
    assert kept > 3.0 and undone < 0.6 * kept
    # A weakening, turning field (a steel beam's shadow, say) then the same strong field: nothing is undone.
    weaker = H_ENU - 0.5 * ramp[:, None] * magnet
    weaker[first:] = field[first:]
    assert yaw_error(AttitudeConfig(), weaker) == pytest.approx(
        yaw_error(replace(AttitudeConfig(), magnet_undo_tau_s=0.0), weaker), abs=1e-9)


def _bent_field(dip_deg: float, turn_deg: float, magnitude_uT: float) -> FloatArray:
    """A field (ENU, uT) of the given dip below the horizontal, its horizontal part turned ``turn_deg`` from
    north (counter-clockwise seen from above), as steel bends the earth's indoors."""
    d = math.radians(dip_deg)
    north_down = magnitude_uT * np.array([0.0, math.cos(d), -math.sin(d)])
    return quat.rotate(quat.from_euler(0.0, 0.0, math.radians(turn_deg)), north_down)


def test_a_field_far_from_the_earths_dip_is_not_north():
    """5 s standing, then 30 s of walking-like motion, in a building's bent field (dip 35 deg where the earth's is
    65.6, 26 uT): standing where it is turned 5 deg, walking where it is turned 30 deg; then 40 s in the earth's
    field. The reference follows the bent field, so its gates pass the walk's rows and the yaw turns with them;
    with the earth's dip known (``earth_dip_deg``) they are refused and the yaw is carried on the gyro, and the
    earth's field later sets it as before.
    """
    n0, n1, n2 = int(5 * FS), int(30 * FS), int(40 * FS)
    t_walk, q_walk, acc_walk, gyro_walk = _tilted_walk(n1 + n2)
    q_stand = np.tile(q_walk[0], (n0, 1))
    acc_stand = np.tile(quat.rotate(quat.conjugate(q_walk[0]), np.array([0.0, 0.0, GRAVITY_MPS2])), (n0, 1))
    field = np.vstack([np.tile(_bent_field(35.0, 5.0, 26.0), (n0, 1)), np.tile(_bent_field(35.0, 30.0, 26.0), (n1, 1)),
                       np.tile(H_ENU, (n2, 1))])
    q_true = np.vstack([q_stand, q_walk])
    acc = np.vstack([acc_stand, acc_walk])
    gyro = np.vstack([np.zeros((n0, 3)), gyro_walk])
    mag = quat.rotate(quat.conjugate(q_true), field)
    earth_dip = math.degrees(math.atan2(-H_ENU[2], H_ENU[1]))
    bent = slice(n0, n0 + n1)
    late = n0 + n1 - 1                                      # the last sample in the bent field
    q_free, used_free = AttitudeFilter(FS).run(acc, gyro, mag)
    q, used = AttitudeFilter(FS, replace(AttitudeConfig(), earth_dip_deg=earth_dip)).run(acc, gyro, mag)
    assert (used_free[bent] & 2).mean() > 0.9 and not (used[bent] & 2).any()
    followed = math.degrees(quat.angle_between(q_free[late], q_true[late]))
    carried = math.degrees(quat.angle_between(q[late], q_true[late]))
    assert followed > 20.0 and carried < 8.0
    assert (used[n0 + n1:] & 2).any()
    assert math.degrees(quat.angle_between(q[-1], q_true[-1])) < 5.0


@pytest.mark.parametrize("method", ["ukf", "ekf"])
def test_a_stand_without_field_rows_grows_the_yaw_variance_with_the_residual_bias(method):
    """Standing, the yaw gets no field rows (``mag_when_static`` off) and the gyro's residual bias ``b`` may turn it
    by ``b T`` over a stand of ``T`` s: the yaw's variance grows by about ``(b T)^2`` (the stillness tests take the
    stand's first seconds), from zero again at each stand, and hardly at all with ``stand_bias_dps = 0``.
    """
    from pdr.phone.heading import yaw_variance

    q_true = quat.from_euler(0.1, -0.2, 1.0)
    bias = np.array([0.01, -0.02, 0.015])

    def run(stand_bias_dps):
        rng = np.random.default_rng(5)
        f = AttitudeFilter(FS, AttitudeConfig(stand_bias_dps=stand_bias_dps), method=method)

        def stand(seconds):
            n = int(seconds * FS)
            acc, mag = body_measurements(q_true, n, rng, 0.02)
            f.run(acc, bias + rng.normal(0, 0.002, (n, 3)), mag)
            return yaw_variance(f.state.q, f.state.P)

        def move(seconds):      # shaken: no stillness and no gravity rows, the field's rows taken
            n = int(seconds * FS)
            acc, mag = body_measurements(q_true, n)
            used = f.run(acc + rng.normal(0, 3.0, acc.shape), np.tile(bias, (n, 1)), mag)[1]
            assert (used[-50:] & 2).all()
            return yaw_variance(f.state.q, f.state.P)

        stand(6.0)              # the gyro bias; the yaw reopens when it ends
        grown = []
        for _ in range(2):
            before = move(20.0)
            grown.append(stand(20.0) - before)
        return grown

    b = math.radians(0.2)
    for g in run(0.2):
        assert (b * 15.0) ** 2 < g < (b * 20.0) ** 2
    assert max(run(0.0)) < 0.01 * (b * 15.0) ** 2
