import json

from pdr.cli import main


def test_eval_coop_json_has_the_issue_keys(capsys):
    code = main(["eval", "coop", "--json", "--runs", "2", "--agents", "1,2", "--duration", "12",
                 "--static-duration", "12", "--cost-agents", "2", "--cost-duration", "4"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["march"]["rmse_by_agents"]) == {"1", "2"}
    assert isinstance(out["march"]["exponent"], float)
    assert out["static"]["max_rmse_m"] > 0
    assert set(out["march"]["correlation"]) >= {"distance_m", "x_mc", "y_mc", "z_mc", "x_filter"}
    assert out["cost"]["2"]["downlink_values_per_s"] == 8.0


def test_eval_coop_rejects_bad_group_sizes(capsys):
    assert main(["eval", "coop", "--agents", "0,2", "--no-cost"]) == 2
    assert "--agents" in capsys.readouterr().err


def test_eval_coop_rejects_no_workers(capsys):
    assert main(["eval", "coop", "--workers", "0", "--no-cost"]) == 2
    assert "--workers" in capsys.readouterr().err
