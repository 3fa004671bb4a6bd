"""Gyro yaw: the turn about the vertical of a swinging phone, without geometric phase or filter corrections."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr import quaternion as quat
from pdr.phone.gyro_yaw import GyroYaw

RATE_HZ = 100.0
TS = 1.0 / RATE_HZ


def swinging_walk(seconds: float = 30.0, turn_dps: float = 6.0, cone_deg: float = 25.0, stride_s: float = 1.1,
                  base_rpy_deg: tuple[float, float, float] = (80.0, 10.0, 30.0)):
    """Attitudes of a phone whose tilt traces a cone once per stride (a thigh that swings and rolls) while the
    walker turns steadily, and the body rates that produce them exactly (``q_k = q_{k-1} exp(w_k ts)``).

    Returns ``(t, q_nb (N, 4), gyro_b (N, 3), true turn (N,) rad)``.
    """
    t = np.arange(int(seconds * RATE_HZ)) * TS
    turn = np.radians(turn_dps) * t
    phase = 2 * math.pi * t / stride_s
    cone = math.radians(cone_deg) * np.column_stack([np.cos(phase), np.sin(phase), np.zeros_like(t)])
    base = quat.from_euler(*np.radians(base_rpy_deg))
    q = quat.multiply(quat.from_euler(np.zeros_like(t), np.zeros_like(t), turn),
                      quat.multiply(quat.from_rotvec(cone), np.broadcast_to(base, (t.size, 4))))
    gyro = np.zeros((t.size, 3))
    gyro[1:] = quat.to_rotvec(quat.multiply(quat.conjugate(q[:-1]), q[1:])) / TS
    return t, quat.normalize(q), gyro, turn


def vertical_rate_integral(q: np.ndarray, gyro: np.ndarray) -> np.ndarray:
    """The plain integral of the body rate's vertical component (what the gyro yaw replaces)."""
    up_b = quat.to_rotmat(q)[:, 2, :]
    return np.cumsum(np.sum(gyro * up_b, axis=1)) * TS


def test_a_swinging_phone_gives_the_turn_without_the_cone_s_geometric_phase():
    t, q, gyro, turn = swinging_walk()
    yaw, _ = GyroYaw(RATE_HZ).update(q, gyro)
    whole = np.flatnonzero(np.isclose(t % 1.1, 0.0, atol=TS / 2) | np.isclose(t % 1.1, 1.1, atol=TS / 2))
    # At the same phase of every stride the attitude repeats up to the turn: the yaw is the turn, exactly.
    np.testing.assert_allclose(yaw[whole] - yaw[0], turn[whole] - turn[0], atol=1e-9)
    # The vertical rate integrated directly gains the cone's solid angle every stride.
    drift = vertical_rate_integral(q, gyro)[whole[-1]] - (turn[whole[-1]] - turn[0])
    assert abs(math.degrees(drift)) > 20.0


def test_the_attitude_filter_s_corrections_about_the_vertical_do_not_enter():
    _, q, gyro, _ = swinging_walk(seconds=20.0)
    clean, _ = GyroYaw(RATE_HZ).update(q, gyro)
    rng = np.random.default_rng(3)
    # A magnetometer that pulls the heading about (random walk) and a landmark that turns it by 25 degrees.
    pull = np.cumsum(rng.normal(0.0, math.radians(0.3), q.shape[0]))
    pull[1200:] += math.radians(25.0)
    zeros = np.zeros_like(pull)
    corrected = quat.multiply(quat.from_euler(zeros, zeros, pull), q)
    got, _ = GyroYaw(RATE_HZ).update(corrected, gyro)
    np.testing.assert_allclose(got - got[0], clean - clean[0], atol=1e-9)


def test_a_constant_gyro_bias_is_what_up_time_says():
    _, q, gyro, _ = swinging_walk(seconds=20.0)
    b = np.radians([0.4, -0.3, 0.8])
    clean, _ = GyroYaw(RATE_HZ).update(q, gyro)
    biased, up_time = GyroYaw(RATE_HZ).update(q, gyro + b)
    # The filter's attitude does not follow the bias (it is removed there); the gyro yaw keeps it, as up_time . b.
    np.testing.assert_allclose(biased - up_time @ b, clean, atol=math.radians(0.01))
    assert abs(math.degrees(biased[-1] - clean[-1])) > 3.0


def test_an_upright_phone_uses_an_axis_that_is_not_vertical():
    # Long axis vertical (pitch 90 deg): its yaw is undefined, the gyro yaw still follows the turn.
    t, q, gyro, turn = swinging_walk(cone_deg=0.0, base_rpy_deg=(0.0, 90.0, 0.0), turn_dps=10.0)
    g = GyroYaw(RATE_HZ)
    yaw, _ = g.update(q, gyro)
    np.testing.assert_allclose(yaw - yaw[0], turn - turn[0], atol=1e-9)


@settings(max_examples=20, deadline=None)
@given(cuts=st.lists(st.integers(min_value=0, max_value=1500), max_size=6))
def test_batches_and_state_round_trips_give_the_one_batch_result(cuts):
    _, q, gyro, _ = swinging_walk(seconds=15.0, base_rpy_deg=(20.0, 75.0, 0.0))
    whole = GyroYaw(RATE_HZ).update(q, gyro)
    g = GyroYaw(RATE_HZ)
    parts = []
    for a, b in zip([0, *sorted(cuts)], [*sorted(cuts), q.shape[0]], strict=True):
        parts.append(g.update(q[a:b], gyro[a:b]))
        g = GyroYaw.from_state(g.state(), RATE_HZ)
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), whole[0])
    np.testing.assert_array_equal(np.concatenate([p[1] for p in parts]), whole[1])


def test_a_bad_state_is_refused():
    d = GyroYaw(RATE_HZ).state() | {"axis": 3}
    with pytest.raises(ValueError, match="axis"):
        GyroYaw.from_state(d, RATE_HZ)
