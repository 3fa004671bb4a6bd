"""The phone pipeline's configuration built in one place (pdr.phone.configure) for the CLI and the service."""

from __future__ import annotations

import argparse
from dataclasses import replace

from pdr.cli.track import config_from_args
from pdr.phone.configure import pipeline_config, placement_group
from pdr.phone.pipeline import PipelineConfig
from pdr.phone.step_length import StepLengthModel


def test_placement_groups_of_every_device_placement():
    assert placement_group("trouser_pocket_back") == "pocket"
    assert placement_group("neck") == "torso"
    assert placement_group("bag") == "torso"
    assert placement_group("armband") == "hand"
    assert placement_group("vehicle_mount") == "auto"
    assert placement_group(None) == "auto"
    assert placement_group("") == "auto"


def test_defaults_are_the_pipeline_defaults():
    assert pipeline_config() == PipelineConfig()


def test_choices_land_in_the_right_fields():
    model = StepLengthModel(k=0.5)
    cfg = pipeline_config("pocket", attitude_method="ekf", initial_floor=2.0, step_length=model, floor_height_m=3.5)
    base = PipelineConfig(placement="pocket", attitude_method="ekf", initial_floor=2.0)
    assert cfg == replace(base, step_length=model, floors=replace(base.floors, floor_height_m=3.5, learn_height=False))
    # A stated floor height is kept, even the default's: it is not learnt from the flights walked.
    assert not pipeline_config(floor_height_m=4.0).floors.learns_height() and PipelineConfig().floors.learns_height()


def test_cli_options_build_the_same_config(tmp_path):
    cal = tmp_path / "cal.json"
    StepLengthModel(k=0.45).save(cal)
    args = argparse.Namespace(placement="hand", method="ukf", calibration=str(cal), floor_height=4.5)
    assert config_from_args(args, 1.0) == pipeline_config("hand", initial_floor=1.0,
                                                          step_length=StepLengthModel.load(cal), floor_height_m=4.5)
    args = argparse.Namespace(placement="auto", method="ekf", calibration=None, floor_height=None)
    assert config_from_args(args) == PipelineConfig(attitude_method="ekf")
