import json
import math

import pytest

from pdr.errors import InputError
from pdr.sim.scenario import load_scenario, parse_scenario

WALK = {"segments": [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 5}]}


def _with(**kw):
    return {**WALK, **kw}


def test_defaults_resolve_every_segment():
    sc = parse_scenario({"segments": [
        {"type": "stand", "duration_s": 2}, {"type": "walk", "distance_m": 13, "speed_mps": 1.3},
        {"type": "turn", "angle_deg": -90}, {"type": "stairs", "direction": "up"},
        {"type": "elevator", "direction": "down", "floors": 2}, {"type": "escalator", "direction": "up"},
        {"type": "run", "duration_s": 3}]})
    walk, turn, stairs, elevator, escalator, run = sc.segments[1:]
    assert walk.duration_s == pytest.approx(10.0) and walk.step_frequency_hz == pytest.approx(1.8)
    assert turn.turn_rad == pytest.approx(-math.pi / 2) and turn.landmark == "turn_right"
    assert turn.speed_mps == pytest.approx(1.3)
    assert stairs.climb_m == pytest.approx(3.0) and stairs.mode == "stairs_up"
    assert stairs.duration_s * stairs.step_frequency_hz == pytest.approx(18)
    assert elevator.climb_m == pytest.approx(-6.0) and elevator.mode == "elevator_down"
    assert escalator.duration_s == pytest.approx(3.0 / (0.5 * 0.5))
    assert run.mode == "running" and run.speed_mps == 3.0
    assert sc.start_yaw_rad == pytest.approx(0.0)  # heading 90 deg (east)
    assert sc.rates_hz == {"acc": 100.0, "gyro": 100.0, "mag": 50.0, "baro": 10.0}


def test_foot_defaults_and_rate_omission():
    sc = parse_scenario(_with(placement="foot", rates_hz={"acc": 400, "gyro": 400, "baro": 20}))
    assert sc.rates_hz == {"acc": 400.0, "gyro": 400.0, "baro": 20.0}
    sc = parse_scenario(_with(rates_hz={"mag": None}))
    assert "mag" not in sc.rates_hz


@pytest.mark.parametrize(("doc", "match"), [
    ([], "must be a JSON object"),
    ({}, "'segments' is required"),
    ({"segments": []}, "segments"),
    ({"segments": [{"type": "fly", "duration_s": 2}]}, r"segments\[0\].type.*'fly' is not one of"),
    ({"segments": [{"type": "walk"}]}, r"segments\[0\].*exactly one of duration_s and distance_m"),
    ({"segments": [{"type": "walk", "duration_s": 3, "distance_m": 3}]}, "exactly one of"),
    ({"segments": [{"type": "walk", "duration_s": 3, "speed_mps": -1}]}, r"segments\[0\].speed_mps"),
    ({"segments": [{"type": "walk", "duration_s": 3, "speed": 1}]}, r"unknown field.*'speed'"),
    ({"segments": [{"type": "stairs", "direction": "sideways"}]}, r"segments\[0\].direction"),
    ({"segments": [{"type": "turn", "angle_deg": 0}]}, r"segments\[0\].angle_deg.*non-zero"),
    ({"segments": [{"type": "elevator", "direction": "up", "duration_s": 4}]}, r"duration_s.*at least 11"),
    ({"segments": [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 0.3}]},
     r"segments\[1\].*at least one step"),
    ({"segments": [{"type": "stand", "duration_s": "long"}]}, r"segments\[0\].duration_s.*not of type"),
    ({**WALK, "placement": "pocket"}, r"placement.*'pocket' is not one of"),
    ({**WALK, "rates_hz": {"acc": None}}, r"rates_hz.acc.*cannot be left out"),
    ({**WALK, "rates_hz": {"acc": 5000}}, r"rates_hz.acc"),
    ({**WALK, "sensors": {"grade": "military"}}, r"sensors.grade"),
    ({**WALK, "sensors": {"gyro": {"arw": 1}}}, r"sensors.gyro.*unknown field.*'arw'"),
    ({**WALK, "sensors": {"gyro": {"bias_instability_model": "pink"}}}, "bias_instability_model"),
    ({**WALK, "mount_rpy_deg": [1, 2]}, "mount_rpy_deg"),
    ({"segments": [{"type": "stairs", "direction": "up", "floors": 1, "steps": 10, "riser_m": 0.2}]},
     "at most two of"),
])
def test_validation_errors_name_the_field(doc, match):
    with pytest.raises(InputError, match=match):
        parse_scenario(doc, source="s.json")


def test_load_scenario_reports_file_and_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"segments": [\n  {"type": "stand",, "duration_s": 1}]}')
    with pytest.raises(InputError, match=r"bad.json, line 2: not valid JSON"):
        load_scenario(bad)
    with pytest.raises(InputError, match="cannot read scenario"):
        load_scenario(tmp_path / "missing.json")
    good = tmp_path / "good.json"
    good.write_text(json.dumps(WALK))
    assert load_scenario(good).duration_s == pytest.approx(7.0)
