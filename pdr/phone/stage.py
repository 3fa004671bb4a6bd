"""The stage protocol of the phone pipeline and the typed data passed between its per-step stages.

Every stage of :class:`pdr.phone.pipeline.PdrPipeline` keeps its own state between batches and spells its
serialisation one way: ``state() -> dict`` (JSON-serialisable) and ``from_state(d, ...)`` (a classmethod taking the
configuration the state does not hold). The per-step stages take a :class:`StepWindow` (one step's samples) and
give typed results (:class:`StepHeading`, :class:`pdr.phone.heading.HeadingEstimate`,
:class:`pdr.phone.events.StepEvent`).

A :class:`StepObserver` watches the confirmed steps and their samples without changing anything.

A stage that is not part of the pipeline (a map matcher, a learned step-length correction) plugs in as a
:class:`StepStage`: ``PdrPipeline(..., stages=[stage])``. It sees every step event after the PDR position update,
may correct the track (:class:`pdr.phone.track.TrackState`) and returns the event to emit; its state is saved under
``state["stages"][stage.name]`` and restored by ``PdrPipeline.from_state(d, stages=[fresh_stage])`` through
``fresh_stage.from_state(saved)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from pdr.frames import wrap_angle_float
from pdr.phone.events import PipelineEvent, StepEvent
from pdr.phone.heading import HeadingEstimate
from pdr.phone.history import SampleHistory
from pdr.phone.track import TrackState

FloatArray = NDArray[np.float64]


@runtime_checkable
class Stage(Protocol):
    """What every stage has: its JSON-serialisable state (restored by the class's ``from_state``)."""

    def state(self) -> dict[str, Any]: ...


@runtime_checkable
class StepStage(Protocol):
    """A stage plugged into the pipeline after the PDR position update (module doc).

    ``name`` keys its saved state; :meth:`step` gets each step event and the track, may move the track (e.g.
    ``track.fix``) and returns the step event to emit (``dataclasses.replace`` of the one given) plus any further
    events of its own; :meth:`from_state` returns a stage like this one with a saved state.
    """

    name: str

    def step(self, event: StepEvent, track: TrackState) -> tuple[StepEvent, list[PipelineEvent]]: ...

    def state(self) -> dict[str, Any]: ...

    def from_state(self, d: dict[str, Any]) -> StepStage: ...


@runtime_checkable
class StepObserver(Protocol):
    """A watcher of the steps the detector confirms (e.g. an evaluation's probe): ``PdrPipeline(...,
    observers=[o])`` calls ``o.confirmed(s, e, history)`` with each step's grid indices ``[s, e)`` and the sample
    history before the pipeline processes the step. It reads, never changes, the history; it is not part of the
    pipeline's saved state.
    """

    def confirmed(self, s: int, e: int, history: SampleHistory) -> None: ...


@dataclass(frozen=True)
class StepWindow:
    """Typed input of the heading stages: one step's samples.

    Attributes
    ----------
    s, e
        Grid sample indices of the step, ``[s, e)``.
    history
        The sample history (attitude, specific force in ENU, ... by grid index).
    q, f_n
        Attitudes ``q_nb`` (N, 4) and specific force in ENU (N, 3, m/s^2) over the step.
    axis
        RMPCA walking axis over the step (rad, a line).
    att_q, att_p
        The attitude filter's quaternion (4,) and covariance (4, 4) when the step was confirmed.
    """

    s: int
    e: int
    history: SampleHistory
    q: FloatArray
    f_n: FloatArray
    axis: float
    att_q: FloatArray
    att_p: FloatArray


@dataclass(frozen=True)
class StepHeading:
    """Typed output of a heading stage: the step's heading estimate (rad, rad^2; second UKF for a pocket), the RMPCA
    direction ``psi0`` (rad) it was resolved to, the walking axis used (rad), the scatter matrix ``m1`` (3, 3) of
    eq. 26 in the device frame of ``att_q`` (zero where no landmark can use it), and whether the 180-degree vote
    reversed the walking direction (the step waiting for output must then be reversed too). ``pocket_side``: a
    walking trouser-pocket stride's side evidence (:meth:`pdr.phone.walking_direction.PocketSide.mean_corr`), None
    for other carriages and running strides.
    """

    est: HeadingEstimate
    psi0: float
    axis: float
    m1: FloatArray
    reversed_direction: bool = False
    pocket_side: float | None = None


@dataclass
class PendingStep:
    """A processed step waiting one step for output (the neighbour-step correction of its landmark label needs the
    next step's): grid indices, times (s), patterns, heading (rad, rad^2), RMPCA direction and axis (rad), label,
    height (m) and floor, the scatter matrix and the attitude it is expressed in, the detector's peak, and the
    heading smoother's inputs (gyro yaw (rad), up time (s), gyro bias (rad/s), the pocket's side evidence). Saved as
    a plain dict.
    """

    s: int
    e: int
    t_start: float
    t_end: float
    pats: list[float]
    yaw: float
    var: float
    psi0: float
    axis: float
    mode: str
    up: float
    floor: float
    m1: list[list[float]]
    q1: list[float]
    peak: float
    gyro_yaw: Any = None
    up_time: Any = None
    gyro_bias: list[float] | None = None
    pocket_side: float | None = None

    def reverse(self) -> None:
        """Turn the step's heading and direction by 180 degrees (the vote refuted the direction it was resolved to)."""
        self.yaw = wrap_angle_float(self.yaw + math.pi)
        self.psi0 = wrap_angle_float(self.psi0 + math.pi)

    def state(self) -> dict[str, Any]:
        return dict(self.__dict__)

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> PendingStep:
        # The gyro yaw, up time and gyro bias are absent in states saved before the heading smoother, the pocket's
        # side before the smoother split the turn lag by it.
        return cls(**{**{"gyro_yaw": None, "up_time": None, "gyro_bias": None, "pocket_side": None}, **d})
