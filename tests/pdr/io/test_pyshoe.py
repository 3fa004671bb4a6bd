import gzip

import numpy as np
import pytest
from scipy.io import savemat

from pdr.errors import InputError
from pdr.io import pyshoe
from tests.conftest import data_path
from tests.pdr.io._registry import detect_or_skip


def _trial(n=400, **over):
    ts = 0.005 + np.arange(n) * 0.005
    imu = np.zeros((n, 6))
    imu[:, 2] = 9.81
    zv = (np.arange(n) % 100 < 50).astype(np.int64)
    d = {"imu": imu, "ts": ts[None, :], "gt": np.column_stack([np.arange(n) * 0.01, np.zeros(n), np.ones(n)]),
         "zv_shoe_opt": zv[None, :], "zv_vicon_opt": (1 - zv)[None, :], "best_detector": np.array(["vicon"]),
         "best_error": np.array([[0.05]]), "trial_error": np.array([[0.06, 0.07, 0.08, 0.09, 0.05]]),
         "G_shoe_opt": np.array([[2.5e6]])}
    d.update(over)
    return d


def _write(tmp_path, d, name="trial.mat"):
    p = tmp_path / name
    savemat(p, d)
    return p


def test_synthetic_trial(tmp_path):
    p = _write(tmp_path, _trial())
    assert pyshoe.sniff(p)
    rec = pyshoe.read(p)
    assert rec.stream("acc").median_rate_hz() == pytest.approx(200.0)
    assert rec.device.role == "right_foot" and rec.device.placement == "foot" and rec.meta["foot_side"] == "unknown"
    pos = rec.truth.positions
    assert pos is not None and pos.kind == "dense" and pos.frame == "map" and len(pos) == 400
    np.testing.assert_allclose(pos.t_s, rec.t_s("acc"))
    zv = rec.truth.extra["zero_velocity"]
    assert zv.dtype == bool and zv.shape == (400,)
    np.testing.assert_array_equal(zv, rec.truth.extra["zero_velocity_vicon"])  # best detector
    assert rec.meta["trial_error_m"]["mbgtd"] == 0.09 and rec.meta["best_error_m"] == 0.05
    # The amvd slot of trial_error repeats ared's error (PyShoe's script): not reported as amvd's.
    assert set(rec.meta["trial_error_m"]) == {"shoe", "ared", "mbgtd", "vicon"}
    assert rec.meta["zv_thresholds"] == {"shoe": 2.5e6}


def test_gz_is_read(tmp_path):
    p = _write(tmp_path, _trial())
    gz = tmp_path / "trial.mat.gz"
    gz.write_bytes(gzip.compress(p.read_bytes()))
    assert pyshoe.sniff(gz)
    assert pyshoe.read(gz) == pyshoe.read(p)


@pytest.mark.parametrize(("over", "field", "match"), [
    ({"imu": np.zeros((400, 5))}, "imu", "Nx6"),
    ({"ts": np.arange(399)[None, :] * 0.005}, "ts", "399 timestamps but 400"),
    ({"ts": np.r_[0.0, 0.005, np.arange(1, 7) * 6e-4, 0.02 + np.arange(392) * 0.005][None, :]}, "ts[2]",
     "backwards in 6 of 400"),
    ({"imu": np.r_[np.zeros((10, 6)), np.full((1, 6), np.nan), np.zeros((389, 6))]}, "imu", "row 11 is not finite"),
    ({"gt": np.zeros((10, 3))}, "gt", "10 VICON rows"),
    ({"imu": np.full((400, 6), "x")}, "imu", "not a numeric"),
])
def test_bad_trial_names_variable(tmp_path, over, field, match):
    p = _write(tmp_path, _trial(**over))
    with pytest.raises(InputError, match=match) as err:
        pyshoe.read(p)
    assert err.value.field == field and err.value.source == str(p)


def test_garbage_and_foreign_files(tmp_path):
    g = tmp_path / "g.mat"
    g.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(range(256)) * 4)
    assert not pyshoe.sniff(g)
    with pytest.raises(InputError, match="not a readable MATLAB"):
        pyshoe.read(g)
    empty = tmp_path / "e.mat"
    empty.write_bytes(b"")
    assert not pyshoe.sniff(empty)
    with pytest.raises(InputError, match="e.mat"):
        pyshoe.read(empty)
    other = _write(tmp_path, {"GCP_meters": np.zeros((3, 2))}, "other.mat")
    assert not pyshoe.sniff(other)
    with pytest.raises(InputError, match="missing variable 'imu'"):
        pyshoe.read(other)
    assert not pyshoe.sniff(tmp_path)


@pytest.mark.data
def test_real_trial():
    p = data_path("pyshoe_vicon", "2017-11-22-11-22-03.mat")
    rec = pyshoe.read(p)
    assert rec.format == "pyshoe"
    assert rec.stream("acc").median_rate_hz() == pytest.approx(200.0, rel=1e-3)
    assert len(rec.stream("gyro")) == 6490
    assert rec.duration_s == pytest.approx(32.44, abs=0.01)
    acc = rec.values("acc")
    assert np.linalg.norm(acc[:100], axis=1).mean() == pytest.approx(9.8, abs=0.1)  # standing still at the start
    pos = rec.truth.positions
    assert pos is not None and len(pos) == 6490
    # the foot moves over the VICON area (metres), not millimetres or kilometres
    span = np.ptp(pos.pos_m[:, :2], axis=0).max()
    assert 1.0 < span < 10.0
    zv = rec.truth.extra["zero_velocity"]
    assert rec.meta["best_detector"] == "shoe"
    assert 0.2 < zv.mean() < 0.9
    # stance (zero velocity) really is where VICON shows the foot at rest
    speed = np.linalg.norm(np.gradient(pos.pos_m, pos.t_s, axis=0), axis=1)
    assert np.median(speed[zv]) < 0.1 < np.median(speed[~zv])
    assert rec.meta["best_error_m"] == pytest.approx(0.032)
    assert detect_or_skip(p) == "pyshoe"


@pytest.mark.data
def test_all_real_trials_are_detected():
    folder = data_path("pyshoe_vicon")
    files = sorted(folder.glob("*.mat"))
    assert files
    for f in files:
        assert pyshoe.sniff(f), f


def test_vicon_positions_are_mirrored_into_a_right_handed_frame(tmp_path):
    d = _trial()
    n = d["gt"].shape[0]
    d["gt"] = np.column_stack([np.full(n, 1.0), np.full(n, 2.0), np.full(n, 3.0)])
    rec = pyshoe.read(_write(tmp_path, d))
    assert rec.truth.positions is not None
    np.testing.assert_array_equal(rec.truth.positions.pos_m[0], [1.0, -2.0, 3.0])


def test_a_trial_cut_short_is_named_unreadable_not_an_unsupported_format(tmp_path):
    """A .mat copy cut short (inside its first variable: the sniffer lists no imu and ts) was 'not a supported log
    format ...; pass --format to force one'; it is now the damaged MATLAB file it is."""
    from pdr.io import read_recording

    whole = _write(tmp_path, _trial())
    cut = tmp_path / "cut.mat"
    cut.write_bytes(whole.read_bytes()[:2000])                  # inside the first variable, imu
    with pytest.raises(InputError, match=r"not a readable MATLAB \.mat file") as err:
        read_recording(cut)
    assert err.value.source == str(cut)
    assert detect_or_skip(whole) == "pyshoe"
