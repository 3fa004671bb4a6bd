"""Foot-mounted navigation of one shoe IMU (role ``left_foot`` / ``right_foot``) as a session processor.

Two inputs, one per session role (not mixed):

* raw foot IMU batches: :class:`pdr.foot.online.OnlineFootNavigator` (the step-wise ZUPT-aided INS of
  ``pdr foot --method stepwise``); one track row and one ``step`` event per reset: a stride of this foot, or, mode
  ``standing``, a reset while it stands (:attr:`pdr.foot.online.FootStep.stride`; not counted as a step); the
  provisional tail (:meth:`FootProcessor.tail`) is what the end of the recording would add (with, at the last
  sample, a stride that ended after the last reset; the next batch replaces the tail, so it is counted once), so
  the track equals ``pdr foot --method stepwise --per-step`` on the same data at any time (with ``--zaru on`` or
  ``--imu-samples interval`` when the session's processing options, :mod:`server.processing_options`, ask for it);
* step-wise dead-reckoning summaries (:mod:`pdr.foot.summaries`, uploaded to ``POST .../steps``): composed with
  eq. 7 by :class:`pdr.foot.stepwise.StepwiseDeadReckoning`; a row per summary.

Track rows: ``t_s`` on the device's clock (s), ENU position from the start (m), ``heading_deg`` compass
(clockwise from north), ``step_length_m`` the horizontal length of the stride ``hypot(dp_x, dp_y)``, mode
``walking``, no floor. Step events carry the step's increment (``data.increment``: sample index, ``dp_m``,
``dpsi_rad``, 4x4 ``cov``), from which :mod:`server.fused_feet` fuses the two feet of a session
(:mod:`server.foot_steps` reads and writes it).
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.foot.online import FootStep, OnlineFootNavigator
from pdr.foot.stepwise import StepwiseDeadReckoning
from pdr.foot.summaries import StepSummaryBatch
from pdr.frames import yaw_to_heading_deg
from pdr.recording import Recording
from pdr.step_increment import StepIncrement
from server.foot_steps import increment_to_json, mode_of
from server.processing import ProcessorOutput, SessionContext
from server.processing_options import session_options
from server.store import EventRow, TrackRow


def _add_step(out: ProcessorOutput, t_s: float, pos_n: Any, yaw: float, inc: StepIncrement) -> None:
    """Append a step's track row and its step event (the increment; joined to the row by its step index); mode
    ``walking``, or ``standing`` for a reset that closes no stride (``inc.stride`` False, :func:`mode_of`).
    """
    heading = float(yaw_to_heading_deg(yaw))
    length = float(math.hypot(float(inc.dp[0]), float(inc.dp[1])))
    mode = mode_of(inc.stride)
    out.events.append(EventRow("step", float(t_s), label=mode, value=length, step=len(out.track),
                               data={"heading_deg": heading, "dpsi_deg": math.degrees(float(inc.dpsi)),
                                     "dz_m": float(inc.dp[2]), "increment": increment_to_json(inc)}))
    out.track.append(TrackRow(float(t_s), float(pos_n[0]), float(pos_n[1]), float(pos_n[2]), None, heading, length,
                              mode))


def _output(steps: list[FootStep], warnings: list[str]) -> ProcessorOutput:
    out = ProcessorOutput(warnings=warnings)
    for s in steps:
        _add_step(out, s.t_s, s.pos_n, s.yaw, s.increment)
    return out


class FootProcessor:
    """Online foot navigation for one shoe IMU of a session; state = JSON of the navigator or dead reckoning."""

    def __init__(self, ctx: SessionContext, state: bytes | None) -> None:
        self.role = ctx.role
        self.meta = ctx.meta
        self.navigator: OnlineFootNavigator | None = None
        self.dr: StepwiseDeadReckoning | None = None
        self.last_t_s: float | None = None
        if state:
            d = json.loads(state)
            if d.get("navigator") is not None:
                self.navigator = OnlineFootNavigator.from_dict(d["navigator"])
            if d.get("dr") is not None:
                r = d["dr"]
                self.dr = StepwiseDeadReckoning(np.array(r["pos_n"]), r["heading"], np.array(r["cov"]))
                self.last_t_s = r["last_t_s"]

    def update(self, recording: Recording) -> ProcessorOutput:
        """Raw foot IMU samples."""
        if self.dr is not None:
            raise InputError(f"the {self.role} of this session sends step summaries; raw IMU batches cannot be "
                             "mixed in", source=recording.source or None)
        if self.navigator is None:
            # The session's options are read once, when the navigator starts; its saved state keeps them.
            self.navigator = OnlineFootNavigator(zupt=session_options(self.meta).zupt_config())
        steps = self.navigator.update(recording)
        return _output(steps, self.navigator.take_warnings())

    def update_steps(self, batch: StepSummaryBatch) -> ProcessorOutput:
        """Step-wise dead-reckoning summaries (eq. 7)."""
        if self.navigator is not None:
            raise InputError(f"the {self.role} of this session sends raw IMU batches; step summaries cannot be "
                             "mixed in")
        if batch.role != self.role:
            raise InputError(f"summaries of the {batch.role} stored under the {self.role}", field="device.role")
        if self.dr is None:
            self.dr = StepwiseDeadReckoning()
        out = ProcessorOutput()
        for inc in batch.steps:
            if self.last_t_s is not None and inc.t_s <= self.last_t_s:
                out.warnings.append(f"{self.role} step at {inc.t_s:.3f} s is not after the previous one "
                                    f"({self.last_t_s:.3f} s): ignored")
                continue
            self.dr.update(inc)
            self.last_t_s = float(inc.t_s)
            _add_step(out, inc.t_s, self.dr.pos_n, self.dr.heading, inc)
        return out

    def tail(self) -> ProcessorOutput:
        """What ending the session now would add: the steps in the last samples (raw IMU input)."""
        if self.navigator is None:
            return ProcessorOutput()
        copy = OnlineFootNavigator.from_dict(self.navigator.to_dict())
        return _output(copy.finish(), [])

    def to_bytes(self) -> bytes:
        dr = None if self.dr is None else {"pos_n": self.dr.pos_n.tolist(), "heading": self.dr.heading,
                                           "cov": self.dr.cov.tolist(), "last_t_s": self.last_t_s}
        return json.dumps({"navigator": None if self.navigator is None else self.navigator.to_dict(),
                           "dr": dr}).encode()
