"""tools/walking_steps.py: the pipeline's step events on every walking recording (empty tracks listed)."""

from __future__ import annotations

import importlib.util
from types import ModuleType

import pytest

from tests.conftest import REPO_ROOT, data_path


@pytest.fixture(scope="module")
def tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("walking_steps", REPO_ROOT / "tools" / "walking_steps.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.data
def test_the_tool_counts_the_pipelines_steps_and_lists_the_datasets(tool: ModuleType) -> None:
    from pdr.io import read_recording
    from pdr.phone.pipeline import PdrPipeline, PipelineConfig
    from pdr.phone.steps import StepConfig
    data = data_path()
    found = list(tool.recordings(data))
    names = {d for d, _, _ in found}
    assert {"sensor_logger_walks", "oxford_step_counter", "mobifall WAL", "mobifall CSI", "ms_indoor_location",
            "ipin2023_t3", "attitude_smartphones"} <= names
    assert all(walking == (not d.startswith("mobifall") or d.split()[1] in tool.MOBIFALL_WALKING)
               for d, _, walking in found)
    # The same step count as the pipeline (gyro and mag on the grid), here on a short MS trace.
    path = data / "ms_indoor_location" / "site2" / "F3" / "path_data_files" / "5dd398d944333f00067aa442.txt.gz"
    rec = read_recording(path)
    n, duration = tool.pipeline_steps(rec, StepConfig(), PipelineConfig().rate_hz)
    assert n == sum(1 for e in PdrPipeline().run(rec) if e.get("type") == "step") > 0
    assert 6.0 < duration < 7.0
