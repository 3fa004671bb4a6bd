"""A session's shoe IMUs and the track that stands for the session (its *primary* track).

*Paired* feet are the session's devices of a foot role (``POST .../devices``, or, in a session without a phone, a
foot batch's device: a shoe streaming alone names its foot; :func:`pairs_itself`);
*live* feet are the paired feet with stored data (raw IMU batches, uploaded files or step summaries). The
fused dual-foot track (:mod:`server.fused_feet`) needs two live feet that have taken steps: a paired foot that
never sends data is not fused in (it would hold the midpoint at its start). The primary track follows the
shoes when they are paired and live (the mission: the track comes from the shoes): two feet, the ``fused``
track; one foot, that foot's ZUPT track; no foot, the phone's. The phone still gives the motion modes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from pdr.recording import FOOT_ROLES
from server.foot_steps import FUSED
from server.store import Store

__all__ = ["FOOT_SIDES", "FUSED", "ROLE_PRIORITY", "ROLE_SIDES"]
#: The feet as the fusion library names them (:data:`pdr.foot.dual.SIDES`, a group's ``FusionConfig.feet``) and
#: their names in the API, the sessions' device roles: the one foot vocabulary of sessions, the fused track and
#: groups (the library's names never reach a client).
FOOT_SIDES = {"left": "left_foot", "right": "right_foot"}
#: The inverse of :data:`FOOT_SIDES`: the API's foot names to the library's.
ROLE_SIDES = {role: side for side, role in FOOT_SIDES.items()}
#: Which device's track stands for the session, first present wins (module doc).
ROLE_PRIORITY = (FUSED, *FOOT_ROLES, "phone")


@dataclass(frozen=True)
class Feet:
    """The session's paired foot roles and those of them with stored data (both sorted)."""

    paired: tuple[str, ...]
    live: tuple[str, ...]

    def to_json(self) -> dict[str, list[str]]:
        return {"paired": list(self.paired), "live": list(self.live)}


def foot_role(side: str) -> str:
    """The API's name (device role) of the foot the fusion library names ``side`` (other names unchanged)."""
    return FOOT_SIDES.get(side, side)


def session_feet(store: Store, session_id: str) -> Feet:
    """Paired and live feet of a session (module doc)."""
    paired = sorted(d.role for d in store.devices(session_id) if d.role in FOOT_ROLES)
    with_data = store.batch_roles(session_id)
    return Feet(tuple(paired), tuple(r for r in paired if r in with_data))


def pairs_itself(store: Store, session_id: str, role: str) -> bool:
    """Whether a raw batch of ``role`` may pair its device by arriving: a phone, or a foot in a session without a
    phone. A foot batch to a session with a phone needs the foot paired first: a phone's batch sent with a foot's
    role would otherwise silently replace the phone's track as the session's primary one.
    """
    if role not in FOOT_ROLES:
        return True
    return "phone" not in {d.role for d in store.devices(session_id)}


def primary_role(roles: Iterable[str]) -> str:
    """The role, among those with a track, whose track stands for the session ('' when there is none)."""
    present = set(roles)
    return next((r for r in ROLE_PRIORITY if r in present), min(present, default=""))
