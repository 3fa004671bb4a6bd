"""Transition classes hold only next to what they lead into or out of: getting into a car comes right before
driving, getting out right after it.

A window classifier trained on isolated clips (MobiFall's car step-in/out recordings) sees a person settling on a
seat or a phone coming to rest and cannot tell it from a car door scene; in a walk it labels standing still
``car_step_in``. The rule: a window labelled with a transition class keeps it only when a window of its anchor
class lies within ``TRANSITION_REACH_S`` on the anchor's side (``car_step_in``: a ``vehicle`` window starting
after it; ``car_step_out``: one ending before it). Otherwise it takes the best of the other classes (posterior
renormalised over them), so a phone at rest becomes ``stationary``/``sitting``.

:func:`gate_transitions` applies the rule to a whole sequence (offline); :class:`TransitionGate` applies it online,
holding back a ``car_step_in`` window (and the windows after it) until a vehicle window comes or the reach has
passed, so the streaming decisions equal the offline ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]

#: Transition class -> (anchor class, side of the anchor: ``after`` the transition or ``before`` it).
TRANSITIONS: dict[str, tuple[str, str]] = {"car_step_in": ("vehicle", "after"),
                                          "car_step_out": ("vehicle", "before")}
#: Longest time (s) between a transition window and its anchor window (getting seated, buckling up, starting).
TRANSITION_REACH_S = 30.0


def fallback(proba: Sequence[float], classes: Sequence[str]) -> tuple[str, float]:
    """Best non-transition class of one window's posterior and its posterior renormalised over those classes."""
    p = np.asarray(proba, dtype=np.float64)
    allowed = np.array([c not in TRANSITIONS for c in classes])
    if not allowed.any():
        raise InputError("every class is a transition class", field="classes")
    q = np.where(allowed, p, -1.0)
    b = int(np.argmax(q))
    total = float(p[allowed].sum())
    return str(classes[b]), float(p[b] / total) if total > 0 else 0.0


def gate_transitions(labels: Sequence[str], confidence: FloatArray, proba: FloatArray, classes: Sequence[str],
                     t_start_s: FloatArray, t_end_s: FloatArray,
                     reach_s: float = TRANSITION_REACH_S) -> tuple[tuple[str, ...], FloatArray]:
    """Labels and confidences with unanchored transition windows relabelled (module docstring)."""
    labs = list(labels)
    conf = np.array(confidence, dtype=np.float64, copy=True)
    t0, t1 = np.asarray(t_start_s, dtype=np.float64), np.asarray(t_end_s, dtype=np.float64)
    for cls_name, (anchor, side) in TRANSITIONS.items():
        idx = [i for i, lab in enumerate(labels) if lab == cls_name]
        if not idx:
            continue
        is_anchor = np.array([lab == anchor for lab in labels], dtype=bool)
        a0, a1 = t0[is_anchor], t1[is_anchor]
        for i in idx:
            if side == "after":
                ok = np.any((a0 >= t0[i]) & (a0 - t1[i] <= reach_s))
            else:
                ok = np.any((a1 <= t1[i]) & (t0[i] - a1 <= reach_s))
            if not ok:
                labs[i], conf[i] = fallback(proba[i], classes)
    return tuple(labs), conf


class TransitionGate:
    """Online :func:`gate_transitions` over results arriving in time order.

    Items are dicts with ``t_start_s``, ``t_end_s``, ``mode``, ``confidence`` and ``proba`` (class -> posterior);
    :meth:`push` returns the items that are final, :meth:`flush` the held ones at the end of the session.
    """

    def __init__(self, reach_s: float = TRANSITION_REACH_S) -> None:
        self.reach_s = float(reach_s)
        self.held: list[dict[str, Any]] = []
        self.last_anchor_end: dict[str, float] = {}

    def push(self, items: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for it in items:
            if it["mode"] in [a for a, _ in TRANSITIONS.values()]:
                self.last_anchor_end[it["mode"]] = float(it["t_end_s"])
                for h in self.held:  # a vehicle window confirms the held step-in windows within reach
                    if h["mode"] in TRANSITIONS and TRANSITIONS[h["mode"]] == (it["mode"], "after") and \
                            float(it["t_start_s"]) - float(h["t_end_s"]) <= self.reach_s:
                        h["anchored"] = True
            self.held.append(self._judge_past(dict(it)))
            out += self._release(now_s=float(it["t_start_s"]))
        return out

    def flush(self) -> list[dict[str, Any]]:
        return self._release(now_s=float("inf"))

    def _judge_past(self, it: dict[str, Any]) -> dict[str, Any]:
        """A ``before`` transition is decided at once from the anchors seen so far."""
        if it["mode"] in TRANSITIONS and TRANSITIONS[it["mode"]][1] == "before":
            end = self.last_anchor_end.get(TRANSITIONS[it["mode"]][0])
            it["anchored"] = end is not None and float(it["t_start_s"]) - end <= self.reach_s
        return it

    def _release(self, now_s: float) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        while self.held:
            h = self.held[0]
            if h["mode"] in TRANSITIONS and "anchored" not in h and now_s - float(h["t_end_s"]) <= self.reach_s:
                break  # a step-in window waits for its vehicle
            self.held.pop(0)
            if h["mode"] in TRANSITIONS and not h.pop("anchored", False):
                classes = list(h["proba"])
                h["mode"], h["confidence"] = fallback([h["proba"][c] for c in classes], classes)
            h.pop("anchored", None)
            out.append(h)
        return out

    def state(self) -> dict[str, Any]:
        return {"reach_s": self.reach_s, "held": [dict(h) for h in self.held],
                "last_anchor_end": dict(self.last_anchor_end)}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> TransitionGate:
        try:
            g = cls(float(state["reach_s"]))
            g.held = [dict(h) for h in state["held"]]
            g.last_anchor_end = {str(k): float(v) for k, v in state["last_anchor_end"].items()}
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"not a transition gate state ({exc})", field="state") from None
        return g
