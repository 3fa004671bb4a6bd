"""``pdr eval coop --real``: simulate-then-recover on a march, and the real PyShoe group (data)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pdr.cli import main
from pdr.errors import InputError
from pdr.evaluation.coop_real import RealAgent, RealCoopResult, real_coop_experiment
from pdr.fusion.ranging import RangeModel
from pdr.fusion.simulation import SimulationConfig, StepEvent, march_scenario
from pdr.fusion.state import FootKey
from tests.conftest import data_path


def march_agents(n: int = 3, duration_s: float = 60.0) -> list[RealAgent]:
    """The left feet of a simulated march as single-foot recordings with their truth."""
    sc = march_scenario(n, duration_s, SimulationConfig(), np.random.default_rng(4))
    out = []
    for a in sc.agents:
        truth = sc.truth[FootKey(a, "left")]
        steps = tuple(e.increment for e in sc.events(False) if isinstance(e, StepEvent) and e.agent == a
                      and e.foot == "left")
        out.append(RealAgent(a, 0.0, steps, truth.t_s, truth.pos_n))
    return out


def test_ranges_help_every_agent_of_a_march_and_share_one_agents_drift():
    """Simulate then recover: three marchers with the seed's step errors. Ranges between the reset positions
    lower every agent's RMSE (seed 001 Sec. 5.1: the group averages its heading errors). One agent drifting
    3 deg/step: the ranges pull it part of the way back and pull the others off, as ranges alone (no anchor)
    only fix the group's shape, not where it is (issue 32 saw the same on real walks)."""
    agents = march_agents()
    def experiment(biased_agent: int = -1, bias_deg_per_step: float = 0.0) -> RealCoopResult:
        return real_coop_experiment(agents, 3, 0, RangeModel(0.1, 0.1), "gaussian", 0.05, 0.0, biased_agent,
                                    bias_deg_per_step, step_heading_sigma_deg=1.0, at_resets=True)

    plain = experiment()
    assert plain.helped == [True, True, True] and plain.steps == (60, 60, 60) and plain.ranges == 59
    assert np.all(plain.rmse_group_m < 0.6 * plain.rmse_dead_reckoning_m)
    biased = experiment(0, 3.0)
    assert biased.rmse_dead_reckoning_m[0] > 10 * plain.rmse_dead_reckoning_m[0]
    assert biased.rmse_group_m[0] < 0.7 * biased.rmse_dead_reckoning_m[0]
    assert biased.helped == [True, False, False]
    # The other agents' dead reckoning does not depend on agent 0's drift.
    np.testing.assert_allclose(biased.rmse_dead_reckoning_m[1:], plain.rmse_dead_reckoning_m[1:])


def test_bad_conditions_are_refused():
    agents = march_agents(2, 10.0)
    with pytest.raises(InputError, match="two or more"):
        real_coop_experiment(agents[:1])
    with pytest.raises(InputError, match="out of range"):
        real_coop_experiment(agents, biased_agent=2)
    with pytest.raises(InputError, match="cauchy or gaussian"):
        real_coop_experiment(agents, noise="uniform")


@pytest.mark.data
@pytest.mark.slow
def test_eval_coop_real_on_pyshoe_trials(capsys):
    root = data_path("pyshoe_vicon")
    code = main(["eval", "coop", "--real", "--json", "--runs", "2", "--data", str(root),
                 "--trials", "2017-11-27-11-18-11,2017-11-22-11-35-59"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["agents"] == ["2017-11-27-11-18-11", "2017-11-22-11-35-59"] and "VICON" in out["protocol"]
    assert len(out["conditions"]) == 12
    for c in out["conditions"]:
        assert set(c["rmse_group_m"]) == set(out["agents"]) and all(v > 0 for v in c["rmse_group_m"].values())
    drifting = [c for c in out["conditions"] if c["biased_agent"]]
    assert all(c["rmse_dead_reckoning_m"]["2017-11-27-11-18-11"] > 0.5 for c in drifting)
    assert main(["eval", "coop", "--real", "--data", str(root), "--trials", "nope"]) == 2
