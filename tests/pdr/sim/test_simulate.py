import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr import strapdown
from pdr.errors import InputError
from pdr.frames import GRAVITY_MPS2, pressure_to_altitude_m, wrap_angle
from pdr.sim import parse_scenario, simulate
from pdr.sim.simulate import build_path, device_motion, mount_quaternion, sample_times

PLACEMENTS = ("trouser_pocket", "torso", "hand", "foot")
IDEAL = {"grade": "ideal"}
QUIET_FIELD = {"indoor_disturbance_ut": 0.0, "escalator_disturbance_ut": 0.0}


def _scenario(segments, **kw):
    return {"segments": segments, **kw}


@pytest.fixture(scope="module")
def tour():
    """Every segment type once, pocket phone, consumer sensors."""
    return _scenario([
        {"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 4},
        {"type": "turn", "angle_deg": 90}, {"type": "stairs", "direction": "up", "steps": 6},
        {"type": "stand", "duration_s": 2}, {"type": "elevator", "direction": "down"},
        {"type": "walk", "duration_s": 2}, {"type": "escalator", "direction": "up"},
        {"type": "run", "duration_s": 3}, {"type": "stand", "duration_s": 2}], name="tour")


@pytest.mark.parametrize("placement", PLACEMENTS)
def test_same_seed_same_recording_other_seed_other_noise(tour, placement):
    doc = {**tour, "placement": placement}
    a, b, c = simulate(doc, 7), simulate(doc, 7), simulate(doc, 8)
    assert a == b
    for kind in a.streams:
        assert not np.array_equal(a.values(kind), c.values(kind)), kind
    # the walk itself does not depend on the seed
    assert a.truth.positions is not None and c.truth.positions is not None
    np.testing.assert_array_equal(a.truth.positions.pos_m, c.truth.positions.pos_m)
    np.testing.assert_array_equal(a.truth.step_times_s, c.truth.step_times_s)


def test_recording_metadata_and_truth_layout(tour):
    rec = simulate({**tour, "placement": "foot", "side": "left"}, 1)
    assert rec.device.role == "left_foot" and rec.device.placement == "foot"
    assert rec.meta["seed"] == 1 and rec.meta["scenario"]["name"] == "tour"
    tr = rec.truth
    k = tr.extra["trajectory_t_s"].size
    assert tr.positions is not None and tr.step_times_s is not None
    assert tr.modes is not None and tr.landmarks is not None
    assert tr.positions.kind == "dense" and tr.positions.frame == "enu" and len(tr.positions) == k
    assert tr.extra["q_nb"].shape == (k, 4) and tr.extra["vel_n"].shape == (k, 3)
    assert tr.extra["zero_velocity"].dtype == bool and tr.extra["step_foot"].shape == tr.step_times_s.shape
    assert set(tr.modes.label) == {"standing", "walking", "stairs_up", "elevator_down", "escalator_up", "running"}
    assert tr.landmarks.label == ("turn_left", "stairs_up", "elevator_down", "escalator_up")
    assert rec.t_s("acc")[-1] == pytest.approx(rec.duration_s)
    assert rec.stream("acc").median_rate_hz() == pytest.approx(200.0)


def test_bad_seed():
    with pytest.raises(InputError, match="seed"):
        simulate({"segments": [{"type": "stand", "duration_s": 2}]}, -1)


def test_gait_statistics_match_the_scenario():
    doc = _scenario([{"type": "stand", "duration_s": 3}, {"type": "walk", "duration_s": 20, "speed_mps": 1.4,
                                                          "step_frequency_hz": 1.9},
                     {"type": "stand", "duration_s": 3}], sensors=IDEAL)
    rec = simulate(doc, 0)
    st, sl = rec.truth.step_times_s, rec.truth.step_lengths_m
    assert st is not None and sl is not None
    steady = (st > 5.0) & (st < 21.0)
    assert np.diff(st[steady]).mean() == pytest.approx(1 / 1.9, rel=1e-3)
    assert sl[steady].mean() == pytest.approx(1.4 / 1.9, rel=1e-3)
    assert st.size == round(20 * 1.9)                     # phase advances f * T: one step per unit
    assert sl.sum() == pytest.approx(1.4 * 20, abs=1.4 / 1.9)
    assert rec.truth.positions is not None
    pos = rec.truth.positions.pos_m
    assert np.linalg.norm(pos[-1] - pos[0]) == pytest.approx(1.4 * 20, abs=1e-6)
    assert np.all(np.abs(rec.truth.extra["walking_heading_rad"]) < 1e-12)   # heading 90 deg = east
    assert pos[-1, 0] - pos[0, 0] == pytest.approx(28.0, abs=1e-6)


def test_every_walking_bout_has_its_steps():
    bout = [{"type": "walk", "duration_s": 10, "step_frequency_hz": 1.8},
            {"type": "turn", "angle_deg": 90, "duration_s": 2, "step_frequency_hz": 1.8}]
    doc = _scenario([{"type": "stand", "duration_s": 2}, *bout, {"type": "stand", "duration_s": 3}, *bout,
                     {"type": "escalator", "direction": "up"}, *bout, {"type": "stand", "duration_s": 2}],
                    sensors=IDEAL)
    rec = simulate(doc, 0)
    st = rec.truth.step_times_s
    b = np.cumsum([0, 2, 10, 2, 3, 10, 2, 12, 10, 2])
    foot = rec.truth.extra["step_foot"]
    for start, end in ((b[1], b[3]), (b[4], b[6]), (b[7], b[9])):
        mine = (st > start - 1) & (st < end + 1)
        assert np.count_nonzero(mine) == round(12 * 1.8)
        assert np.all(foot[mine][::2] == 1) and np.all(foot[mine][1::2] == -1)   # right foot first, alternating


@pytest.mark.parametrize("placement", PLACEMENTS)
def test_turn_angle_and_floor_change(placement):
    doc = _scenario([{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 3},
                     {"type": "turn", "angle_deg": -135, "duration_s": 3}, {"type": "stairs", "direction": "up"},
                     {"type": "walk", "duration_s": 2}, {"type": "stand", "duration_s": 2}],
                    placement=placement, sensors=IDEAL, start={"heading_deg": 0, "floor": 2})
    rec = simulate(doc, 0)
    ex = rec.truth.extra
    heading = ex["walking_heading_rad"]
    assert wrap_angle(heading[-1] - heading[0]) == pytest.approx(math.radians(-135))
    _, _, yaw = quat.to_euler(ex["q_nb"][[0, -1]])
    if placement in ("torso", "hand", "foot"):   # upright devices: their yaw turns with the walker
        assert wrap_angle(yaw[1] - yaw[0]) == pytest.approx(math.radians(-135), abs=1e-9)
    assert quat.angle_between(ex["q_nb"][0], ex["q_nb"][-1]) == pytest.approx(math.radians(135), abs=1e-9)
    assert ex["floor"][0] == 2 and ex["floor"][-1] == 3
    assert rec.truth.positions is not None
    pos = rec.truth.positions.pos_m
    assert pos[-1, 2] - pos[0, 2] == pytest.approx(3.0, abs=1e-9)


@pytest.mark.parametrize("placement", ("trouser_pocket", "torso", "hand"))
def test_noise_free_phone_at_rest_reads_gravity_in_its_attitude(placement):
    doc = _scenario([{"type": "stand", "duration_s": 3}, {"type": "walk", "duration_s": 3},
                     {"type": "stand", "duration_s": 3}], placement=placement, sensors=IDEAL,
                    mount_rpy_deg="random", truth_rate_hz=100)
    rec = simulate(doc, 11)
    t = rec.truth.extra["trajectory_t_s"]
    still = (t < 1.4) | (t > 8.1)
    q = rec.truth.extra["q_nb"][still]
    expected = quat.rotate(quat.conjugate(q), np.array([0.0, 0.0, GRAVITY_MPS2]))
    np.testing.assert_allclose(rec.values("acc")[still], expected, atol=1e-9)
    np.testing.assert_allclose(rec.values("gyro")[still], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(rec.values("acc")[still], axis=1), GRAVITY_MPS2, atol=1e-9)
    # while walking, the accelerometer is not just gravity
    assert np.abs(np.linalg.norm(rec.values("acc")[~still], axis=1) - GRAVITY_MPS2).max() > 1.0


SHORT_WALK = [{"type": "stand", "duration_s": 1}, {"type": "walk", "duration_s": 4},
              {"type": "turn", "angle_deg": -90, "duration_s": 2}, {"type": "walk", "duration_s": 2},
              {"type": "stand", "duration_s": 1}]


def _strapdown_errors(placement, rate):
    doc = _scenario(SHORT_WALK, placement=placement, sensors=IDEAL, rates_hz={"acc": rate, "gyro": rate},
                    truth_rate_hz=rate)
    rec = simulate(doc, 4)
    tr = rec.truth
    assert tr.positions is not None
    q, v, p = tr.extra["q_nb"], tr.extra["vel_n"], tr.positions.pos_m
    pos, vel, qq = strapdown.integrate(q[0], v[0], p[0], rec.t_s("acc"), rec.values("acc"), rec.values("gyro"))
    return (np.abs(pos - p).max(), np.abs(vel - v).max(), np.degrees(quat.angle_between(qq, q).max()))


@pytest.mark.parametrize("placement", ("foot", "trouser_pocket"))
def test_noise_free_imu_through_strapdown_reproduces_the_truth(placement):
    coarse = _strapdown_errors(placement, 500)
    fine = _strapdown_errors(placement, 1000)
    # pdr.strapdown integrates to second order: errors must fall about fourfold when the interval halves,
    # which they only do if the IMU signals are the exact derivatives of the truth (the foot's position error
    # falls less, about 2.8x: its heel-strike shock is not smooth on the scale of a millisecond).
    for c, f in zip(coarse, fine, strict=True):
        assert 2.5 < c / f < 4.5
    pos_err, vel_err, att_err_deg = fine
    assert pos_err < 0.005 and vel_err < 0.002 and att_err_deg < 0.002


def test_gyro_and_attitude_agree_to_second_order():
    # The two-sample (trapezoid + coning) attitude update of pdr.strapdown on the instantaneous rates.
    sc = parse_scenario(_scenario(SHORT_WALK, placement="foot"))
    path = build_path(sc)
    q_mount = mount_quaternion(sc, np.random.default_rng(0))
    t = sample_times(1000.0, sc.duration_s)
    truth, _ = device_motion(path, t, q_mount)
    q = strapdown.propagate_attitude(truth.frame.q_nb[0], truth.angular_rate_b(), np.diff(t, prepend=0.0))
    assert np.degrees(quat.angle_between(q, truth.frame.q_nb).max()) < 2e-3


@pytest.mark.parametrize("placement", PLACEMENTS)
def test_velocity_and_acceleration_are_exact_derivatives(placement):
    doc = _scenario([*SHORT_WALK[:-1], {"type": "stairs", "direction": "down", "steps": 4},
                     {"type": "escalator", "direction": "down"}, {"type": "elevator", "direction": "up"},
                     {"type": "run", "duration_s": 2}], placement=placement)
    sc = parse_scenario(doc)
    t = sample_times(2000.0, sc.duration_s)
    mo, _ = device_motion(build_path(sc), t, mount_quaternion(sc, np.random.default_rng(0)))
    h = np.diff(t)[:, None]
    dpos = 0.5 * h * (mo.vel_n[:-1] + mo.vel_n[1:]) + h**2 / 12 * (mo.acc_n[:-1] - mo.acc_n[1:])
    np.testing.assert_allclose(mo.pos_n[0] + np.cumsum(dpos, axis=0), mo.pos_n[1:], atol=1e-6)
    dvel = 0.5 * h * (mo.acc_n[:-1] + mo.acc_n[1:])
    np.testing.assert_allclose(mo.vel_n[0] + np.cumsum(dvel, axis=0), mo.vel_n[1:], atol=2e-3)


def test_shoe_is_still_during_stance_and_hits_the_ground():
    doc = _scenario([{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 6},
                     {"type": "stand", "duration_s": 2}], placement="foot", sensors=IDEAL, truth_rate_hz=200)
    rec = simulate(doc, 0)
    ex = rec.truth.extra
    still = ex["zero_velocity"]
    np.testing.assert_allclose(ex["vel_n"][still], 0.0, atol=1e-12)
    assert 0.3 < still[(ex["trajectory_t_s"] > 3) & (ex["trajectory_t_s"] < 7)].mean() < 0.7
    assert rec.truth.step_times_s is not None
    right = rec.truth.step_times_s[ex["step_foot"] == 1]
    acc = rec.values("acc")
    ta = rec.t_s("acc")
    shock = [np.abs(np.linalg.norm(acc[(ta >= s) & (ta < s + 0.05)], axis=1) - GRAVITY_MPS2).max() for s in right]
    assert min(shock) > 15.0   # heel-strike shock of 25 m/s^2 peak (walking style)
    assert np.abs(acc).max() < 80.0
    speed = np.linalg.norm(ex["vel_n"], axis=1)
    assert speed.max() > 2.0 * 1.3   # the swinging foot overtakes the body


def test_leg_pitch_pattern_on_stairs_follows_seed_003():
    """Seed 003 eqs. 2-3: upstairs opens the legs wider and higher than walking, downstairs less and higher."""
    doc = _scenario([{"type": "walk", "duration_s": 8}, {"type": "stairs", "direction": "up", "steps": 14},
                     {"type": "stairs", "direction": "down", "steps": 14}], sensors=IDEAL)
    rec = simulate(doc, 0)
    ex = rec.truth.extra
    y_n = quat.rotate(ex["q_nb"], np.array([0.0, 1.0, 0.0]))   # default mount: device y up the thigh
    fwd = np.column_stack([np.cos(ex["walking_heading_rad"]), np.sin(ex["walking_heading_rad"])])
    pitch = np.degrees(np.arctan2(-np.sum(y_n[:, :2] * fwd, axis=1), y_n[:, 2]))  # thigh forward positive
    t = ex["trajectory_t_s"]
    b = np.cumsum([0, 8, 14 / 1.6, 14 / 1.8])
    parts = [pitch[(t > b[i] + 1.5) & (t < b[i + 1] - 1.5)] for i in range(3)]
    walk, up, down = ((p.max(), p.min(), p.max() - p.min()) for p in parts)
    assert up[2] > walk[2] > down[2]
    assert up[0] > walk[0] and down[1] > walk[1]


def test_elevator_impulse_pair_and_magnetic_drop_at_the_doors():
    doc = _scenario([{"type": "stand", "duration_s": 3}, {"type": "elevator", "direction": "up", "floors": 2},
                     {"type": "stand", "duration_s": 3}], placement="torso", sensors=IDEAL, magnetic=QUIET_FIELD)
    rec = simulate(doc, 0)
    acc_norm = np.linalg.norm(rec.values("acc"), axis=1) - GRAVITY_MPS2
    t = rec.t_s("acc")
    peak = 1.875 * 1.0 / 2.0        # smoothstep ramp of 1 m/s over 2 s
    assert acc_norm.max() == pytest.approx(peak, rel=1e-3) and acc_norm.min() == pytest.approx(-peak, rel=1e-3)
    assert t[np.argmax(acc_norm)] < t[np.argmin(acc_norm)]      # up: push first, then the lighter feeling
    mag = np.linalg.norm(rec.values("mag"), axis=1)
    tm = rec.t_s("mag")
    assert mag[tm < 2].mean() == pytest.approx(50.0, rel=1e-9)
    assert mag[(tm > 5) & (tm < 12)].mean() == pytest.approx(50.0 * 0.55, rel=1e-9)
    floor = rec.truth.extra["floor"]
    assert floor[0] == 0 and floor[-1] == 2
    alt = pressure_to_altitude_m(rec.values("baro")[:, 0])
    assert alt[-1] - alt[0] == pytest.approx(6.0, abs=1e-3)


def test_escalator_carries_a_still_standing_rider_and_shakes_the_field():
    doc = _scenario([{"type": "stand", "duration_s": 2}, {"type": "escalator", "direction": "down"},
                     {"type": "stand", "duration_s": 2}], placement="hand", sensors=IDEAL)
    rec = simulate(doc, 0)
    assert rec.truth.positions is not None
    pos = rec.truth.positions.pos_m
    assert pos[-1, 2] - pos[0, 2] == pytest.approx(-3.0, abs=1e-9)
    assert pos[-1, 0] - pos[0, 0] == pytest.approx(3.0 / math.tan(math.radians(30)), abs=1e-6)
    assert rec.truth.step_count == 0
    mag = np.linalg.norm(rec.values("mag"), axis=1)
    tm = rec.t_s("mag")
    assert mag[(tm > 4) & (tm < 12)].std() > 5 * mag[tm < 1.5].std()


def test_noisy_sensors_have_the_configured_white_noise():
    doc = _scenario([{"type": "stand", "duration_s": 60}], placement="torso",
                    sensors={"grade": "ideal", "gyro": {"white_noise_density": 0.002},
                             "baro": {"white_noise_density": 0.01}})
    rec = simulate(doc, 3)
    np.testing.assert_allclose(rec.values("gyro").std(axis=0), 0.002 * 10.0, rtol=0.05)
    assert rec.values("baro").std() == pytest.approx(0.01 * math.sqrt(10.0), rel=0.1)


def test_native_round_trip(tmp_path, tour):
    native = pytest.importorskip("pdr.io.native")
    rec = simulate({**tour, "placement": "foot"}, 5)
    out = native.write(rec, tmp_path / "rec")
    back = native.read(out) if hasattr(native, "read") else None
    if back is None:
        pytest.skip("pdr.io.native has no read()")
    assert back == rec


def test_every_step_sends_a_heel_strike_shock_up_the_body():
    from pdr.sim.placement import BODY_SHOCK_S, body_shock

    sc = parse_scenario(_scenario([{"type": "stand", "duration_s": 1}, {"type": "walk", "duration_s": 6},
                                   {"type": "run", "duration_s": 4}, {"type": "stand", "duration_s": 1}]))
    path = build_path(sc)
    t = sample_times(2000.0, sc.duration_s)
    jet = body_shock(path, t)
    st = path.steps.t_s
    for s_t, peak in ((st[(st > 2) & (st < 6)], 3.0), (st[(st > 8.5) & (st < 10.5)], 10.0)):
        for s in s_t:
            win = (t >= s) & (t < s + BODY_SHOCK_S)
            assert np.abs(jet.d2[win]).max() == pytest.approx(peak, rel=1e-2)
    outside = np.ones(t.size, dtype=bool)
    for s in st:
        outside &= ~((t >= s) & (t < s + BODY_SHOCK_S))
    assert np.all(jet.value[outside] == 0) and np.all(jet.d1[outside] == 0)
