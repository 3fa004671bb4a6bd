import json

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.fusion.agent import Agent
from pdr.fusion.simulation import SimulationConfig, StepEvent, march_scenario, start_centre


def scenario():
    return march_scenario(2, 20, SimulationConfig(), np.random.default_rng(4))


def agent_for(sc, name):
    centre = start_centre(sc)
    corr = centre.correction(name)
    a = Agent(name, corr.mean[:3], float(corr.mean[3]), None, 0.0,
              [corr.mean[0:3] - corr.mean[0:3], corr.mean[4:7] - corr.mean[0:3]])
    return centre, a


def test_local_estimate_equals_the_centre_without_other_information():
    sc = scenario()
    centre, a0 = agent_for(sc, "a0")
    for ev in sc.steps:
        centre.apply_step(ev.agent, ev.foot, ev.increment)
        if ev.agent == "a0":
            a0.step(ev.foot, ev.increment)
    np.testing.assert_allclose(a0.estimate().mean, centre.correction("a0").mean, atol=1e-12)
    np.testing.assert_allclose(a0.estimate().cov, centre.correction("a0").cov, atol=1e-12)


def test_correction_is_adopted_and_unseen_steps_are_replayed():
    sc = scenario()
    centre, a0 = agent_for(sc, "a0")
    events = [e for e in sc.events() if e.t_s <= 12]
    late = [e for e in sc.steps if 12 < e.t_s <= 16 and e.agent == "a0"]
    for ev in events:
        if isinstance(ev, StepEvent):
            centre.apply_step(ev.agent, ev.foot, ev.increment)
            if ev.agent == "a0":
                a0.step(ev.foot, ev.increment)
        else:
            centre.apply_range(ev.agent_a, ev.agent_b, ev.measured_m)
    for ev in late:                                    # the agent walks on; the centre has not seen these yet
        a0.step(ev.foot, ev.increment)
    assert len(a0.take_outbox()) == 12 * 2 + len(late) and a0.take_outbox() == []
    assert a0.apply_correction(centre.correction("a0"))
    for ev in late:
        centre.apply_step(ev.agent, ev.foot, ev.increment)
    np.testing.assert_allclose(a0.estimate().mean, centre.correction("a0").mean, atol=1e-9)
    np.testing.assert_allclose(a0.estimate().cov, centre.correction("a0").cov, atol=1e-9)


def test_stale_and_foreign_corrections():
    sc = scenario()
    centre, a0 = agent_for(sc, "a0")
    old = centre.correction("a0")
    for ev in [e for e in sc.steps if e.agent == "a0"][:4]:
        centre.apply_step(ev.agent, ev.foot, ev.increment)
        a0.step(ev.foot, ev.increment)
    assert a0.apply_correction(centre.correction("a0"))
    assert not a0.apply_correction(old)                # older than what the agent already adopted
    with pytest.raises(InputError, match="does not fit"):
        a0.apply_correction(centre.correction("a1"))
    restored = Agent.from_dict(json.loads(json.dumps(a0.to_dict())))
    np.testing.assert_array_equal(restored.estimate().mean, a0.estimate().mean)
    ahead = centre.correction("a0")
    fresh = agent_for(sc, "a0")[1]
    with pytest.raises(InputError, match="never made"):
        fresh.apply_correction(ahead)
