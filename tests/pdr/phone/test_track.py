"""PDR mechanization (seed 004 eq. 22): positions, the covariance's linearisation, fixes, redone tracks, state."""

import math

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.frames import yaw_to_heading_deg
from pdr.phone.track import TrackState, dead_reckon, redo_steps


def _position(length: float, yaw: float) -> np.ndarray:
    return np.array([length * math.cos(yaw), length * math.sin(yaw)])


def test_a_step_moves_along_its_yaw_and_the_covariance_is_the_jacobian_propagation():
    tr = TrackState(2.0, -1.0)
    tr.step(0.7, math.radians(30.0), 0.01, 0.004)
    assert (tr.east_m, tr.north_m) == pytest.approx((2.0 + 0.7 * math.cos(math.radians(30)),
                                                     -1.0 + 0.7 * math.sin(math.radians(30))))
    # J of eq. 22 with respect to (length, yaw), by central differences: P = J diag(var_s, var_psi) J^T.
    s, y, h = 0.7, math.radians(30.0), 1e-6
    j = np.column_stack([(_position(s + h, y) - _position(s - h, y)) / (2 * h),
                         (_position(s, y + h) - _position(s, y - h)) / (2 * h)])
    np.testing.assert_allclose(tr.P, j @ np.diag([0.01, 0.004]) @ j.T, rtol=1e-7, atol=1e-12)
    tr.step(0.7, math.radians(120.0), 0.01, 0.004)
    assert tr.n_steps == 2 and np.trace(tr.P) > 2 * 0.01       # uncertainty grows with every step


def test_a_fix_resets_position_and_covariance_and_bad_steps_are_refused():
    tr = TrackState()
    for _ in range(5):
        tr.step(0.6, 0.3, 0.01, 0.01)
    tr.fix(10.0, 20.0, 0.5)
    assert (tr.east_m, tr.north_m) == (10.0, 20.0)
    np.testing.assert_array_equal(tr.P, 0.5 * np.eye(2))
    with pytest.raises(InputError, match="finite"):
        tr.step(math.nan, 0.0, 0.0, 0.0)


def test_dead_reckon_equals_stepping_the_track():
    rng = np.random.default_rng(3)
    length, yaw = rng.uniform(0.4, 0.9, 50), rng.uniform(-math.pi, math.pi, 50)
    tr = TrackState(1.0, 2.0)
    pos = []
    for s, y in zip(length, yaw, strict=True):
        tr.step(float(s), float(y), 0.0, 0.0)
        pos.append((tr.east_m, tr.north_m))
    np.testing.assert_allclose(dead_reckon(length, yaw, (1.0, 2.0)), pos, atol=1e-12)
    with pytest.raises(InputError, match="one shape"):
        dead_reckon(length, yaw[:-1])


def test_redo_steps_moves_positions_by_the_changed_displacements_and_restarts_at_fixes():
    length, yaw = np.array([1.0, 1.0, 1.0, 1.0]), np.zeros(4)
    pos = dead_reckon(length, yaw)
    steps = [{"east_m": float(p[0]), "north_m": float(p[1]), "heading_deg": float(yaw_to_heading_deg(0.0)),
              "step_length_m": 1.0, "floor": 0.0} for p in pos]
    # A landmark fixed the position at (49, 0) before the 3rd step's displacement: the track goes on from there.
    steps[2] = {**steps[2], "east_m": 50.0, "north_m": 0.0, "position_fix": True}
    steps[3] = {**steps[3], "east_m": 51.0, "north_m": 0.0}
    new = redo_steps(steps, np.full(4, math.pi / 2), np.full(4, 2.0))
    # Before the fix: walked north with 2 m steps; the fix's own step moved by its change; after: from the fix.
    assert [(r["east_m"], r["north_m"]) for r in new[:2]] == [pytest.approx((0.0, 2.0)), pytest.approx((0.0, 4.0))]
    assert (new[2]["east_m"], new[2]["north_m"]) == pytest.approx((49.0, 2.0))
    assert (new[3]["east_m"], new[3]["north_m"]) == pytest.approx((49.0, 4.0))
    assert all(r["heading_deg"] == pytest.approx(0.0) and r["step_length_m"] == 2.0 for r in new)
    with pytest.raises(InputError, match="one yaw and one length per step"):
        redo_steps(steps, np.zeros(3))


def test_state_round_trip_and_bad_state():
    tr = TrackState(1.5, 2.5)
    tr.step(0.8, 1.0, 0.02, 0.03)
    again = TrackState.from_state(tr.state())
    assert (again.east_m, again.north_m, again.n_steps) == (tr.east_m, tr.north_m, 1)
    np.testing.assert_array_equal(again.P, tr.P)
    with pytest.raises(InputError, match="bad track state"):
        TrackState.from_state({"east_m": 0.0})


def test_redo_steps_converts_each_heading_as_one_step_at_a_time_would():
    """The headings converted as one array are the per-step conversions bit for bit (and positions move by floats)."""
    rng = np.random.default_rng(3)
    yaw = np.concatenate([rng.uniform(-10.0, 10.0, 5000), [0.0, -0.0, math.pi, -math.pi, math.pi / 2, 1e-300]])
    steps = [{"east_m": float(e), "north_m": float(n), "heading_deg": 10.0, "step_length_m": 0.7}
             for e, n in rng.normal(0.0, 50.0, (yaw.size, 2))]
    new = redo_steps(steps, yaw)
    got = np.array([s["heading_deg"] for s in new])
    want = np.array([float(yaw_to_heading_deg(y)) for y in yaw])
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    assert all(type(s[k]) is float for s in new for k in ("east_m", "north_m", "heading_deg", "step_length_m"))
