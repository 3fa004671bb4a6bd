"""A pocket phone's ``sitting`` needs a thigh turned from its upright (walking) direction (classifiers.posture)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from classifiers.posture import SITTING_MIN_TILT_DEG, PostureGate, gate_posture
from pdr.errors import InputError
from tests.conftest import data_path

CLASSES = ("walking", "stationary", "sitting", "car_step_in", "vehicle")


def _tilted(deg: float) -> list[float]:
    """Unit gravity direction turned by ``deg`` from the device's +x (the upright thigh's) towards +z."""
    return [math.cos(math.radians(deg)), 0.0, math.sin(math.radians(deg))]


def _item(label: str, t0: float, gravity: list[float],
          proba: tuple[float, ...] = (0.1, 0.3, 0.4, 0.15, 0.05)) -> dict:
    return {"t_start_s": t0, "t_end_s": t0 + 2.56, "mode": label, "confidence": max(proba),
            "proba": dict(zip(CLASSES, proba, strict=True)), "gravity": gravity}


def _modes(items: list[dict]) -> list[str]:
    gate = PostureGate()
    return [it["mode"] for it in gate.push(items) + gate.flush()]


def test_sitting_stands_only_with_the_thigh_turned_from_its_walking_direction():
    walk = [_item("walking", 0.0, _tilted(10.0)), _item("walking", 1.28, _tilted(-10.0))]
    # Standing after the walk (thigh within 20 deg of the walking one): at rest and upright, with the posterior of
    # being at rest (stationary 0.1 + sitting 0.3).
    gate = PostureGate()
    out = gate.push([*walk, _item("sitting", 5.0, _tilted(20.0), proba=(0.5, 0.1, 0.3, 0.05, 0.05))])
    assert (out[-1]["mode"], out[-1]["confidence"]) == ("stationary", pytest.approx(0.4))
    assert _modes([*walk, _item("sitting", 6.28, _tilted(SITTING_MIN_TILT_DEG + 35.0))])[-1] == "sitting"  # seated
    assert _modes([*walk, _item("sitting", 5.0, [math.nan] * 3)])[-1] == "sitting"
    # A stand before the walk waits for it and is judged against it; a seated start is not.
    stand = [_item("sitting", 0.0, _tilted(15.0)), _item("stationary", 1.28, _tilted(15.0))]
    later_walk = [_item("walking", 3.0, _tilted(5.0)), _item("walking", 4.28, _tilted(0.0))]
    assert _modes([*stand, *later_walk]) == ["stationary", "stationary", "walking", "walking"]
    assert _modes([_item("sitting", 0.0, _tilted(85.0)), *later_walk])[0] == "sitting"
    # No upright window within reach on either side, or none at all: the thigh's angle is unknown.
    far_walk = [_item("walking", 40.0, _tilted(5.0))]
    assert _modes([*stand, *far_walk])[:2] == ["sitting", "stationary"]
    assert _modes(stand) == ["sitting", "stationary"]
    assert _modes([*walk, _item("sitting", 100.0, _tilted(0.0))])[-1] == "sitting"


def test_online_decisions_in_chunks_with_saved_state_equal_the_offline_ones():
    rng = np.random.default_rng(4)
    n = 60
    labels = list(rng.choice(["walking", "sitting", "stationary"], n, p=[0.5, 0.3, 0.2]))
    gravity = np.array([_tilted(a) for a in rng.uniform(-30.0, 100.0, n)])
    proba = rng.dirichlet(np.ones(len(CLASSES)), n)
    t0 = np.arange(n, dtype=np.float64) * 1.28
    offline, conf = gate_posture(labels, proba.max(axis=1), proba, CLASSES, t0, t0 + 2.56, gravity)
    assert offline != tuple(labels)                       # the rule acts on this sequence
    items = [{"t_start_s": t0[i], "t_end_s": t0[i] + 2.56, "mode": labels[i], "confidence": proba[i].max(),
              "proba": dict(zip(CLASSES, proba[i], strict=True)), "gravity": gravity[i].tolist()} for i in range(n)]
    gate, online = PostureGate(), []
    for a in range(0, n, 7):
        online += gate.push(items[a:a + 7])
        gate = PostureGate.from_state(gate.state())
    online += gate.flush()
    assert [it["t_start_s"] for it in online] == list(t0)        # every window once, in time order
    assert tuple(it["mode"] for it in online) == offline
    np.testing.assert_allclose([it["confidence"] for it in online], conf)
    assert all("gravity" not in it for it in online)
    with pytest.raises(InputError, match="posture gate state"):
        PostureGate.from_state({"reach_s": 30.0})


@pytest.mark.data
def test_real_and_simulated_pocket_phones_sit_only_with_a_turned_thigh():
    from classifiers.streaming import shared_model
    from pdr.io import read_recording

    model = shared_model("motion_mode")
    # The simulated pocket office walk ends standing: once labelled sitting.
    office = model.classify(read_recording(Path(__file__).resolve().parents[2] / "mobile_logs" / "sim" /
                                           "pocket_office.zip"))
    assert "sitting" not in office.label, office.label        # it stands before and after its walk
    # MobiFall: walking to a car and getting in turns the thigh to the horizontal; the seat stays sitting.
    car = model.classify(read_recording(data_path("mobifall_v2_pocket", "sub2", "ADL", "CSI", "CSI_acc_2_1.txt.gz")))
    assert car.label[0] == "walking" and car.label[1:] == ("sitting", "sitting"), car.label
