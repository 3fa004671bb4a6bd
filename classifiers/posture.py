"""A trouser-pocket phone is ``sitting`` only when its thigh is horizontal.

A pocket phone lies along the thigh. Standing or walking, the thigh hangs near the vertical (while walking it swings
by 20-30 deg about a slight forward flexion); seated, it is near the horizontal. So the direction of gravity in the
device frame turns by about 70-90 deg between walking and sitting, and by less than about 20 deg between walking and
standing. The window classifier, trained on clips, confuses a pocket phone at rest with one on a seated thigh: the
simulated pocket office walk (``mobile_logs/sim/pocket_office.zip``) had its last stand labelled ``sitting``.

The rule: a window labelled ``sitting`` keeps it unless the walker was upright (walking, running, stairs) within
:data:`POSTURE_REACH_S` before it and the window's mean gravity direction (device frame) lies within
:data:`SITTING_MIN_TILT_DEG` of the upright one (the midpoint between standing and sitting). Then the thigh has not
turned: the classifier's "at rest, seated" becomes "at rest, upright", ``stationary``, with the posterior of
being at rest (sitting plus stationary) as its confidence; a model without that class gives the best class other
than sitting, the transitions and their anchors (:func:`classifiers.transitions.fallback`). The upright
reference is the running mean of the upright windows' gravity directions (weight :data:`REFERENCE_WEIGHT` each).
A ``sitting`` window with no upright window within reach before it (a walk that starts from a stand) waits, with the
windows after it, for the first upright window: if one starts within reach after it, it is judged against the
reference that window makes; if none comes (a recording that starts seated), it keeps its label, since without a
reference the thigh's angle is unknown. :class:`PostureGate` applies the rule online, holding such windows back;
:func:`gate_posture` runs the same gate over a whole recording, so the two decide alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from classifiers.transitions import fallback
from classifiers.windows import Windows
from pdr.errors import InputError

FloatArray = NDArray[np.float64]

SITTING = "sitting"
#: The pocket model's class of a phone at rest on an upright thigh.
AT_REST_UPRIGHT = "stationary"
#: Labels of a walker whose thigh hangs near the vertical (the posture reference).
UPRIGHT = ("walking", "running", "stairs_up", "stairs_down")
#: Smallest angle (deg) between a window's gravity direction and the upright one for ``sitting`` to stand.
SITTING_MIN_TILT_DEG = 45.0
#: Longest time (s) from the end of the last upright window to a ``sitting`` window judged against it.
POSTURE_REACH_S = 30.0
#: Weight of each upright window in the running mean of the reference direction.
REFERENCE_WEIGHT = 0.2


def window_gravity(win: Windows) -> FloatArray:
    """(W, 3) unit mean specific force of each window in the device frame (NaN without accelerometer data)."""
    acc = win.get("acc")
    if acc is None:
        return np.full((len(win), 3), np.nan)
    present = np.isfinite(acc)
    count = present.sum(axis=1)             # np.nanmean, without its warning for a window with no sample (a gap)
    mean = np.where(count > 0, np.where(present, acc, 0.0).sum(axis=1) / np.maximum(count, 1), np.nan)
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, mean / norm, np.nan)


class PostureGate:
    """Online posture rule (module doc) over decision dicts arriving in time order (``t_start_s``, ``t_end_s``,
    ``mode``, ``confidence``, ``proba`` class -> posterior, ``gravity``: the window's unit gravity direction in the
    device frame). :meth:`push` returns the decided ones (``gravity`` removed), :meth:`flush` the held ones at the
    end of the session. JSON-able state.
    """

    def __init__(self, reach_s: float = POSTURE_REACH_S, min_tilt_deg: float = SITTING_MIN_TILT_DEG) -> None:
        self.reach_s = float(reach_s)
        self.min_tilt_deg = float(min_tilt_deg)
        self.reference: list[float] | None = None      # unit gravity direction of the upright walker (device)
        self.reference_end_s: float | None = None      # end (s) of the last upright window
        self.held: list[dict[str, Any]] = []           # a sitting window waiting for a reference, and those after

    def push(self, items: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for item in items:
            it = dict(item)
            t0 = float(it["t_start_s"])
            while self.held and t0 - float(self.held[0]["t_end_s"]) > self.reach_s:
                out += self._release_first()          # no upright window came within reach: it stays sitting
            if self.held or (it["mode"] == SITTING and not self._fresh(t0)):
                it["pending"] = it["mode"] == SITTING
                self.held.append(it)
            else:
                out.append(self._decide(it))
                continue
            if self._learn(it):
                for h in self.held:
                    if h.pop("pending", False) and t0 - float(h["t_end_s"]) <= self.reach_s:
                        self._judge(h)
                out += [self._done(h) for h in self.held]
                self.held = []
        return out

    def flush(self) -> list[dict[str, Any]]:
        """The held windows at the end of the session, undecided ones keeping their labels."""
        out = [self._done(h) for h in self.held]
        self.held = []
        return out

    def _fresh(self, t_start_s: float) -> bool:
        """Whether an upright window ended within reach before ``t_start_s``."""
        return self.reference_end_s is not None and t_start_s - self.reference_end_s <= self.reach_s

    def _decide(self, it: dict[str, Any]) -> dict[str, Any]:
        """A window judged against the reference of the past, then learnt from (in time order)."""
        if it["mode"] == SITTING and self._fresh(float(it["t_start_s"])):
            self._judge(it)
        self._learn(it)
        return self._done(it)

    def _judge(self, it: dict[str, Any]) -> None:
        g = np.asarray(it["gravity"], dtype=np.float64)
        if self.reference is None or not np.all(np.isfinite(g)):
            return
        cos = float(np.clip(g @ np.asarray(self.reference), -1.0, 1.0))
        if math.degrees(math.acos(cos)) < self.min_tilt_deg:
            classes = list(it["proba"])
            it["mode"], it["confidence"] = _upright([it["proba"][c] for c in classes], classes)

    def _learn(self, it: dict[str, Any]) -> bool:
        """An upright window's gravity into the reference; whether it was one."""
        g = np.asarray(it["gravity"], dtype=np.float64)
        if it["mode"] not in UPRIGHT or not np.all(np.isfinite(g)):
            return False
        ref = g if self.reference is None else \
            (1.0 - REFERENCE_WEIGHT) * np.asarray(self.reference) + REFERENCE_WEIGHT * g
        self.reference = (ref / np.linalg.norm(ref)).tolist()
        self.reference_end_s = float(it["t_end_s"])
        return True

    def _release_first(self) -> list[dict[str, Any]]:
        """Release the first held window undecided, and the windows after it that no longer wait for anything."""
        first = self.held.pop(0)
        first.pop("pending", None)
        out = [self._done(first)]
        while self.held and not self.held[0].get("pending"):
            out.append(self._done(self.held.pop(0)))
        return out

    @staticmethod
    def _done(it: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in it.items() if k not in ("gravity", "pending")}

    def state(self) -> dict[str, Any]:
        return {"reach_s": self.reach_s, "min_tilt_deg": self.min_tilt_deg, "reference": self.reference,
                "reference_end_s": self.reference_end_s, "held": [dict(h) for h in self.held]}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> PostureGate:
        try:
            g = cls(float(state["reach_s"]), float(state["min_tilt_deg"]))
            g.reference = None if state["reference"] is None else [float(v) for v in state["reference"]]
            g.reference_end_s = None if state["reference_end_s"] is None else float(state["reference_end_s"])
            g.held = [dict(h) for h in state.get("held", [])]
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"not a posture gate state ({exc})", field="state") from None
        return g


