"""``pdr site from-ms|check`` and ``pdr track --site --start`` (map matching) on the MS floor folders."""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from pdr.cli import main
from pdr.cli import site as site_cli
from pdr.errors import InputError
from tests.conftest import data_path


def site_command(argv: list[str]) -> int:
    """The ``site`` command's parser alone (its entry point appears once the package metadata is reinstalled)."""
    p = argparse.ArgumentParser(prog="pdr")
    site_cli.register(p.add_subparsers(dest="command"))
    args = p.parse_args(["site", *argv])
    return int(args.func(args))


@pytest.mark.data
def test_from_ms_writes_a_site_that_checks_and_draws(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    floor = data_path("ms_indoor_location", "site2", "F4")
    out, png, pts = tmp_path / "f4.json", tmp_path / "f4.png", tmp_path / "pts.json"
    assert site_command(["from-ms", str(floor), "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert [f["floor"] for f in doc["floors"]] == [4]
    from pdr.io import read_recording
    truth = read_recording(sorted((floor / "path_data_files").iterdir())[0]).truth.positions
    assert truth is not None
    pts.write_text(json.dumps([[*truth.pos_m[0, :2].tolist(), 4], [0.5, 0.5, 4]]))
    assert site_command(["check", str(out), "--plot", str(png), "--points", str(pts)]) == 1
    text = capsys.readouterr().out
    assert "point 1 (0.50, 0.50) on floor 4 is outside" in text and "1 of 2 points walkable" in text
    assert site_command(["check", str(out), "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000
    nested = tmp_path / "sites" / "site2" / "f4.json"           # its folder is made (pdr.cli.outputs)
    assert site_command(["from-ms", str(floor), "--out", str(nested)]) == 0
    assert json.loads(nested.read_text()) == doc


def test_check_refuses_a_self_intersecting_site(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"landmarks": [], "floors": [{"floor": 0, "walkable": {
        "type": "Polygon", "coordinates": [[[0, 0], [4, 4], [4, 0], [0, 4], [0, 0]]]}}]}))
    with pytest.raises(InputError, match="ring 0.*intersects itself"):
        site_command(["check", str(bad)])



def test_check_says_where_a_plot_without_an_extension_went(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """``pdr site check S --plot out/p`` wrote out/p.png silently; it now says so."""
    site = tmp_path / "square.json"
    site.write_text(json.dumps({"floors": [{"floor": 0, "walkable": {
        "type": "Polygon", "coordinates": [[[0, 0], [4, 0], [4, 4], [0, 4], [0, 0]]]}}]}))
    plot = tmp_path / "p"
    assert site_command(["check", str(site), "--plot", str(plot)]) == 0
    assert f"note: --plot {plot} has no extension: the PNG is written to {plot}.png" in capsys.readouterr().err
    assert Path(f"{plot}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

@pytest.mark.data
def test_track_with_a_floor_plan_and_a_known_start(tmp_path: Path) -> None:
    from pdr.io import read_recording
    from pdr.site.ms import site_from_ms_floor
    floor = data_path("ms_indoor_location", "site2", "F3")
    trace = sorted((floor / "path_data_files").iterdir())[3]
    site = tmp_path / "f3.json"
    site.write_text(json.dumps(site_from_ms_floor(floor)))
    truth = read_recording(trace).truth.positions
    assert truth is not None
    e, n = truth.pos_m[0, :2]
    out = tmp_path / "t.csv"
    assert main(["track", str(trace), "--site", str(site), "--start", f"{e},{n}", "--out", str(out)]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    xy = np.array([[float(r["east_m"]), float(r["north_m"])] for r in rows])
    assert len(rows) > 10 and {r["floor"] for r in rows} == {"3"}
    assert np.linalg.norm(xy[0] - [e, n]) < 2.0             # in the site's frame, from the start
    # Causal: the map matcher runs online as a pipeline stage (pdr.mapmatch.stage).
    assert main(["track", str(trace), "--site", str(site), "--start", f"{e},{n}", "--smoother", "off",
                 "--out", str(out)]) == 0
    with out.open() as fh:
        online = list(csv.DictReader(fh))
    assert len(online) == len(rows) and {r["floor"] for r in online} == {"3"}
    # a start inside a shop, a start without a floor plan and a malformed start are refused (exit code 2)
    assert main(["track", str(trace), "--site", str(site), "--start", "0.5,0.5", "--out", str(out)]) == 2
    assert main(["track", str(trace), "--start", f"{e},{n}", "--out", str(out)]) == 2
    assert main(["track", str(trace), "--site", str(site), "--start", "a,b", "--out", str(out)]) == 2
    assert main(["track", str(trace), "--site", str(site), "--start", f"{e},{n},7", "--out", str(out)]) == 2


@pytest.mark.data
def test_eval_ms_map_scores_absolutely_from_the_first_waypoint(capsys: pytest.CaptureFixture[str]) -> None:
    floor = data_path("ms_indoor_location", "site2", "F3")
    assert main(["eval", "ms", str(floor), "--map", "--limit", "2", "--json",
                 "--map-config", '{"particles": 300}']) == 0
    res = json.loads(capsys.readouterr().out)
    m = res["overall"]["map"]
    assert m["traces"] == 2 and m["speed"]["particles"] == 300 and m["speed"]["steps"] > 20
    for name in ("pdr", "online", "smoothed", "hindsight"):
        # (the pooled p75 may exceed every trace's own p75: a few large errors of each trace pool into the top 25 %)
        assert 0 < m[name]["median_m"] <= m[name]["p75_m"] < 50 and 0 < m[name]["worst_p75_m"] < 50
    assert main(["eval", "ms", str(floor), "--map", "--map-config", '{"walls": 1}']) == 2


@pytest.mark.data
def test_eval_ms_calibrates_each_trace_on_the_other_floors(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    # Two F3 traces and one F4 trace (each floor folder with its plan): every trace's K comes from the other floor.
    picks = {"F3": ["5dd398d727889b0006b76b8d.txt.gz", "5dd51c0350e04e0006f56442.txt.gz"],
             "F4": ["5dd5205350e04e0006f5645c.txt.gz"]}
    for floor, names in picks.items():
        src = data_path("ms_indoor_location", "site2", floor)
        (tmp_path / floor / "path_data_files").mkdir(parents=True)
        for f in ("geojson_map.json", "floor_info.json"):
            (tmp_path / floor / f).symlink_to(src / f)
        for n in names:
            (tmp_path / floor / "path_data_files" / n).symlink_to(src / "path_data_files" / n)
    assert main(["eval", "ms", str(tmp_path), "--map", "--calibrate", "cross", "--json",
                 "--map-config", '{"particles": 200}']) == 0
    res = json.loads(capsys.readouterr().out)
    c = res["overall"]["calibrated"]
    assert c["mode"] == "cross" and c["traces"] == 3 and c["without_calibration_walk"] == 0
    assert c["map"]["traces"] == 3 and 0 < c["map"]["online"]["p75_m"] < 50
    per = {p["file"]: p["calibrated"] for p in res["files"]}
    assert per[picks["F4"][0]]["calibrated_on"] == 2 and per[picks["F3"][0]]["calibrated_on"] == 1
    assert per[picks["F3"][0]]["k"] == per[picks["F3"][1]]["k"] != per[picks["F4"][0]]["k"]
    assert main(["eval", "ms", str(tmp_path), "--map", "--calibrate", "cross",
                 "--map-config", '{"particles": 200}']) == 0
    text = capsys.readouterr().out
    for line in ("CALIBRATED --calibrate cross (K on the other floors'", "MAP online CALIBRATED --calibrate cross (3",
                 "MAP bound:", "| F3 (2): median"):
        assert line in text


@pytest.mark.data
@pytest.mark.slow
def test_bench_phone_times_the_map_matching_stage_on_a_site(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``pdr bench phone --site SITE --start E,N`` (it failed with a NameError: the site's plan class was imported
    for type checking only)."""
    from pdr.io import read_recording
    from pdr.site.ms import site_from_ms_floor
    floor = data_path("ms_indoor_location", "site2", "F3")
    site = tmp_path / "f3.json"
    site.write_text(json.dumps(site_from_ms_floor(floor)))
    truth = read_recording(sorted((floor / "path_data_files").iterdir())[3]).truth.positions
    assert truth is not None
    e, n = truth.pos_m[0, :2]
    assert main(["bench", "phone", "--duration", "30", "--site", str(site), "--start", f"{e},{n}", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["map"]["stage_steps"] > 0
