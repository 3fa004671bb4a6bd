"""Per-session processing options: what ``pdr track --site/--calibration`` and ``pdr foot --zaru/--imu-samples``
set offline.

A client gives them when it creates the session (``processing`` in the JSON body, or a ``processing`` form
field holding that JSON next to an uploaded file), or replaces them later with ``PUT .../processing``, which
rebuilds the session's results; they are checked first -- a bad site or calibration is refused with the field
it names, before anything is stored -- and kept in the session's ``meta``. Every
processor of the session reads them from its :class:`~server.processing.SessionContext`:

* ``site``: the site description of ``pdr track --site`` (landmarks in the track's local east/north frame,
  floor height, optional declination and building grid); detected landmarks then correct heading and position;
* ``calibration``: the file ``pdr calibrate`` writes (``{"step_length": {...}}``), the walker's step-length
  model;
* ``foot``: ``{"zaru": true}`` turns on the zero angular-rate update of the shoe IMUs' gyroscope bias,
  ``{"imu_samples": "interval"}`` takes their samples as means over the interval ending at each
  (``pdr foot --imu-samples``; default ``"instant"``; :class:`pdr.foot.zupt.ZuptConfig`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from pdr.errors import InputError
from pdr.foot.zupt import ZuptConfig
from pdr.phone.landmarks import Site
from pdr.phone.step_length import StepLengthModel

#: Key of the options in the session's ``meta``.
META_KEY = "processing"
#: Values of ``foot.imu_samples`` (``pdr foot --imu-samples``).
IMU_SAMPLES = ("instant", "interval")


@dataclass(frozen=True)
class ProcessingOptions:
    """Checked processing options of one session (all optional)."""

    site: Site | None = None
    step_length: StepLengthModel | None = None
    foot_zaru: bool = False
    foot_interval_samples: bool = False

    @classmethod
    def from_json(cls, d: Any) -> ProcessingOptions:
        """Options from the client's ``processing`` object; :class:`InputError` naming the bad field."""
        if d is None:
            return cls()
        if not isinstance(d, dict):
            raise InputError("must be an object", field="processing")
        unknown = sorted(set(d) - {"site", "calibration", "foot"})
        if unknown:
            raise InputError(f"unknown option(s) {unknown}; expected site, calibration, foot", field="processing")
        site = Site.from_dict(d["site"], source="processing.site") if d.get("site") is not None else None
        model = None
        cal = d.get("calibration")
        if cal is not None:
            if not isinstance(cal, dict) or not isinstance(cal.get("step_length"), dict):
                raise InputError("expected the object `pdr calibrate` writes, with a 'step_length' object",
                                 field="processing.calibration")
            try:
                model = StepLengthModel.from_dict(cal["step_length"])
            except InputError as exc:
                field = f"processing.calibration.step_length.{exc.field}" if exc.field else "processing.calibration"
                raise InputError(exc.message, field=field) from None
        foot = d.get("foot") or {}
        if (not isinstance(foot, dict) or set(foot) - {"zaru", "imu_samples"}
                or not isinstance(foot.get("zaru", False), bool)
                or foot.get("imu_samples", "instant") not in IMU_SAMPLES):
            raise InputError("expected {\"zaru\": true|false, \"imu_samples\": \"instant\"|\"interval\"}",
                             field="processing.foot")
        return cls(site, model, bool(foot.get("zaru", False)), foot.get("imu_samples") == "interval")

    @classmethod
    def from_text(cls, text: str | None) -> ProcessingOptions:
        """Options from the JSON text of a form field (``None`` or empty: none)."""
        if not text:
            return cls()
        try:
            return cls.from_json(json.loads(text))
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON ({exc})", field="processing") from None
        except RecursionError:  # the JSON parser recurses per nesting level
            raise InputError("JSON nested too deeply", field="processing") from None

    def to_json(self) -> dict[str, Any]:
        """The options as stored and shown (only those set)."""
        out: dict[str, Any] = {}
        if self.site is not None:
            out["site"] = self.site.to_dict()
        if self.step_length is not None:
            out["calibration"] = {"step_length": self.step_length.to_dict()}
        foot: dict[str, Any] = {}
        if self.foot_zaru:
            foot["zaru"] = True
        if self.foot_interval_samples:
            foot["imu_samples"] = "interval"
        if foot:
            out["foot"] = foot
        return out

    def zupt_config(self) -> ZuptConfig:
        """The shoe IMUs' ZUPT-INS settings these options ask for."""
        return ZuptConfig(zaru=self.foot_zaru, interval_samples=self.foot_interval_samples)


def session_options(meta: dict[str, Any]) -> ProcessingOptions:
    """The options kept in a session's ``meta`` (none when absent)."""
    return ProcessingOptions.from_json(meta.get(META_KEY))
