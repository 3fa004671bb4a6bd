"""Gait styles of the simulator (pdr.sim.gait): the thigh-angle shape against its normative source, seed 003's
stairs rules, and no motion without stepping.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pdr.sim.gait import STILL, STYLES, THIGH_SHAPE, GaitStyle, style
from pdr.sim.placement import thigh_shape
from pdr.sim.smooth import Jet

_D = np.pi / 180.0


def shape(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``s(phi)`` and ``ds/dphi`` (per stride) on stride phases ``phi``."""
    out = thigh_shape(Jet(phi, np.ones_like(phi), np.zeros_like(phi)))
    return out.value, out.d1


def test_thigh_shape_is_normalised_and_follows_the_normative_angle() -> None:
    """Range [-1, 1]; from Winter's normative thigh angle (+20 deg at heel strike, -13 deg at 55 %, +23 deg at 90 %
    of the stride; mid-range 5 deg, half range 18 deg) the shape is 15/18 at heel strike, -1 near 55 % and +1 near
    90 %; it extends slowly through stance and flexes fast in swing.
    """
    phi = np.linspace(0.0, 1.0, 100001)
    s, ds = shape(phi)
    assert s.max() == pytest.approx(1.0, abs=0.02) and s.min() == pytest.approx(-1.0, abs=0.02)
    # The three-harmonic fit passes within 2 deg (0.11 of the half range) of the normative points.
    assert s[0] == pytest.approx(15.0 / 18.0, abs=0.11)
    assert phi[np.argmin(s)] == pytest.approx(0.55, abs=0.04)
    assert phi[np.argmax(s)] == pytest.approx(0.90, abs=0.04)
    assert s[0] == pytest.approx(s[-1], abs=1e-9)                      # periodic
    # Peak flexion rate about 9.7 per stride (module doc: about 9.7 amp rad/s per Hz of stride frequency), larger
    # than the peak extension rate: the thigh swings forward faster than it extends in stance.
    assert ds.max() == pytest.approx(9.7, abs=0.1)
    assert ds.max() > -ds.min()
    assert (THIGH_SHAPE[0] + sum(a for a, _ in THIGH_SHAPE[1])) == pytest.approx(s[0], abs=1e-9)


def test_stairs_follow_seed_003() -> None:
    """Seed 003 eqs. 1-3: upstairs the thigh opens wider and lifts higher than walking; downstairs it opens less,
    with a higher minimum.
    """
    walk, up, down = STYLES["walking"], STYLES["stairs_up"], STYLES["stairs_down"]
    assert up.thigh_amp_rad > walk.thigh_amp_rad
    assert up.thigh_mean_rad + up.thigh_amp_rad > walk.thigh_mean_rad + walk.thigh_amp_rad
    assert down.thigh_amp_rad < walk.thigh_amp_rad
    assert down.thigh_mean_rad - down.thigh_amp_rad > walk.thigh_mean_rad - walk.thigh_amp_rad


def test_running_is_stronger_than_walking_with_a_shorter_stance() -> None:
    walk, run = STYLES["walking"], STYLES["running"]
    assert run.stance_fraction < 0.5 < walk.stance_fraction
    for name in ("thigh_amp_rad", "bounce_m", "impact_mps2", "body_shock_mps2", "leg_shock_mps2"):
        assert getattr(run, name) > getattr(walk, name), name


@pytest.mark.parametrize("mode", ["standing", "elevator_up", "escalator_down", "unknown"])
def test_modes_without_stepping_have_no_motion(mode: str) -> None:
    st = style(mode)
    assert st is STILL
    for f in dataclasses.fields(GaitStyle):
        if f.name.endswith(("_rad", "_m", "_mps2")):
            assert getattr(st, f.name) == 0.0, f.name


def test_styles_are_read_only() -> None:
    with pytest.raises(TypeError):
        STYLES["walking"] = STILL  # type: ignore[index]
    assert style("walking") is STYLES["walking"]
