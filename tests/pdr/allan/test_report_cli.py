import base64
import json
import re

import numpy as np
import pytest

from pdr.allan import synthetic as sy
from pdr.allan.characterise import Settings, characterise_recording, characterise_samples
from pdr.allan.report import comparison_dict, report_dict, write_report
from pdr.cli import main
from pdr.errors import InputError
from pdr.recording import DeviceInfo, Recording, SensorStream

FS = 100.0
COLUMNS = np.array(["Gyro. X", "Gyro. Y", "Gyro. Z", "Accel. X", "Accel. Y", "Accel. Z"])


def _imu(n, seed, turn_at=None):
    rng = np.random.default_rng(seed)
    gyro = np.column_stack([sy.white_noise(n, FS, 1e-3, rng) + sy.random_walk(n, FS, 1e-4, rng)
                            + sy.flicker_noise(n, FS, 5e-4, rng) + 0.01 for _ in range(3)])
    acc = np.column_stack([sy.white_noise(n, FS, 2e-3, rng) + sy.flicker_noise(n, FS, 5e-4, rng) for _ in range(3)])
    acc[:, 2] += 9.81
    if turn_at is not None:
        gyro[turn_at:turn_at + 200, 2] += 1.0
    return gyro, acc


def _write_npz(path, n=30_000, seed=0, turn_at=None):
    gyro, acc = _imu(n, seed, turn_at)
    np.savez(path, data=np.column_stack([gyro, acc]), columns=COLUMNS, fs=FS)
    return path


def _recording(n=30_000, seed=0, with_temperature=True):
    gyro, acc = _imu(n, seed)
    t = np.round(np.arange(n) / FS * 1e9).astype(np.int64)
    streams = {"gyro": SensorStream("gyro", t, gyro), "acc": SensorStream("acc", t, acc)}
    if with_temperature:
        streams["temperature"] = SensorStream("temperature", t[::100], 25 + np.linspace(0, 1, t[::100].size))
    return Recording(streams, device=DeviceInfo(platform="imu", model="sim"), source="sim.npz", format="test")


def test_report_json_has_every_axis_term_and_nulls_for_unresolved(tmp_path):
    res = characterise_recording(_recording(), settings=Settings(extra_estimators=("nonoverlapping", "modified")))
    paths = write_report(res, tmp_path)
    data = json.loads(paths["json"].read_text())
    assert data["schema"] == "pdr.allan.report/1"
    for s in ("gyro", "acc"):
        for a in ("x", "y", "z"):
            ax = data[s][a]
            assert len(ax["tau_s"]) == len(ax["adev"]) == len(ax["adev_lo"]) == len(ax["adev_hi"])
            assert all(lo <= v <= hi for lo, v, hi in zip(ax["adev_lo"], ax["adev"], ax["adev_hi"], strict=True))
            assert set("QNBKR") <= set(ax)
            for k in "QNBKR":
                assert (ax[k] is None) == (not ax["fit"]["resolved"][k])
                if ax[k] is None:
                    assert ax["fit"]["reason"][k] and ax["fit"]["upper_bound"][k] > 0
            assert "adev_nonoverlapping" in ax and "adev_modified" in ax
    # a 5-minute record shows white noise but cannot resolve the random walk
    assert data["gyro"]["z"]["N"] == pytest.approx(1e-3, rel=0.1)
    assert data["gyro"]["z"]["K"] is None and "too short" in data["gyro"]["z"]["fit"]["reason"]["K"]
    # change = mean of the last minute - mean of the first minute of a 0 -> 1 degC ramp over 5 min
    assert data["recording"]["temperature"]["change_degC"] == pytest.approx(0.8, abs=0.01)
    assert data["gyro"]["pdr_impact"]["axes"]["z"]["time_to_3deg_s"] > 0
    assert data["gyro"]["grade"]["overall"] in ("navigation", "tactical", "consumer", "below consumer")


