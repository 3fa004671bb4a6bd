"""``pdr bench track``: the tiled log and the per-stage timing of the whole ``pdr track`` path."""

from __future__ import annotations

import numpy as np
import pytest

from pdr.cli import main
from pdr.errors import InputError
from pdr.evaluation import track_bench as bench_track
from pdr.io import ipin
from tests.conftest import data_path

LOG = """% LogFile created by the 'GetSensorData' App for Android.
% Model:                   \tSM-TEST
ACCE;0.050;100.0000;0.10000;0.20000;9.80000;3
GYRO;0.052;100.0010;0.01000;0.02000;0.03000;3
WIFI;0.06;100.1;net;00:11;2412;-60;
ACCE;0.070;100.0200;0.10000;0.20000;9.81000;3
GYRO;0.072;100.0110;0.01000;0.02000;0.03000;3
POSI;0.080;1;49.4611;11.1110;0;100
"""


def test_tiled_log_repeats_the_samples_with_increasing_clocks(tmp_path) -> None:
    src = tmp_path / "walk.txt"
    src.write_text(LOG)
    one = ipin.read(src)
    tiled = ipin.read(bench_track.tile_ipin_log(src, 3, tmp_path / "tiled.txt"))
    for kind in ("acc", "gyro"):
        a, b = one.stream(kind), tiled.stream(kind)
        assert len(b) == 3 * len(a)
        assert np.array_equal(b.values, np.tile(a.values, (3, 1)))
        assert np.all(np.diff(b.t_ns) > 0)
    period_s = (tiled.stream("acc").t_ns[2] - tiled.stream("acc").t_ns[0]) / 1e9
    assert period_s == pytest.approx(2.0, abs=1e-6)     # a 0.02 s log: ceil(0.02 + 1) s
    assert tiled.meta["ignored_records"] == {"WIFI": 3}
    assert tiled.truth.positions is not None and len(tiled.truth.positions) == 3


def test_tiling_refuses_no_copies(tmp_path) -> None:
    src = tmp_path / "walk.txt"
    src.write_text(LOG)
    with pytest.raises(ValueError, match="copies must be at least 1"):
        bench_track.tile_ipin_log(src, 0, tmp_path / "x.txt")


@pytest.mark.data
def test_stage_times_add_up_to_the_track_the_cli_writes(tmp_path) -> None:
    log = data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial21_repetition01.txt")
    res = bench_track.time_track(log, tmp_path / "bench.csv")
    assert set(res["stages_s"]) == set(bench_track.STAGES)
    assert all(v >= 0 for v in res["stages_s"].values())
    assert sum(res["stages_s"].values()) <= res["total_s"] * 1.001
    assert set(res["stages_cpu_s"]) == set(bench_track.STAGES)
    assert all(v >= -1e-3 for v in res["stages_cpu_s"].values())      # "other" is a difference of CPU clocks
    assert 0 < sum(res["stages_cpu_s"].values()) <= res["total_cpu_s"] * 1.001 + 1e-3
    assert main(["track", str(log), "--out", str(tmp_path / "cli.csv")]) == 0
    assert (tmp_path / "bench.csv").read_text() == (tmp_path / "cli.csv").read_text()


@pytest.mark.data
def test_ahrs_ekf_reference_runs_on_the_same_samples() -> None:
    pytest.importorskip("ahrs")
    rec = ipin.read(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial21_repetition01.txt"))
    start = rec.time_span_s()[0]
    res = bench_track.time_ahrs_ekf(rec.slice_time(start, start + 20.0))
    assert res is not None and res["samples"] > 500 and res["samples_per_s"] > 0
    from importlib.metadata import version
    assert res["version"] == version("ahrs")     # the reference's release is printed: its speed varies by release


def test_tiling_a_folder_or_a_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(InputError, match="got a folder"):
        bench_track.tile_ipin_log(tmp_path, 2, tmp_path / "out.txt")
    with pytest.raises(InputError, match="no such file"):
        bench_track.tile_ipin_log(tmp_path / "absent.txt", 2, tmp_path / "out.txt")


def test_start_up_processes_run_as_installed_with_their_bytecode_kept_apart(tmp_path, monkeypatch) -> None:
    # The product's processes write their bytecode under the bench's own prefix, not into the checkout, even where
    # the caller's environment forbids bytecode.
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    env = bench_track.process_env(tmp_path / "pycache", tmp_path / "numba")
    assert "PYTHONDONTWRITEBYTECODE" not in env and env["NUMBA_CACHE_DIR"] == str(tmp_path / "numba")
    assert bench_track.time_command(["--help"], env) > 0
    written = list((tmp_path / "pycache").rglob("*.pyc"))
    assert any(p.name.startswith("__init__") and "pdr" in p.parts for p in written)
    with pytest.raises(RuntimeError, match="pdr inspect failed"):
        bench_track.time_command(["inspect", str(tmp_path / "absent.txt")], env)
