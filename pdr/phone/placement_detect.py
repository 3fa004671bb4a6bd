"""Online placement detection of a walking phone from the physics of its carriage (no trained model).

Per stride (two steps) two angles are measured in the device frame (:func:`stride_cues`):

``tilt_swing_deg``
    How far the device's up direction ``u_b = C_nb^T e_z`` (from the attitude filter) turns over the stride:
    the range of its component along its principal direction of motion, as an angle. A phone held in front
    (texting, reading, phoning) or worn on the torso is steady: a few degrees of gait bounce and wrist tremor.
    A phone in a trouser pocket turns with the thigh and one in a swinging hand with the arm: tens of degrees
    per stride at the stride frequency.
``force_swing_deg``
    The same range for the direction of the specific force ``acc_b`` smoothed over ``smooth_s`` (the gait's
    impacts removed).
``long_axis_up``
    ``|mean u_b . y|``: the cosine of the angle between the device's long axis (y) and the vertical.

The decision, stride by stride (:func:`classify_stride`):

1. ``tilt_swing_deg < held_max_swing_deg``: the phone is held steady (``hand``).
2. Else the ratio ``force_swing_deg / tilt_swing_deg`` separates the two swinging carriages.

   - A phone in a swinging hand is the bob of a pendulum (the arm). The specific force of a pendulum bob lies
     along the string at every instant: the tangential part of gravity is exactly what accelerates the bob, so
     no tangential specific force is left. The specific-force direction in the device frame therefore stays
     nearly fixed (along the arm) while the device turns through the whole swing: the ratio is well below 1.
   - A phone in a trouser pocket turns with the thigh, which through the stance (about 60 % of the cycle)
     turns about the planted foot while the hip moves on at nearly constant velocity: no pendulum, the
     specific force is gravity plus the trunk's bounce and the heel strikes' impacts, so its direction turns at
     least as much as the device does (ratio about 1 or more; running, with its larger impacts, well above 1).

   ``ratio < pendulum_max_ratio`` (halfway between the ideal pendulum's 0 and the rigid, gravity-dominated
   mount's 1) is ``swinging``.
3. Else a trouser pocket holds the phone along the thigh, its long axis near vertical: ``long_axis_up``
   at least ``cos(pocket_max_axis_tilt_deg)`` is ``pocket``; a phone that turns but lies across the vertical
   (a reading phone swaying in a walking hand, screen up) is ``hand``.

The device's turn comes from the attitude filter's gyro propagation: without a gyroscope the attitude follows
the specific force and neither cue exists (the pipeline then takes the phone as hand-held and says so).

:class:`PlacementDetector` turns these per-stride labels into an online decision. During the first
``switch_strides`` strides of the session the placement is the latest stride's label (a walk's first stride
starts from rest and swings the limb through half its range); afterwards a different label replaces the
current one once it has won ``switch_strides`` strides in a row, so a phone taken out of the pocket mid-walk is
followed within a few strides while one odd stride changes nothing.

A phone taken out of a pocket also turns: from along the thigh (long axis near the vertical) to the reading or
phoning hand, its stride-mean up direction in the device frame (``up_b``) moves by tens of degrees, while it
stays within a few degrees from stride to stride in the pocket, slow steps and pauses included. A stride that
reads as held steady (rule 1) while the phone's mean up direction is within ``moved_min_deg`` of the pocket's
is a gentle pocket stride (the benchmark's walkers slowing down in a pocket read as held for three strides and
more, and their walks turned backwards), not a phone in the hand. For ``pocket_hold_strides`` strides in a row at
most: a slow-down at a turn or a door lasts a few strides, while a phone that stays steady for longer as the steps go
on is not swinging with a thigh (a hand-held phone that was handled upright for a few strides and read as a pocket
would otherwise stay one: two IPIN walks, 117 and 162 steps).

A pause (no step for longer than ``pause_s``) ends a walk, and the next walk settles afresh: its first
``switch_strides`` strides each decide on their own, as at the session's start, and the pocket's hold (a slow-down
within a walk) is not given. A pause is where a phone is put away or taken out, and where a walker settles into
reading: the IPIN walkers wave the phone for a calibration, stand, and then walk with it held steady; the wave's last
strides read as a pocket, and with the decision and the hold carried over the stand, 13-17 s of the walk after it were
a pocket's (IPIN2023_T3_TrainingTrial02_repetition01 and 22_repetition01, p75 16.3 and 13.0 m). ``pdr eval ipin
../shared/data/ipin2023_t3 --placement detect`` (the carriage detected, not taken from the reader): p75 4.13 -> 3.65 m
causal, 3.99 -> 3.07 m smoothed (the reader's hand-held: 3.54 / 2.96); ``pdr eval placement ../shared/data``: IPIN
steps read as held 93.1 -> 94.2 %, the other datasets' and ``pdr eval heading`` unchanged. ``pause_s`` is two of the
step detector's longest steps: the gap one missed step leaves in a slow walk (at one step, 1.2 s, the other walker's
disturbed back pocket flipped to the hand for three strides after a 1.7 s gap: causal 9.4 -> 12.7 deg).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

FloatArray = NDArray[np.float64]

#: Labels the detector gives (pipeline placements).
DETECTED_PLACEMENTS = ("hand", "pocket", "swinging")


@dataclass(frozen=True)
class PlacementDetectConfig:
    """Parameters of the placement detector (angles in degrees, SI otherwise).

    Attributes
    ----------
    held_max_swing_deg
        Largest turn of the device's up direction over a stride of a phone held steady (deg).
    pendulum_max_ratio
        Largest ratio of specific-force to device turn of a phone swinging freely with the arm.
    pocket_max_axis_tilt_deg
        Largest angle between a pocket phone's long axis and the vertical (deg).
    smooth_s
        Moving-average length applied to the specific force before its direction is taken (s).
    switch_strides
        Consecutive strides with another label before the placement changes.
    moved_min_deg
        Smallest turn of a pocket phone's stride-mean up direction (device frame, deg) that lets a steady stride
        read as a phone held in the hand (module doc): half the 60 deg between a thigh's long axis and a reading
        phone's.
    pocket_hold_strides
        Most steady strides in a row that the unmoved up direction keeps in the pocket (module doc).
    pause_s
        Longest gap (s) between the end of a step and the start of the next within one walk; a longer one is a
        pause, after which the next walk settles afresh (module doc). Two of the step detector's longest steps
        (:attr:`pdr.phone.steps.StepConfig.max_step_s`): the gap one missed step leaves in a slow walk.
    """

    held_max_swing_deg: float = 12.0
    pendulum_max_ratio: float = 0.8
    pocket_max_axis_tilt_deg: float = 45.0
    smooth_s: float = 0.1
    switch_strides: int = 3
    moved_min_deg: float = 30.0
    pocket_hold_strides: int = 8
    pause_s: float = 2.4

    def __post_init__(self) -> None:
        if not (self.held_max_swing_deg > 0 and self.pendulum_max_ratio > 0 and self.smooth_s > 0
                and self.switch_strides >= 1):
            raise InputError("placement detector parameters must be positive (switch_strides >= 1)",
                             source="config", field="placement_detect")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class StrideCues:
    """Turn of the device's up direction and of the specific-force direction over one stride (deg), the
    cosine of the long axis' angle to the vertical, and the stride-mean up direction in the device frame (unit
    vector; None where unknown).
    """

    tilt_swing_deg: float
    force_swing_deg: float
    long_axis_up: float
    up_b: tuple[float, float, float] | None = None

    @property
    def ratio(self) -> float:
        """``force_swing_deg / tilt_swing_deg`` (inf for a device that did not turn)."""
        return self.force_swing_deg / self.tilt_swing_deg if self.tilt_swing_deg > 0 else math.inf


def swing_range_deg(v: FloatArray) -> float:
    """Angular range (deg) of unit vectors ``v`` (N, 3) along their principal direction of motion.

    The vectors' components across their mean direction are projected on the principal axis of those
    components; the range of the projection, taken as the sine of an angle, is the swing.
    """
    m = v.sum(axis=0)
    nm = float(np.linalg.norm(m))
    if v.shape[0] < 3 or nm == 0.0:
        return 0.0
    m = m / nm
    d = v - np.outer(v @ m, m)
    dc = d - d.sum(axis=0) / d.shape[0]
    s = dc.T @ dc
    w, vec = np.linalg.eigh(s)
    p = np.clip(d @ vec[:, -1], -1.0, 1.0)
    return math.degrees(math.asin(float(p.max())) - math.asin(float(p.min())))


def stride_cues(q_nb: FloatArray, acc_b: FloatArray, rate_hz: float, smooth_s: float = 0.1) -> StrideCues:
    """The two placement cues of one stride (module doc).

    Parameters
    ----------
    q_nb
        (N, 4) attitude quaternions (scalar first, body to ENU) over the stride.
    acc_b
        (N, 3) specific force including gravity (m/s^2, device frame) at the same samples.
    rate_hz
        Sample rate (Hz).
    smooth_s
        Moving-average length (s) of the specific force.
    """
    q = np.asarray(q_nb, dtype=np.float64)
    a = np.asarray(acc_b, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or a.shape != (q.shape[0], 3):
        raise InputError("need (N, 4) attitudes and (N, 3) specific forces of the same stride", source="placement")
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    # Third row of C_nb(q): the navigation frame's up axis seen in the device frame.
    up_b = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
    k = min(max(int(round(smooth_s * rate_hz)), 1), a.shape[0])
    kernel = np.full(k, 1.0 / k)
    a_s = np.column_stack([np.convolve(a[:, i], kernel, mode="valid") for i in range(3)])
    n = np.linalg.norm(a_s, axis=1)
    a_s = a_s[n > 0] / n[n > 0, None]
    long_axis_up = abs(float(up_b[:, 1].sum())) / up_b.shape[0]
    mean_up = up_b.sum(axis=0)
    norm = float(np.linalg.norm(mean_up))
    up_mean = (float(mean_up[0] / norm), float(mean_up[1] / norm), float(mean_up[2] / norm)) if norm > 0 else None
    return StrideCues(swing_range_deg(up_b), swing_range_deg(a_s), long_axis_up, up_mean)


def classify_stride(cues: StrideCues, config: PlacementDetectConfig | None = None) -> str:
    """``hand``, ``swinging`` or ``pocket`` for one stride's cues (module doc)."""
    c = config or PlacementDetectConfig()
    if cues.tilt_swing_deg < c.held_max_swing_deg:
        return "hand"
    if cues.ratio < c.pendulum_max_ratio:
        return "swinging"
    return "pocket" if cues.long_axis_up >= math.cos(math.radians(c.pocket_max_axis_tilt_deg)) else "hand"


