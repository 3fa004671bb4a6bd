"""The session's fused dual-foot track (device role ``fused``) from its left and right shoe IMUs.

After each pass of :class:`server.processing.SessionProcessing` over a session's pending batches, when both the
session's ``left_foot`` and ``right_foot`` are live (:mod:`server.feet`: data stored) and have stepped,
:func:`fuse_session` reads the foot step events
committed since it last ran (final rows only; each carries its step increment, see
:mod:`server.foot_processor`) and feeds them to :class:`pdr.foot.dual.DualFootFusion`, whose state is kept in
``processor_states`` under the role ``fused``. The fusion consumes steps only up to the time both feet have
reported, in time order, so the fused rows do not depend on the order or grouping in which the batches
arrived or were processed; a rebuild (reprocess, late batch) clears the state with the rest and reproduces them.

Track rows (one per fused step update): ``t_s`` of the step (s, the devices' common clock), the midpoint
between the two fused feet (m, ENU in the left foot's navigation frame, origin at its start), ``heading_deg``
the compass heading of the circular mean of the two feet's headings, ``step_length_m`` how far the midpoint
moved in the update, mode ``walking``, or ``standing`` for the update of a foot's reset while it stands (the fused
step's :attr:`~pdr.foot.dual.FusedStep.stride`, carried from the foot's step event's mode through its increment:
that foot's own row's mode; not counted as a step), no floor. The provisional tail is what the fusion would add if the
session ended now: the steps it still holds back plus the feet's own provisional steps.
"""

from __future__ import annotations

import json

from pdr.errors import InputError
from pdr.foot.dual import DualFootFusion, FusedStep
from pdr.frames import yaw_to_heading_deg
from server.feet import FOOT_SIDES, FUSED, session_feet
from server.foot_steps import mode_of, step_increments
from server.store import Store, TrackRow

ROLE = FUSED
#: Device roles of the two feet, in the order of :data:`pdr.foot.dual.SIDES`.
FEET = FOOT_SIDES
FEET_INDEX = {side: i for i, side in enumerate(FEET)}


def _row(u: FusedStep) -> TrackRow:
    """The fused track row of update ``u``."""
    mid = u.midpoint_n
    return TrackRow(u.t_s, float(mid[0]), float(mid[1]), float(mid[2]), None, float(yaw_to_heading_deg(u.body_yaw)),
                    u.midpoint_shift_m, mode_of(u.stride))


def fuse_session(store: Store, session_id: str) -> bool:
    """Fuse the session's new foot steps and commit the ``fused`` rows; whether the session has both feet.

    Raises
    ------
    InputError
        Foot step events that cannot be fused (without increments, or out of time order).
    """
    if set(session_feet(store, session_id).live) != set(FEET.values()):
        return False        # a paired foot without data is not fused in (it would hold the midpoint at its start)
    state, _ = store.load_state(session_id, ROLE)
    fusion = DualFootFusion.from_dict(json.loads(state)) if state else DualFootFusion()
    last = dict(zip(FEET, fusion.last_t_s, strict=True))
    known = [t for t in last.values() if t is not None]
    # Only the rows after the older of the two feet's last fused steps (cost proportional to what is new).
    since = min(known) if len(known) == 2 else None
    rows = store.events(session_id, "step", since_s=since)
    if state is None and not set(FEET.values()) <= {r.device_role for r in rows}:
        return False        # both feet live, but one has not taken a step yet
    out: list[FusedStep] = []
    for side, role in FEET.items():
        out += fusion.add_steps(side, step_increments(rows, role, last[side], provisional=False))
    # The tail, on a copy: the held steps and the feet's provisional steps, as if the session ended now.
    tail_fusion = DualFootFusion.from_dict(fusion.to_dict())
    tail: list[FusedStep] = []
    try:
        for side, role in FEET.items():
            tail += tail_fusion.add_steps(side, step_increments(rows, role, tail_fusion.last_t_s[FEET_INDEX[side]],
                                                                provisional=True))
        tail += tail_fusion.finish()
    except InputError:          # a provisional step that the final ones have overtaken: no tail this time
        tail = []
    store.commit_results(session_id, ROLE, None, json.dumps(fusion.to_dict()).encode(), None,
                         [_row(u) for u in out], [], tail_track=[_row(u) for u in tail])
    return True

