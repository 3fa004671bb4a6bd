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
reference is the running mean of the upright windows' gravity directions (weight :data:`REFERENCE_WEIGHT` each); it
is only ever taken from the past, so the online decisions (:class:`PostureGate`) equal the offline ones
(:func:`gate_posture`) without holding windows back. A ``sitting`` window with no upright window before it within
reach keeps its label: without a reference the thigh's angle is unknown (a recording that starts seated).
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
    mean = np.nanmean(acc, axis=1) if acc.size else np.zeros((len(win), 3))
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, mean / norm, np.nan)


class PostureGate:
    """Online posture rule (module doc) over decisions arriving in time order; JSON-able state."""

    def __init__(self, reach_s: float = POSTURE_REACH_S, min_tilt_deg: float = SITTING_MIN_TILT_DEG) -> None:
        self.reach_s = float(reach_s)
        self.min_tilt_deg = float(min_tilt_deg)
        self.reference: list[float] | None = None      # unit gravity direction of the upright walker (device)
        self.reference_end_s: float | None = None      # end (s) of the last upright window

    def judge(self, label: str, confidence: float, proba: Sequence[float], classes: Sequence[str],
              t_start_s: float, t_end_s: float, gravity: Sequence[float]) -> tuple[str, float]:
        """The window's label and confidence after the rule; learns the reference from upright windows."""
        g = np.asarray(gravity, dtype=np.float64)
        known = bool(np.all(np.isfinite(g)))
        if (label == SITTING and known and self.reference is not None and self.reference_end_s is not None
                and t_start_s - self.reference_end_s <= self.reach_s):
            cos = float(np.clip(g @ np.asarray(self.reference), -1.0, 1.0))
            if math.degrees(math.acos(cos)) < self.min_tilt_deg:
                label, confidence = _upright(proba, classes)
        if label in UPRIGHT and known:
            ref = g if self.reference is None else \
                (1.0 - REFERENCE_WEIGHT) * np.asarray(self.reference) + REFERENCE_WEIGHT * g
            self.reference = (ref / np.linalg.norm(ref)).tolist()
            self.reference_end_s = float(t_end_s)
        return label, confidence

    def push(self, items: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
        """Decision dicts (``t_start_s``, ``t_end_s``, ``mode``, ``confidence``, ``proba`` class -> posterior,
        ``gravity``) with the rule applied; ``gravity`` is removed.
        """
        out = []
        for item in items:
            it = dict(item)
            gravity = it.pop("gravity")
            classes = list(it["proba"])
            it["mode"], it["confidence"] = self.judge(
                str(it["mode"]), float(it["confidence"]), [it["proba"][c] for c in classes], classes,
                float(it["t_start_s"]), float(it["t_end_s"]), gravity)
            out.append(it)
        return out

    def state(self) -> dict[str, Any]:
        return {"reach_s": self.reach_s, "min_tilt_deg": self.min_tilt_deg, "reference": self.reference,
                "reference_end_s": self.reference_end_s}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> PostureGate:
        try:
            g = cls(float(state["reach_s"]), float(state["min_tilt_deg"]))
            g.reference = None if state["reference"] is None else [float(v) for v in state["reference"]]
            g.reference_end_s = None if state["reference_end_s"] is None else float(state["reference_end_s"])
        except (KeyError, TypeError, ValueError) as exc:
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
    """Offline posture rule over a recording's windows in time order (module doc)."""
    gate = PostureGate()
    labs = list(labels)
    conf = np.array(confidence, dtype=np.float64, copy=True)
    for i in range(len(labs)):
        labs[i], conf[i] = gate.judge(labs[i], float(conf[i]), proba[i], classes, float(t_start_s[i]),
                                      float(t_end_s[i]), gravity[i])
    return tuple(labs), conf
