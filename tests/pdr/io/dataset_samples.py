"""One real sample file (or folder) per shared dataset, for format detection and cross-sniffing tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import SHARED_DATA

#: Dataset sample -> path relative to ../shared/data. The first part of the key is the reader's FORMAT,
#: or a dataset read by another reader (foreign to the five readers whose tests use this table).
SAMPLES: dict[str, str] = {
    "ipin:txt": "ipin2023_t3/logfiles/IPIN2023_T3_TrainingTrial01_repetition01.txt",
    "ipin:mat": "ipin2023_t3/mat/IPIN2023_T3_TrainingTrial53_repetition01.mat",
    "ms_indoor:trace": "ms_indoor_location/site2/F3/path_data_files/5dd38ffd27889b0006b76aca.txt.gz",
    "oxford:folder": "oxford_step_counter/optimisation/data/Samsung_Carmelo_Hard_FrontPocket_1",
    "oxford:acc": "oxford_step_counter/optimisation/data/Samsung_Carmelo_Hard_FrontPocket_1/accelerometer.csv.gz",
    "mobifall:acc": "mobifall_v2_pocket/sub2/ADL/WAL/WAL_acc_2_1.txt.gz",
    "mobifall:gyro": "mobifall_v2_pocket/sub2/ADL/WAL/WAL_gyro_2_1.txt.gz",
    "driving:folder": "driving_phone_mount/17",
    "driving:acc": "driving_phone_mount/17/acelerometro_terra.csv",
    "tyrex:folder": "attitude_smartphones/android/Jakob_Nexus5_NoDist_Texting",
    "other:pyshoe": "pyshoe_vicon/2017-11-22-11-35-59.mat",
    "other:xio": "xio_gait_loop/short_walk.csv",
    "other:npz": "allan_static_imudata/adis_16405_imu1.npz",
    "other:stride_csv": "foot_stride_gcp/LLIO_training_data/2017-11-22-11-44-47_strideIndex_timestamp_gcpX_gcpY.csv",
}


def samples_of(fmt: str) -> list[str]:
    """Keys of the samples that belong to reader ``fmt``."""
    return [k for k in SAMPLES if k.split(":")[0] == fmt]


def foreign_to(fmt: str) -> list[str]:
    """Keys of the samples another reader owns."""
    return [k for k in SAMPLES if k.split(":")[0] != fmt]


def sample_path(key: str) -> Path:
    """Absolute path of a sample; skips the test when the dataset is absent."""
    p = SHARED_DATA / SAMPLES[key]
    if not p.exists():
        pytest.skip(f"shared dataset not available: {p}")
    return p


def detect_or_skip(path: Path) -> str:
    """``pdr.io.detect_format(path)``; skips while a reader listed in the registry is not written yet."""
    from pdr.io import detect_format
    try:
        return detect_format(path)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.startswith("pdr.io."):
            pytest.skip(f"reader module {exc.name} not written yet")
        raise