def test_html_is_self_contained_with_embedded_plots(tmp_path):
    paths = write_report(characterise_recording(_recording(with_temperature=False)), tmp_path)
    html = paths["html"].read_text()
    imgs = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)
    assert len(imgs) == 2 and all(base64.b64decode(i).startswith(b"\x89PNG") for i in imgs)
    assert "http://" not in html and "https://" not in html and "<link" not in html
    assert "not recorded" in html and "Table 3" in html
    assert paths["png_gyro"].read_bytes().startswith(b"\x89PNG")
    yaml = paths["yaml"].read_text()
    assert "gyroscope_noise_density:" in yaml and "accelerometer_random_walk:" in yaml


def test_stuck_axis_and_axis_names_are_errors():
    y = np.zeros((5000, 2))
    y[:, 0] = np.random.default_rng(0).standard_normal(5000)
    with pytest.raises(InputError, match="axis y is constant"):
        characterise_samples(y, FS, "gyro", axis_names=("x", "y"))
    with pytest.raises(InputError, match="3 axis names"):
        characterise_samples(y, FS, "gyro")
    with pytest.raises(InputError, match="unknown axes"):
        characterise_recording(_recording(n=3000), axes=("w",))
    with pytest.raises(InputError, match="no 'mag' stream|none of the streams"):
        characterise_recording(_recording(n=3000), sensors=("mag",))


def test_comparison_reports_spread():
    reports = [report_dict(characterise_recording(_recording(seed=s), sensors=("gyro",))) for s in (1, 2, 3)]
    comp = comparison_dict(reports)
    row = comp["sensors"]["gyro"]["x"]["N"]
    assert row["n_resolved"] == 3 and row["cv_pct"] < 10 and row["mean"] == pytest.approx(1e-3, rel=0.1)


def test_cli_writes_report_and_comparison(tmp_path, capsys):
    a = _write_npz(tmp_path / "unit_a.npz", seed=1)
    b = _write_npz(tmp_path / "unit_b.npz", seed=2)
    out = tmp_path / "rep"
    assert main(["allan", str(a), str(b), "--out", str(out), "--sensor", "gyro", "--axis", "z"]) == 0
    data = json.loads((out / "unit_a.npz" / "report.json").read_text())
    assert "acc" not in data and set(data["gyro"]) >= {"z"} and "x" not in data["gyro"]
    comp = json.loads((out / "comparison.json").read_text())
    assert comp["sensors"]["gyro"]["z"]["N"]["n_resolved"] == 2
    text = capsys.readouterr().out
    assert "grade" in text and "spread across units" in text


def test_cli_flags_motion(tmp_path, capsys):
    log = _write_npz(tmp_path / "moved.npz", turn_at=15_000)
    assert main(["allan", str(log), "--out", str(tmp_path / "r")]) == 0
    data = json.loads((tmp_path / "r" / "report.json").read_text())
    assert any("motion detected" in f for f in data["flags"])
    assert main(["allan", str(log), "--out", str(tmp_path / "r2"), "--motion", "error"]) == 2
    assert "motion detected" in capsys.readouterr().err


def test_cli_bad_input(tmp_path, capsys):
    assert main(["allan", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "r")]) == 2
    assert "no such file" in capsys.readouterr().err
    log = _write_npz(tmp_path / "short.npz", n=3000)
    assert main(["allan", str(log), "--out", str(tmp_path / "r"), "--tau-max", "100"]) == 2
    assert "too short for tau = 100 s" in capsys.readouterr().err



