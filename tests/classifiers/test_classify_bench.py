"""``pdr bench classify``: per-stage timing of ``pdr classify --model`` in process and as a separate process."""

from __future__ import annotations

import json

import pytest

import classifiers.model as model_module
from classifiers import classify_bench
from pdr.cli import main
from tests.conftest import data_path


@pytest.mark.data
def test_bench_times_every_stage_and_the_process_writes_the_same_csv(capsys) -> None:
    log = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial21_repetition01.txt")
    originals = (model_module.make_windows, model_module.extract_features)
    assert main(["bench", "classify", str(log), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    best = res["best"]
    assert set(best["stages_s"]) == set(classify_bench.STAGES)
    assert all(v >= 0 for v in best["stages_s"].values()) and best["windows"] > 50
    assert best["total_s"] >= sum(best["stages_s"].values()) - 1e-6
    assert res["same_output"] and res["process_s"] > 0
    # The timing wrappers are gone once the bench has run.
    assert (model_module.make_windows, model_module.extract_features) == originals


def test_bench_refuses_a_repeat_below_one(capsys) -> None:
    assert main(["bench", "classify", "any.txt", "--repeat", "0"]) == 2
    assert "--repeat and --tile must be at least 1" in capsys.readouterr().out
