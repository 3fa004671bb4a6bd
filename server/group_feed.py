"""Group agents fed from live sessions: an agent joined with a ``session_id`` takes its steps from that session.

After each processing pass over a session's batches, :func:`feed_groups` reads the session's final foot step
events (each carries its step increment, eqs. 7-8, see :mod:`server.foot_steps`) that are newer than what each
following agent's group has accepted, submits them to the group as the agent's step summaries (device role
``left_foot`` is the group's foot ``left``, ``right_foot`` is ``right``: :data:`server.feet.FOOT_SIDES`; a foot
the group does not have is not fed) and applies what the group's watermark allows, so the group's fused solution
follows the session as its batches arrive. The session's steps are on its shoes' own clock (``t_s`` of its foot
track rows); the agent's ``clock_offset_s`` (given when it joined) puts them on the group's: group time = session
time + ``clock_offset_s``. Provisional steps (the
session's tail) are not fed: a group only takes steps that will not change. The agent's ranges and other
measurements still come from its uploads, which may not carry its steps.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from pdr.fusion.group import Group
from pdr.fusion.measurements import StepSummary
from server.feet import FOOT_SIDES
from server.foot_steps import step_increments
from server.group_store import GroupStore
from server.store import Store


def _new_steps(store: Store, session_id: str, group: Group, agent: str, offset_s: float) -> list[StepSummary]:
    """The session's final foot steps the group has not accepted for ``agent`` yet, in time order, on the group's
    clock (session time + ``offset_s``, s).
    """
    feet = {side: role for side, role in FOOT_SIDES.items() if side in group.centre.config.feet}
    if not feet:
        return []
    last = {side: group.last_step_s(agent, side) for side in feet}          # group clock
    since = min(last.values()) - offset_s - 1.0                             # session clock, a margin for rounding
    rows = store.events(session_id, "step", since_s=None if since == float("-inf") else since)
    steps = [StepSummary(agent, side, replace(inc, t_s=inc.t_s + offset_s)) for side, role in feet.items()
             for inc in step_increments(rows, role)]
    return sorted((s for s in steps if s.t_s > last[s.foot]), key=lambda s: s.t_s)


def feed_groups(store: Store, session_id: str) -> dict[str, int]:
    """Submit the session's new foot steps to every group agent that follows it; {group id: steps fed}."""
    repo = GroupStore(store.engine)
    fed: dict[str, int] = {}
    for link in repo.followers(session_id):
        def change(group: Group, agent: str = link.agent, offset_s: float = link.clock_offset_s) -> int:
            steps = _new_steps(store, session_id, group, agent, offset_s)
            if not steps:
                return 0
            accepted = group.submit(steps, reporter=agent)
            group.process()
            return accepted

        count: Any = repo.modify(link.group_id, change)
        fed[link.group_id] = int(count)
    return fed