class PlacementDetector:
    """Online placement from per-stride labels, with a change after ``switch_strides`` agreeing strides; a pocket
    phone must have moved to be taken for a held one (module doc).
    """

    #: Weight of the older strides in the pocket's mean up direction.
    UP_DECAY = 0.8

    def __init__(self, config: PlacementDetectConfig | None = None) -> None:
        self.config = config or PlacementDetectConfig()
        self.placement: str | None = None
        self.candidate: str | None = None
        self.run = 0
        self.strides = 0
        self.pocket_up_b: list[float] | None = None     # stride-mean up direction in the pocket (device frame)
        self.held_in_pocket = 0                          # steady strides in a row kept in the pocket
        self.last_end_s: float | None = None             # end of the last stride's step (s)

    def _still_in_pocket(self, cues: StrideCues) -> bool:
        """A steady stride whose mean up direction is where the pocket's was (module doc)."""
        if self.placement != "pocket" or self.pocket_up_b is None or cues.up_b is None \
                or not cues.tilt_swing_deg < self.config.held_max_swing_deg:
            return False
        cos = float(np.dot(self.pocket_up_b, cues.up_b)) / max(float(np.linalg.norm(self.pocket_up_b)), 1e-12)
        return cos > math.cos(math.radians(self.config.moved_min_deg))

    def update(self, cues: StrideCues, t_start_s: float | None = None, t_end_s: float | None = None) -> str:
        """Add one stride, whose last step spans ``t_start_s`` to ``t_end_s`` (s; None: not known, no pause is
        seen); returns the current placement.
        """
        if t_start_s is not None and self.last_end_s is not None and t_start_s - self.last_end_s > self.config.pause_s:
            # A pause ends the walk: the next one settles afresh, without the pocket's hold (module doc).
            self.strides, self.held_in_pocket = 0, self.config.pocket_hold_strides
        if t_end_s is not None:
            self.last_end_s = t_end_s
        label = classify_stride(cues, self.config)
        if label == "hand" and self._still_in_pocket(cues) and self.held_in_pocket < self.config.pocket_hold_strides:
            label = "pocket"
            self.held_in_pocket += 1
        elif label == "pocket":
            self.held_in_pocket = 0
        if label == "pocket" and cues.up_b is not None:
            up = np.array(cues.up_b)
            if self.pocket_up_b is not None and self.placement == "pocket":
                up = self.UP_DECAY * np.array(self.pocket_up_b) + (1.0 - self.UP_DECAY) * up
            self.pocket_up_b = (up / float(np.linalg.norm(up))).tolist()
        self.strides += 1
        if self.placement is None or self.strides <= self.config.switch_strides:
            self.placement, self.candidate, self.run = label, None, 0
        elif label == self.placement:
            self.candidate, self.run = None, 0
        else:
            self.run = self.run + 1 if label == self.candidate else 1
            self.candidate = label
            if self.run >= self.config.switch_strides:
                self.placement, self.candidate, self.run = label, None, 0
        return self.placement

    def state(self) -> dict[str, Any]:
        return {"placement": self.placement, "candidate": self.candidate, "run": self.run, "strides": self.strides,
                "pocket_up_b": self.pocket_up_b, "held_in_pocket": self.held_in_pocket, "last_end_s": self.last_end_s}

    @classmethod
    def from_state(cls, d: dict[str, Any], config: PlacementDetectConfig | None = None) -> PlacementDetector:
        o = cls(config)
        o.placement, o.candidate, o.run = d["placement"], d["candidate"], int(d["run"])
        o.strides = int(d.get("strides", o.config.switch_strides))   # absent in states saved before the settling
        up = d.get("pocket_up_b")                                     # absent in states saved before it
        o.pocket_up_b = None if up is None else [float(v) for v in up]
        o.held_in_pocket = int(d.get("held_in_pocket", 0))
        last = d.get("last_end_s")                                    # absent in states saved before the pause rule
        o.last_end_s = None if last is None else float(last)
        return o
