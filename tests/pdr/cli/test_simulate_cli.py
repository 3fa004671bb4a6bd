import json

import pytest

from pdr.cli import main
from pdr.io import native
from pdr.sim import simulate

SCENARIO = {"name": "cli", "segments": [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 4},
                                        {"type": "stand", "duration_s": 2}]}


@pytest.fixture
def scenario_file(tmp_path):
    p = tmp_path / "scenario.json"
    p.write_text(json.dumps(SCENARIO))
    return p


def test_simulate_writes_a_native_recording_equal_to_the_library_call(tmp_path, scenario_file, capsys):
    out = tmp_path / "rec"
    assert main(["simulate", str(scenario_file), "--seed", "5", "--out", str(out)]) == 0
    assert "trouser_pocket" in capsys.readouterr().out
    assert native.read(out) == simulate(SCENARIO, 5)


@pytest.mark.parametrize("name", ["rec.zip", "rec.json", "rec.json.gz"])
def test_simulate_output_containers(tmp_path, scenario_file, name):
    out = tmp_path / name
    assert main(["simulate", str(scenario_file), "--out", str(out), "--placement", "foot", "--side", "left"]) == 0
    rec = native.read(out)
    assert rec.device.role == "left_foot" and rec.truth.step_count is not None and rec.truth.step_count > 0


def test_simulate_bad_input_is_a_clean_error(tmp_path, scenario_file, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"segments": [{"type": "walk", "duration_s": 3, "speed_mps": "fast"}]}))
    assert main(["simulate", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "segments[0].speed_mps" in err
    assert main(["simulate", str(tmp_path / "missing.json"), "--out", str(tmp_path / "o")]) == 2
    assert main(["simulate", str(scenario_file), "--seed", "-1", "--out", str(tmp_path / "o")]) == 2
    assert "--seed" in capsys.readouterr().err
