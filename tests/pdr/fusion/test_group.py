import json

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.fusion.group import Group, StaleRangeError
from pdr.fusion.measurements import HeightDifference, InterAgentRange, StepSummary, event_to_dict, parse_event
from pdr.fusion.simulation import SimulationConfig, StepEvent, march_scenario, run_scenario
from pdr.fusion.state import FootKey


def setup(n=3, duration=40, seed=5):
    sc = march_scenario(n, duration, SimulationConfig(), np.random.default_rng(seed))
    g = Group(contact_timeout_s=5.0, max_range_age_s=2.0)
    for a in sc.agents:
        left = sc.truth[FootKey(a, "left")].pos_n[0]
        right = sc.truth[FootKey(a, "right")].pos_n[0]
        g.join(a, left, 0.0, None, 0.0, [[0, 0, 0], right - left])
    return sc, g


def as_events(sc, ranging=True):
    out: list[StepSummary | InterAgentRange] = []
    for e in sc.events(ranging):
        if isinstance(e, StepEvent):
            out.append(StepSummary(e.agent, e.foot, e.increment))
        else:
            out.append(InterAgentRange(e.t_s, e.agent_a, e.agent_b, e.measured_m))
    return out


def test_uploads_in_any_order_give_the_time_ordered_result():
    sc, g = setup()
    events = as_events(sc)
    by_agent = {a: [e for e in events if e.agents[0] == a] for a in sc.agents}
    for chunk in range(0, 41, 5):                      # each agent uploads 5 s batches, agents in reverse order
        for a in reversed(sc.agents):
            g.submit([e for e in by_agent[a] if chunk <= e.t_s < chunk + 5])
        g.process()
    g.process(flush=True)
    reference = run_scenario(sc)
    np.testing.assert_allclose(g.centre.state.mean, reference.centre.state.mean, atol=1e-9)
    assert g.counts["stale_ranges"] == 0 and g.pending == 0
    track = g.track("a1")
    assert track["left"].shape == (41, 5) and np.all(np.diff(track["left"][:, 0]) > 0)


def test_watermark_waits_for_agents_in_contact_only():
    sc, g = setup()
    events = as_events(sc, ranging=False)
    g.submit([e for e in events if e.t_s <= 20 and e.agents[0] != "a2"])
    g.submit([e for e in events if e.t_s <= 3 and e.agents[0] == "a2"])
    assert not g.in_contact("a2") and g.watermark() == pytest.approx(20.0)
    g.process()
    assert g.pending == 0
    g.submit([e for e in events if e.t_s <= 2.5 and e.agents[0] != "a2"])   # a resend is ignored
    assert g.counts["duplicates"] > 0


def test_agent_returning_after_contact_loss_is_merged_in_time_order():
    sc, g = setup()
    events = as_events(sc)
    out = [e for e in events if "a2" in e.agents and 5 < e.t_s <= 30]   # a2's radio is out of contact too
    lost = [e for e in out if isinstance(e, StepSummary)]
    others = [e for e in events if e not in out]
    g.submit([e for e in others if e.t_s <= 30])
    g.process()
    assert not g.in_contact("a2")
    applied_before = g.counts["applied"]
    late_ranges = [InterAgentRange(e.t_s, "a2", next(a for a in e.agents if a != "a2"), e.range_m)
                   for e in out if isinstance(e, InterAgentRange)]    # as a2 measured them meanwhile
    with pytest.raises(StaleRangeError, match="older than the fusion horizon of agent 'a[01]'") as info:
        g.submit(lost + late_ranges)                   # the ranges it measured meanwhile relate states now gone
    # the others' states are at 30 s: every range before 28 s (max_range_age_s 2 s) is refused, the rest not
    assert info.value.events == [len(lost) + k for k, e in enumerate(late_ranges) if e.t_s < 28.0]
    assert g.pending == 0 and g.counts["applied"] == applied_before      # nothing of the refused batch kept
    g.submit(lost)                                     # contact restored: the buffered summaries arrive
    g.submit([e for e in others if e.t_s > 30])
    g.process(flush=True)
    assert g.pending == 0 and g.counts["applied"] > applied_before and g.counts["stale_ranges"] == 0
    steps = g.centre.state.steps
    assert np.all(steps == steps[0])                   # every foot of every agent got all its steps
    reference = run_scenario(sc, ranging=False)
    err = np.linalg.norm(g.centre.state.position(FootKey("a2", "left"))
                         - sc.truth[FootKey("a2", "left")].pos_n[-1])
    err_dr = np.linalg.norm(reference.error[FootKey("a2", "left")][-1])
    assert err < err_dr + 1.0                          # merged, and no worse than dead reckoning alone


