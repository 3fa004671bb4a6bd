"""The recording codec: a decoded recording stored as bytes comes back equal, truth, warnings and meta included."""

from pathlib import Path

import numpy as np
import pytest

from pdr import recording_codec
from pdr.errors import InputError
from pdr.io import read_recording
from pdr.recording import DeviceInfo, GroundTruth, Labels, PositionTruth, Recording, SensorStream

SIM = Path(__file__).resolve().parents[2] / "mobile_logs" / "sim"


def _same(a: Recording, b: Recording) -> None:
    assert a == b  # streams, device, t0 and every kind of truth (NaN equals NaN)
    assert (a.source, a.format, a.warnings) == (b.source, b.format, b.warnings)
    for k, v in a.truth.extra.items():
        assert b.truth.extra[k].dtype == v.dtype and b.truth.extra[k].shape == v.shape


@pytest.mark.parametrize("name", ["hand_escalator.zip", "foot_walk_run.zip"])
def test_simulated_logs_round_trip(name):
    rec = read_recording(SIM / name)
    assert not rec.truth.is_empty()
    _same(rec, recording_codec.loads(recording_codec.dumps(rec)))


def test_every_truth_kind_text_extras_and_meta_round_trip():
    t = np.arange(5, dtype=np.int64) * 10_000_000 + 123
    rec = Recording(
        {"acc": SensorStream("acc", t, np.ones((5, 3))), "baro": SensorStream("baro", t, np.full(5, 1013.0))},
        device=DeviceInfo("android", "Pixel", "left_foot", "foot", "d1"), t0_ns=100, source="x.csv", format="fmt",
        warnings=("one", "two"), meta={"fs_hz": np.float64(100.0), "columns": ("a", "b"), "path": Path("/tmp/x")},
        truth=GroundTruth(
            positions=PositionTruth(np.array([0.0, 1.0]), np.array([[0, 0, 0], [1, 2, 3.0]]), np.array([np.nan, 1]),
                                    kind="waypoint", frame="map", origin_lat_lon_deg=(49.4, 11.1)),
            step_times_s=np.array([0.2, 0.7]), step_lengths_m=np.array([0.7, 0.71]),
            modes=Labels(np.array([0.0]), np.array([1.0]), ("walk",)), landmarks=Labels(np.array([]), np.array([]), ()),
            extra={"zv": np.array([True, False]), "names": np.array(["a", "bc"]), "i16": np.arange(3, dtype=np.int16)}))
    back = recording_codec.loads(recording_codec.dumps(rec))
    _same(rec, back)
    assert back.truth.positions is not None and back.truth.positions.origin_lat_lon_deg == (49.4, 11.1)
    assert back.truth.step_count == 2 and back.device.device_id == "d1"
    assert dict(back.meta) == {"fs_hz": 100.0, "columns": ["a", "b"], "path": "/tmp/x"}


def test_not_a_stored_recording_is_an_input_error():
    from pdr import state_codec

    with pytest.raises(InputError, match="not a stored recording"):
        recording_codec.loads(state_codec.dumps({"version": 99}))
    with pytest.raises(InputError, match="not a stored processing state"):
        recording_codec.loads(b"garbage")


@pytest.mark.data
def test_real_logs_round_trip():
    from tests.conftest import data_path

    for path in (data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt"),
                 data_path("pyshoe_vicon", "2017-11-22-11-35-59.mat")):
        rec = read_recording(path)
        _same(rec, recording_codec.loads(recording_codec.dumps(rec)))
