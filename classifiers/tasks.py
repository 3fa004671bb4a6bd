"""The classification tasks: which classes, which labels of the data map to them, which features.

* ``motion_mode``: how the person moves (stationary, walking, running, stairs up/down, elevator, escalator,
  vehicle, plus jumping, sitting and car entry/exit where the data has them); labels from
  ``truth.modes`` (or derived from floor changes for IPIN logs, :mod:`classifiers.datasets`).
* ``placement``: where the phone is carried (``DeviceInfo.placement``), from walking data.
* ``landmark``: the five motion states of seed 003 Table 1 (stairs, elevator, escalator, walking, standing).

Features that describe how the phone is held (the gravity direction in the body frame) are used only for
placement: motion-mode and landmark models must not learn one subject's pocket orientation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from pdr.errors import InputError


@dataclass(frozen=True)
class Task:
    """One classification task.

    Parameters
    ----------
    name
        Task name used on the command line and in model cards.
    classes
        Every class the task may output (a model uses those present in its training data).
    label_map
        Dataset label -> task class; labels absent from the map and from ``classes`` are dropped.
    label_source
        ``modes`` (time intervals of ``truth.modes``) or ``placement`` (``device.placement``).
    feature_groups
        Feature groups (:data:`classifiers.features.FEATURE_GROUPS`) the task may use.
    mean_dwell_s
        Mean time in one class for the Markov smoothing (:mod:`classifiers.sequence`).
    """

    name: str
    classes: tuple[str, ...]
    label_map: Mapping[str, str]
    label_source: str
    feature_groups: tuple[str, ...]
    mean_dwell_s: float

    def map_label(self, label: str | None) -> str | None:
        """Task class of a dataset label, or None when the task does not use it."""
        if label is None or label == "":
            return None
        mapped = self.label_map.get(label, label)
        return mapped if mapped in self.classes else None


_MOTION_GROUPS = ("acc", "gait", "gyro", "gyro_pitch", "coning", "pitch", "stride", "elevator", "mag", "baro")

TASKS: Mapping[str, Task] = MappingProxyType({
    "motion_mode": Task(
        name="motion_mode",
        classes=("stationary", "walking", "running", "stairs_up", "stairs_down", "elevator", "escalator",
                 "vehicle", "jumping", "sitting", "car_step_in", "car_step_out"),
        label_map=MappingProxyType({"standing": "stationary", "stand": "stationary", "jogging": "running",
                                    "elevator_up": "elevator", "elevator_down": "elevator",
                                    "escalator_up": "escalator", "escalator_down": "escalator",
                                    "driving": "vehicle"}),
        label_source="modes",
        feature_groups=_MOTION_GROUPS,
        # Chosen among 10/20/40/80 s by MobiFall leave-one-subject-out macro-F1 (no separate validation set).
        mean_dwell_s=40.0,
    ),
    "placement": Task(
        name="placement",
        classes=("trouser_pocket_front", "trouser_pocket_back", "trouser_pocket", "hand", "bag", "torso",
                 "neck", "armband"),
        label_map=MappingProxyType({}),
        label_source="placement",
        feature_groups=("acc", "gait", "gyro", "gyro_pitch", "pitch", "orientation"),
        mean_dwell_s=120.0,
    ),
    "landmark": Task(
        name="landmark",
        classes=("stairs", "elevator", "escalator", "walking", "standing"),
        label_map=MappingProxyType({"stairs_up": "stairs", "stairs_down": "stairs", "elevator_up": "elevator",
                                    "elevator_down": "elevator", "escalator_up": "escalator",
                                    "escalator_down": "escalator", "stationary": "standing"}),
        label_source="modes",
        # Landmarks are events with context (seed 003 Sec. 3): the ctx_* groups look beyond the window.
        feature_groups=_MOTION_GROUPS + ("ctx_acc", "ctx_mag", "ctx_baro"),
        mean_dwell_s=10.0,
    ),
})


def get_task(name: str) -> Task:
    """The task called ``name``; :class:`InputError` listing the known tasks otherwise."""
    try:
        return TASKS[name]
    except KeyError:
        raise InputError(f"unknown task '{name}'; expected one of {sorted(TASKS)}", field="task") from None
