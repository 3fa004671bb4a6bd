"""tools/walking_steps.py: the pipeline's step events on every walking recording (empty tracks listed); the
motion-capture step truth it shares with ``pdr eval steps`` (pdr.evaluation.mocap_steps)."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.evaluation import mocap_steps
from pdr.evaluation.walking_recordings import MOBIFALL_WALKING
from tests.conftest import data_path, load_tool


@pytest.fixture(scope="module")
def tool() -> ModuleType:
    return load_tool("walking_steps")


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
    assert all(walking == (not d.startswith("mobifall") or d.split()[1] in MOBIFALL_WALKING)
               for d, _, walking in found)
    # The same step count as the pipeline (gyro and mag on the grid), here on a short MS trace.
    path = data / "ms_indoor_location" / "site2" / "F3" / "path_data_files" / "5dd398d944333f00067aa442.txt.gz"
    rec = read_recording(path)
    n, duration = tool.pipeline_steps(rec, StepConfig(), PipelineConfig().rate_hz)
    assert n == sum(1 for e in PdrPipeline().run(rec) if e.get("type") == "step") > 0
    assert 6.0 < duration < 7.0


def _gait_heights(rng: np.random.Generator, steps: int, rate_hz: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """Phone heights (m) of a walk of ``steps`` steps between two stands: one vault per step (a half-sine rise of
    1-2 cm, step 0.5-0.95 s, cadence drifting), sub-millimetre capture noise, some hidden frames."""
    seg = [np.full(int(3 * rate_hz), 1.2)]
    for _ in range(steps):
        n = int(rng.uniform(0.5, 0.95) * rate_hz)
        seg.append(1.2 + rng.uniform(0.01, 0.02) * np.sin(np.pi * np.arange(n) / n))
    seg.append(np.full(int(3 * rate_hz), 1.2))
    z = np.concatenate(seg) + rng.normal(0.0, 3e-4, sum(s.size for s in seg))
    t = np.arange(z.size) / rate_hz
    pos = np.column_stack([0.3 * t, np.zeros_like(t), z])
    pos[rng.random(z.size) < 0.01] = np.nan
    return t, pos


@pytest.mark.parametrize("steps", [4, 20, 150])
def test_mocap_step_count_recovers_simulated_vaults(steps: int) -> None:
    rng = np.random.default_rng(steps)
    t, pos = _gait_heights(rng, steps)
    assert mocap_steps.mocap_step_count(t, pos) == steps


def test_mocap_step_count_counts_nothing_standing_or_swaying() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(0, 60, 1 / 60)
    # Standing: capture noise and a slow 0.2 Hz, 1 cm sway (below the step band).
    z = 1.2 + 0.01 * np.sin(2 * np.pi * 0.2 * t) + rng.normal(0, 3e-4, t.size)
    assert mocap_steps.mocap_step_count(t, np.column_stack([t * 0, t * 0, z])) == 0


def test_mocap_step_count_refuses_a_too_slow_capture() -> None:
    t = np.arange(0, 10, 0.25)
    with pytest.raises(InputError, match="too slow"):
        mocap_steps.mocap_step_count(t, np.zeros((t.size, 3)))


@pytest.mark.data
@pytest.mark.slow
@pytest.mark.parametrize("name", ["Jakob_Nexus5_NoDist_Texting", "Jakob_Nexus5_NoDist_FrontPocket",
                                  "Guillaume_Nexus5_NoDist_FrontPocket"])
def test_mocap_step_count_agrees_with_the_detector_where_it_is_right(tool: ModuleType, name: str) -> None:
    """On the clean walks where the detector and the plain peak detector agree (within 2 %), the motion-capture count
    is within 5 % of the detector's (the heights are the capture's, the detector's input the accelerometer)."""
    from pdr.io import read_recording
    from pdr.phone.pipeline import PipelineConfig
    from pdr.phone.steps import StepConfig
    rec = read_recording(data_path("attitude_smartphones", "android", name))
    true, origin = mocap_steps.true_step_count(rec)
    assert origin == "mocap"
    n, _ = tool.pipeline_steps(rec, StepConfig(), PipelineConfig().rate_hz)
    assert true is not None and abs(true - n) <= 0.05 * n


def test_matched_steps_pairs_one_to_one_after_the_lag() -> None:
    true = np.arange(20) * 0.6 + 1.0
    det = np.r_[true[:15] - 0.12, 5.3]                       # 15 steps 0.12 s early, one extra between two steps
    hits, lag = mocap_steps.matched_steps(det, true)
    assert hits == 15 and lag == pytest.approx(0.12)
    assert mocap_steps.matched_steps(np.r_[det, det], true)[0] == 15   # one true step matches one detected step only
    assert mocap_steps.matched_steps(np.zeros(0), true) == (0, 0.0)


@pytest.mark.data
@pytest.mark.slow
def test_mocap_steps_are_the_detectors_steps_on_a_brisk_texting_walk(tool: ModuleType) -> None:
    """Jakob_Nexus5_NoDist_Texting (0.63 s steps, the detector and the plain peak detector agree): the true steps from
    the capture's heights and the detector's steps from the accelerometer pair up one to one (180 of 186)."""
    from pdr.io import read_recording
    from pdr.phone.pipeline import PipelineConfig
    from pdr.phone.steps import StepConfig
    rec = read_recording(data_path("attitude_smartphones", "android", "Jakob_Nexus5_NoDist_Texting"))
    trajectory = mocap_steps.mocap_trajectory(rec)
    assert trajectory is not None
    true = mocap_steps.mocap_step_times(*trajectory)
    det, _ = tool.pipeline_step_times(rec, StepConfig(), PipelineConfig().rate_hz)
    hits, lag = mocap_steps.matched_steps(det, true)
    assert hits >= 0.95 * max(det.size, true.size)
    # Both on the recording's t_s axis: the top of the vault (mid-stance) comes before the acceleration's upward
    # crossing that starts the next step (the body falls onto the next foot): -0.24 s here.
    assert -0.4 < lag < 0.0


@pytest.mark.data
def test_cut_counts_a_recording_started_later(tool: ModuleType, capsys: pytest.CaptureFixture[str]) -> None:
    # --cut 5: the Sensor Logger walks less their first 5 s; no whole-walk count is printed as their truth.
    assert tool.main([str(data_path()), "--only", "sensor_logger", "--cut", "5"]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("sensor_logger_walks:")]
    assert len(lines) == 4 and not any("true" in ln for ln in lines)
    pocket = next(ln for ln in lines if "inpocket-27-steps-Matan" in ln)
    assert "25.5 s" in pocket
