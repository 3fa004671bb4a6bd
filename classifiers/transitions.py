"""Transition classes hold only next to what they lead into or out of: getting into a car comes right before
driving, getting out right after it.

A window classifier trained on isolated clips (MobiFall's car step-in/out recordings) sees a person settling on a
seat or a phone coming to rest and cannot tell it from a car door scene; in a walk it labels standing still
``car_step_in``. The rule: a window labelled with a transition class keeps it only when a window of its anchor
class lies within ``TRANSITION_REACH_S`` on the anchor's side (``car_step_in``: a ``vehicle`` window starting
after it; ``car_step_out``: one ending before it). Otherwise it takes the best class other than the transitions
and vehicle (posterior renormalised over them), so a phone at rest becomes ``stationary``/``sitting``.

A segment of the anchor class itself (consecutive ``vehicle`` windows) must last ``MIN_SEGMENT_S``: nobody drives
for less than half a minute, while a phone put down on a table for a few seconds can look like one on a windscreen
mount. A shorter run takes the best class other than it and the transitions; the transitions are judged after,
against the vehicle segments that remain.

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
#: Shortest segment (s, first window start to last window end) of an anchor class (a car trip).
MIN_SEGMENT_S = 30.0
ANCHORS = tuple(sorted({a for a, _ in TRANSITIONS.values()}))


def fallback(proba: Sequence[float], classes: Sequence[str], also_excluded: Sequence[str] = ()) -> tuple[str, float]:
    """Best class of one window's posterior other than the transitions and their anchors (a window that loses a
    car label is not in a car) and ``also_excluded``, and its posterior renormalised over the allowed classes.
    """
    p = np.asarray(proba, dtype=np.float64)
    allowed = np.array([c not in TRANSITIONS and c not in ANCHORS and c not in also_excluded for c in classes])
    if not allowed.any():
        raise InputError("no class is left once transitions and their anchors are excluded", field="classes")
    q = np.where(allowed, p, -1.0)
    b = int(np.argmax(q))
    total = float(p[allowed].sum())
    return str(classes[b]), float(p[b] / total) if total > 0 else 0.0


def _runs(labels: Sequence[str], name: str) -> list[tuple[int, int]]:
    """``[i, j)`` index ranges of consecutive windows labelled ``name``."""
    out: list[tuple[int, int]] = []
    i = 0
    while i < len(labels):
        if labels[i] == name:
            j = i
            while j < len(labels) and labels[j] == name:
                j += 1
            out.append((i, j))
            i = j
        else:
            i += 1
    return out


def gate_transitions(labels: Sequence[str], confidence: FloatArray, proba: FloatArray, classes: Sequence[str],
                     t_start_s: FloatArray, t_end_s: FloatArray, reach_s: float = TRANSITION_REACH_S,
                     min_segment_s: float = MIN_SEGMENT_S) -> tuple[tuple[str, ...], FloatArray]:
    """Labels and confidences with short anchor segments and unanchored transitions relabelled (module docstring)."""
    labs = list(labels)
    conf = np.array(confidence, dtype=np.float64, copy=True)
    t0, t1 = np.asarray(t_start_s, dtype=np.float64), np.asarray(t_end_s, dtype=np.float64)
    for anchor in ANCHORS:
        for i, j in _runs(labs, anchor):
            if t1[j - 1] - t0[i] < min_segment_s:
                for k in range(i, j):
                    labs[k], conf[k] = fallback(proba[k], classes)
    kept = tuple(labs)
    for cls_name, (anchor, side) in TRANSITIONS.items():
        idx = [i for i, lab in enumerate(kept) if lab == cls_name]
        if not idx:
            continue
        is_anchor = np.array([lab == anchor for lab in kept], dtype=bool)
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
    :meth:`push` returns the items that are final, :meth:`flush` the held ones at the end of the session. An
    anchor-class run is held until it lasts ``min_segment_s`` (then it and every later window of it pass at once)
    or ends short (relabelled); a ``car_step_in`` window waits for a confirmed vehicle segment within reach.
    """

    def __init__(self, reach_s: float = TRANSITION_REACH_S, min_segment_s: float = MIN_SEGMENT_S) -> None:
        self.reach_s = float(reach_s)
        self.min_segment_s = float(min_segment_s)
        self.held: list[dict[str, Any]] = []
        self.last_anchor_end: dict[str, float] = {}
        self.run: dict[str, Any] | None = None  # anchor run in progress: mode, t_start_s, confirmed

    def push(self, items: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for item in items:
            it = dict(item)
            mode = it["mode"]
            if self.run is not None and mode != self.run["mode"]:
                self._end_run()
            if mode in ANCHORS:
                if self.run is None:
                    self.run = {"mode": mode, "t_start_s": float(it["t_start_s"]), "confirmed": False}
                it["run"] = True
                if not self.run["confirmed"] and float(it["t_end_s"]) - self.run["t_start_s"] >= self.min_segment_s:
                    self._confirm()
                if self.run["confirmed"]:
                    self.last_anchor_end[mode] = float(it["t_end_s"])
                    it["anchor_ok"] = True
            self.held.append(self._judge_past(it))
            out += self._release(now_s=float(it["t_start_s"]))
        return out

    def flush(self) -> list[dict[str, Any]]:
        if self.run is not None:
            self._end_run()
        return self._release(now_s=float("inf"))

    def _confirm(self) -> None:
        """The run in progress is long enough: its windows stand and anchor the step-ins within reach."""
        assert self.run is not None
        self.run["confirmed"] = True
        mode, start = self.run["mode"], self.run["t_start_s"]
        for h in self.held:
            if h.get("run"):
                h["anchor_ok"] = True
                self.last_anchor_end[mode] = float(h["t_end_s"])
            elif h["mode"] in TRANSITIONS and TRANSITIONS[h["mode"]] == (mode, "after") and \
                    start - float(h["t_end_s"]) <= self.reach_s:
                h["anchored"] = True

    def _end_run(self) -> None:
        """The run in progress ended: unconfirmed windows take another class."""
        assert self.run is not None
        for h in self.held:
            if h.pop("run", False) and not h.get("anchor_ok"):
                classes = list(h["proba"])
                h["mode"], h["confidence"] = fallback([h["proba"][c] for c in classes], classes)
        self.run = None

    def _judge_past(self, it: dict[str, Any]) -> dict[str, Any]:
        """A ``before`` transition is decided at once from the confirmed anchors seen so far."""
        if it["mode"] in TRANSITIONS and TRANSITIONS[it["mode"]][1] == "before":
            end = self.last_anchor_end.get(TRANSITIONS[it["mode"]][0])
            it["anchored"] = end is not None and float(it["t_start_s"]) - end <= self.reach_s
        return it

    def _run_may_anchor(self, h: dict[str, Any]) -> bool:
        """Whether the unconfirmed run in progress started within reach after the transition window ``h``."""
        r = self.run
        return (r is not None and not r["confirmed"] and TRANSITIONS[h["mode"]] == (r["mode"], "after")
                and r["t_start_s"] - float(h["t_end_s"]) <= self.reach_s)

    def _release(self, now_s: float) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        while self.held:
            h = self.held[0]
            if h.get("run") and not h.get("anchor_ok"):
                break  # an anchor run waits until it is long enough or ends
            if h["mode"] in TRANSITIONS and "anchored" not in h and (
                    now_s - float(h["t_end_s"]) <= self.reach_s or self._run_may_anchor(h)):
                break  # a step-in window waits for its vehicle
            self.held.pop(0)
            if h["mode"] in TRANSITIONS and not h.pop("anchored", False):
                classes = list(h["proba"])
                h["mode"], h["confidence"] = fallback([h["proba"][c] for c in classes], classes)
            for k in ("anchored", "run", "anchor_ok"):
                h.pop(k, None)
            out.append(h)
        return out

    def state(self) -> dict[str, Any]:
        return {"reach_s": self.reach_s, "min_segment_s": self.min_segment_s, "held": [dict(h) for h in self.held],
                "last_anchor_end": dict(self.last_anchor_end), "run": None if self.run is None else dict(self.run)}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> TransitionGate:
        try:
            g = cls(float(state["reach_s"]), float(state.get("min_segment_s", MIN_SEGMENT_S)))
            g.held = [dict(h) for h in state["held"]]
            g.last_anchor_end = {str(k): float(v) for k, v in state["last_anchor_end"].items()}
            g.run = None if state.get("run") is None else dict(state["run"])
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"not a transition gate state ({exc})", field="state") from None
        return g
