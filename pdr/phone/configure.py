"""The phone pipeline's configuration from a user's choices, built in one place for ``pdr track``, the phone
evaluations (``pdr eval ipin|ms``) and the service's phone sessions.
"""

from __future__ import annotations

from dataclasses import replace

from pdr.phone.pipeline import PLACEMENT_GROUPS, PipelineConfig
from pdr.phone.step_length import StepLengthModel


def placement_group(placement: str | None) -> str:
    """The pipeline placement (``pocket``, ``hand``, ``torso``) of a device placement (:data:`pdr.recording.PLACEMENTS`,
    e.g. ``trouser_pocket_front``, ``bag``); ``auto`` (decided from the data) when unknown or not given.
    """
    return PLACEMENT_GROUPS.get(placement or "", "auto")


def pipeline_config(placement: str = "auto", *, attitude_method: str = "ukf", initial_floor: float = 0.0,
                    step_length: StepLengthModel | None = None, floor_height_m: float | None = None,
                    use_phone_orientation: bool = False, attitude_source: str = "filter") -> PipelineConfig:
    """The pipeline's configuration: the defaults with what the user chose.

    Parameters
    ----------
    placement
        ``auto``, ``pocket``, ``hand`` or ``torso``.
    attitude_method
        ``ukf`` or ``ekf``.
    initial_floor
        Floor number at the start of the recording.
    step_length
        A calibrated step-length model (``pdr calibrate``); default: the uncalibrated one.
    floor_height_m
        Height of a floor (m), kept as stated (not learnt from the flights walked); default:
        :class:`pdr.phone.floors.FloorConfig`'s.
    use_phone_orientation
        Use the phone's own attitude (``orientation`` stream) as a yaw measurement of our attitude filter.
    attitude_source
        ``filter`` (ours) or ``phone`` (the phone's attitude in place of ours: the evaluations' reference).
    """
    cfg = PipelineConfig(placement=placement, attitude_method=attitude_method, initial_floor=initial_floor,
                         use_phone_orientation=use_phone_orientation, attitude_source=attitude_source)
    if step_length is not None:
        cfg = replace(cfg, step_length=step_length)
    if floor_height_m is not None:
        cfg = replace(cfg, floors=replace(cfg.floors, floor_height_m=float(floor_height_m), learn_height=False))
    return cfg