def test_whole_walk_uploads_refuse_ranges_the_group_cannot_wait_for():
    """Issue 32: each agent uploading its whole 30 s walk at once; with a contact timeout shorter than the walk
    the first upload's ranges could never be fused (the group does not wait for the silent agent): refused,
    naming them and why. With a longer timeout the same uploads give the time-ordered result, nothing stale."""
    sc = march_scenario(2, 30, SimulationConfig(), np.random.default_rng(3))
    events = as_events(sc)
    for timeout in (10.0, 60.0):
        g = Group(contact_timeout_s=timeout, max_range_age_s=2.0)
        for a in sc.agents:
            left, right = (sc.truth[FootKey(a, f)].pos_n[0] for f in ("left", "right"))
            g.join(a, left, 0.0, None, 0.0, [[0, 0, 0], right - left])
        uploads = {a: [e for e in events if e.agents[0] == a] for a in sc.agents}
        if timeout < 30:
            with pytest.raises(StaleRangeError, match="agent 'a1' has reported only up to 0 s and is out of "
                                                      "contact") as info:
                g.submit(uploads["a0"], reporter="a0")
            ranges = [i for i, e in enumerate(uploads["a0"]) if isinstance(e, InterAgentRange)]
            assert set(info.value.events) <= set(ranges) and len(info.value.events) >= len(ranges) - 12
            assert info.value.details()["events"] == info.value.events and g.pending == 0
            continue
        for a in sc.agents:
            g.submit(uploads[a], reporter=a)
            g.process()
        assert g.pending == 0 and g.counts["stale_ranges"] == 0
        np.testing.assert_allclose(g.centre.state.mean, run_scenario(sc).centre.state.mean, atol=1e-9)


def test_a_range_overtaken_while_waiting_is_dropped_and_listed():
    """A range accepted while both agents were in contact, overtaken by its reporter's steps once the other
    agent falls out of contact: dropped at that moment, with the reason in the answer."""
    sc, g = setup()
    events = as_events(sc, ranging=False)
    g.submit([e for e in events if e.t_s <= 4])
    g.process()
    g.submit([InterAgentRange(7.0, "a0", "a2", 10.0)] + [e for e in events if 4 < e.t_s <= 8 and e.agents[0] == "a0"])
    report = g.process()
    assert report["stale_ranges"] == 0 and g.pending > 0
    g.submit([e for e in events if 6 < e.t_s <= 20 and e.agents[0] != "a2"])
    report = g.process()
    assert report["stale_ranges"] == 1 and report["dropped"][0]["agents"] == ["a0", "a2"]
    assert "fusion horizon of agent 'a0'" in report["dropped"][0]["reason"]


def test_state_round_trip_and_bad_input():
    sc, g = setup(duration=10)
    g.submit([event_to_dict(e) for e in as_events(sc)[:30]])
    restored = Group.from_dict(json.loads(json.dumps(g.to_dict())))
    g.process(flush=True)
    restored.process(flush=True)
    np.testing.assert_array_equal(g.centre.state.mean, restored.centre.state.mean)
    with pytest.raises(InputError, match="not joined"):
        g.submit([{"type": "range", "agent_a": "a0", "agent_b": "zz", "t_s": 1.0, "range_m": 3.0}])
    with pytest.raises(InputError, match="foot must be"):
        g.submit([{"type": "step", "agent": "a0", "foot": "hand", "t_s": 20.0, "dp": [1, 0, 0], "dpsi": 0.0,
                   "cov": np.eye(4).tolist()}])
    with pytest.raises(InputError, match="malformed group"):
        Group.from_dict({"centre": {}})


@pytest.mark.parametrize("obj, field", [
    ({"type": "warp"}, "type"),
    ({"type": "range", "agent_a": "a", "agent_b": "b", "t_s": 1.0}, "range_m"),
    ({"type": "range", "agent_a": "a", "agent_b": "b", "t_s": 1.0, "range_m": -2}, "range_m"),
    ({"type": "range", "agent_a": "a", "agent_b": "a", "t_s": 1.0, "range_m": 2}, "agent_b"),
    ({"type": "range", "agent_a": "a", "agent_b": "b", "t_s": "x", "range_m": 2}, "t_s"),
    ({"type": "range", "agent_a": "a", "agent_b": "b", "t_s": 1, "range_m": 2, "colour": 1}, "colour"),
    ({"type": "step", "agent": "a", "foot": "left", "t_s": 1, "dp": [1, 0], "dpsi": 0, "cov": []}, "dp"),
    ({"type": "step", "agent": "a", "foot": "left", "t_s": 1, "dp": [1, 0, 0], "dpsi": 0, "cov": [[1]]}, "step.cov"),
    ({"type": "position_fix", "agent": "a", "t_s": 1, "pos_n": [1], "gamma_m": 1, "sigma_m": 1}, "pos_n"),
    ({"type": "height_difference", "agent_a": "a", "t_s": 1, "gamma_m": 1, "sigma_m": 1}, "dh_m"),
])
def test_bad_events_name_their_field(obj, field):
    with pytest.raises(InputError) as info:
        parse_event(obj, "events[3]")
    assert info.value.field == field and info.value.source == "events[3]"


def test_event_json_round_trip():
    objs = [
        {"type": "range", "agent_a": "a", "agent_b": "b", "t_s": 1.0, "range_m": 2.0},
        {"type": "anchor_range", "agent": "a", "t_s": 1.0, "anchor_n": [1.0, 2.0, 3.0], "range_m": 4.0},
        {"type": "position_fix", "agent": "a", "t_s": 1.0, "pos_n": [1.0, 2.0], "gamma_m": 3.0, "sigma_m": 1.0},
        {"type": "height_difference", "agent_a": "a", "agent_b": None, "t_s": 1.0, "dh_m": 3.0,
         "reference_height_m": 0.0, "gamma_m": 0.5, "sigma_m": 0.5},
    ]
    for obj in objs:
        assert event_to_dict(parse_event(obj)) == obj
    p = parse_event({"type": "height_difference", "agent_a": "a", "t_s": 1.0, "pressure_hpa": 999.6,
                     "reference_pressure_hpa": 1000.0, "gamma_m": 0.5, "sigma_m": 0.5})
    assert isinstance(p, HeightDifference)
    assert 3.0 < p.dh_m < 3.6
