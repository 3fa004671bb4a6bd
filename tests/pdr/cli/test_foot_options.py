"""``pdr foot`` / ``pdr eval foot``: a setting a navigation method does not have is refused or reported, not
silently ignored (issue #5)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

import pdr.cli.foot as foot
from pdr.cli import main
from pdr.foot.navigate import METHOD_OPTIONS, METHODS, unsupported_options
from pdr.foot.zupt import ZuptConfig
from pdr.sim import parse_scenario, simulate

FLAGS = {"zaru": ["--zaru", "on"], "interval_samples": ["--imu-samples", "interval"],
         "gyro_bias": ["--gyro-bias", "on"]}


def test_every_method_lists_its_settings() -> None:
    assert set(METHOD_OPTIONS) == set(METHODS)
    assert unsupported_options("zupt", ZuptConfig(zaru=True, interval_samples=True), True, True) == []
    assert unsupported_options("bc", ZuptConfig(zaru=True, interval_samples=True), True, True) == [
        "zaru", "interval_samples", "smooth", "gyro_bias"]
    assert unsupported_options("filterbank", ZuptConfig(interval_samples=True)) == []
    assert unsupported_options("stepwise", None, gyro_bias=True) == ["gyro_bias"]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("setting", sorted(FLAGS))
def test_pdr_foot_refuses_a_setting_the_method_does_not_have(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                             method: str, setting: str) -> None:
    log = _foot_log(tmp_path, walk_s=6, seed=3)
    out = tmp_path / "track.csv"
    code = main(["foot", str(log), "--method", method, *FLAGS[setting], "--out", str(out)])
    if setting in METHOD_OPTIONS[method]:
        assert code == 0 and out.exists()
    else:
        assert code == 2 and not out.exists()
        assert f"--method {method} does not have {' '.join(FLAGS[setting])}" in capsys.readouterr().err


def test_evaluation_runs_each_method_with_the_settings_it_has(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: dict[str, ZuptConfig] = {}

    def fake_navigate(rec: object, method: str, detector: object, zupt: ZuptConfig, smooth: bool,
                      gyro_bias: bool, zero_velocity: object) -> tuple[None, None]:
        calls[method] = zupt
        return None, None

    monkeypatch.setattr(foot, "navigate", fake_navigate)
    args = argparse.Namespace(smoother="on", zaru="on", gyro_bias="off", detector="shoe", fixed_threshold=False,
                              threshold=None, run_gain=None, imu_samples="interval")
    for method in foot.EVAL_METHODS:
        foot._navigate_variant(None, method, args)
    assert calls["zupt"] == ZuptConfig(zaru=True, interval_samples=True)
    assert calls["filterbank"] == calls["filterbank-height"] == ZuptConfig(interval_samples=True)
    assert calls["bc"] == ZuptConfig()
    assert foot._method_zupt_config("bc", args)[1] == ["--zaru on", "--imu-samples interval"]
    assert foot._method_zupt_config("zupt", args)[1] == []
    with_bias = argparse.Namespace(**{**vars(args), "gyro_bias": "on"})
    assert foot._method_zupt_config("filterbank", with_bias) == (ZuptConfig(interval_samples=True),
                                                                  ["--zaru on", "--gyro-bias on"])


def test_pdr_foot_makes_the_folders_of_its_outputs(tmp_path: Path) -> None:
    # "error: OUT: No such file or directory" before: pdr track and pdr classify make the folder (pdr.cli.outputs).
    log = _foot_log(tmp_path, walk_s=4, seed=4)
    out, png = tmp_path / "a" / "b" / "track.csv", tmp_path / "c" / "track.png"
    assert main(["foot", str(log), "--out", str(out), "--plot", str(png)]) == 0
    assert out.read_text().startswith("t_s") and png.read_bytes().startswith(b"\x89PNG")


def _foot_log(tmp_path: Path, walk_s: float, seed: int) -> Path:
    """A simulated shoe-IMU log (native folder): stand 2 s, walk ``walk_s`` s at 1.4 m/s, stand 2 s."""
    from pdr.io.native import write as write_native

    scenario = {"name": "foot", "placement": "foot", "rates_hz": {"acc": 200, "gyro": 200},
                "sensors": {"grade": "consumer"},
                "segments": [{"type": "stand", "duration_s": 2},
                             {"type": "walk", "duration_s": walk_s, "speed_mps": 1.4},
                             {"type": "stand", "duration_s": 2}]}
    log = tmp_path / "foot"
    write_native(simulate(parse_scenario(scenario), seed), log)
    return log