@pytest.mark.parametrize(("option", "value", "match"), [
    ("--tau-min", "-1", "must be a positive number"), ("--tau-min", "0", "must be a positive number"),
    ("--tau-min", "nan", "must be a positive number"), ("--tau-max", "-1", "must be a positive number"),
    ("--taus-per-decade", "0", "must be a positive number"), ("--confidence", "1", "must be a number between 0 and 1"),
    ("--disagreement", "-0.1", "must be a number >= 0"), ("--scale-factor-error", "inf", "must be a finite number"),
    ("--step-length", "0", "must be a positive number"), ("--step-rate", "-2", "must be a positive number"),
])
def test_cli_refuses_invalid_numeric_options_naming_them(tmp_path, capsys, option, value, match):
    """``--tau-min -1`` was taken (``nan`` even ended in a traceback), others were refused only after reading the log,
    naming an internal field ('per_decade') or the log instead of the option."""
    log = _write_npz(tmp_path / "short.npz", n=3000)
    with pytest.raises(SystemExit) as exit_:
        main(["allan", str(log), "--out", str(tmp_path / "r"), option, value])
    assert exit_.value.code == 2
    assert f"argument {option}: {match}" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_cli_refuses_tau_min_above_tau_max_naming_the_options(tmp_path, capsys):
    """It said "field 'tau_min_s': no averaging time between 0.3 s and 0.1 s for this record", naming the log."""
    log = _write_npz(tmp_path / "short.npz", n=3000)
    assert main(["allan", str(log), "--out", str(tmp_path / "r"), "--tau-min", "0.3", "--tau-max", "0.1"]) == 2
    assert "'--tau-min': 0.3 s is above --tau-max 0.1 s" in capsys.readouterr().err


def test_cli_error_of_one_of_several_logs_names_that_log(tmp_path, capsys):
    """With several LOGs, a record the analysis refuses (3 samples) is named: it said only "error: stream 'gyro':
    has 3 samples; ..." after the first log's report."""
    good = _write_npz(tmp_path / "good.npz", n=3000)
    tiny = _write_npz(tmp_path / "tiny.npz", n=3)
    assert main(["allan", str(good), str(tiny), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {tiny}, stream 'gyro': has 3 samples"), err


def test_html_names_the_file_the_axes_and_the_paper(tmp_path):
    """A report read from a temporary copy shows only the file name; each grade row names its axis; the grade
    table cites the paper (not the project's seed number); a lab IMU is not called a phone."""
    rec = Recording(_recording(with_temperature=False).streams, device=DeviceInfo(platform="imu", model="ADIS16465"),
                    source="/tmp/pdr-upload-rpfql2fy/static.npz", format="test")
    assert rec.device.role == "phone"  # the reader's default
    res = characterise_recording(rec)
    paths = write_report(res, tmp_path)
    html = paths["html"].read_text()
    data = json.loads(paths["json"].read_text())
    assert "pdr-upload" not in html and "<h1>Allan-variance report: static.npz</h1>" in html
    assert data["recording"]["device"]["role"] == "standalone IMU" and "role=phone" not in html
    calls = data["gyro"]["grade"]["calls"]
    assert [c["axis"] for c in calls] == ["x", "x", "y", "y", "z", "z"]
    assert [c["parameter"] for c in calls[:2]] == ["bias_instability", "angular_random_walk"]
    rows = re.findall(r'<tr><td class="l">([xyz])</td><td class="l">(bias instability|angular random walk)</td>', html)
    assert rows == [(c["axis"], c["parameter"].replace("_", " ")) for c in calls]
    assert "seed 004" not in html and "Collin et al. (2019), Table 1" in html
    assert "Handbook of Signal Processing Systems" in html
    assert "Handbook of Signal" in data["gyro"]["grade"]["reference"]


def test_slope_readings_beyond_a_short_record_say_they_are_extrapolated():
    """A 2 s record (longest tau 0.5 s) flagged a "slope reading (+1/2 line at 3 s)" and "(-1/2 line at 1 s)" as if
    read on the curve: they are the lines through a point at tau <= 0.5 s extended to 3 s and 1 s."""
    rng = np.random.default_rng(4)
    gyro = np.column_stack([sy.white_noise(200, FS, 1e-3, rng) + sy.random_walk(200, FS, 1e-2, rng) for _ in range(3)])
    res = characterise_samples(gyro, FS, "gyro")
    assert res.curve.tau_s[-1] < 1.0
    flags = [d for ax in res.axes.values() for d in ax.disagreements]
    assert not [f for f in flags if "line at" in f], flags
    k = [f for f in flags if f.startswith("K: slope reading")]
    assert k and all(re.search(r"\(\+1/2 line through tau 0\.[0-9]+ s extrapolated to 3 s: the record is too short to "
                               r"read it there\) ", f) for f in k), k