def _upright(proba: Sequence[float], classes: Sequence[str]) -> tuple[str, float]:
    """A sitting window's label and confidence once its thigh is seen upright (module doc)."""
    names = list(classes)
    if AT_REST_UPRIGHT not in names:
        return fallback(proba, classes, also_excluded=(SITTING,))
    p = np.asarray(proba, dtype=np.float64)
    return AT_REST_UPRIGHT, float(p[names.index(AT_REST_UPRIGHT)] + p[names.index(SITTING)])


def gate_posture(labels: Sequence[str], confidence: FloatArray, proba: FloatArray, classes: Sequence[str],
                 t_start_s: FloatArray, t_end_s: FloatArray, gravity: FloatArray
                 ) -> tuple[tuple[str, ...], FloatArray]:
    """The posture rule over a whole recording's windows in time order (module doc): :class:`PostureGate` run
    over them and flushed.
    """
    gate = PostureGate()
    items = [{"t_start_s": float(t_start_s[i]), "t_end_s": float(t_end_s[i]), "mode": str(labels[i]),
              "confidence": float(confidence[i]), "proba": dict(zip(classes, map(float, proba[i]), strict=True)),
              "gravity": np.asarray(gravity[i], dtype=np.float64).tolist()} for i in range(len(labels))]
    out = gate.push(items) + gate.flush()
    return tuple(str(it["mode"]) for it in out), np.array([it["confidence"] for it in out], dtype=np.float64)
