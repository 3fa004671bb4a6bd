"""Per-session processing options: what ``pdr track --site/--calibration`` and ``pdr foot --zaru/--imu-samples``
set offline.

A client gives them when it creates the session (``processing`` in the JSON body, or a ``processing`` form
field holding that JSON next to an uploaded file), or replaces them later with ``PUT .../processing``, which
rebuilds the session's results; they are checked first -- a bad site or calibration is refused with the field
it names, before anything is stored -- and kept in the session's ``meta``. Every
processor of the session reads them from its :class:`~server.processing.SessionContext`:

* ``site``: the site description of ``pdr track --site`` (landmarks in the track's local east/north frame,
  floor height, optional declination and building grid); detected landmarks then correct heading and position;
* ``site_id``: a site uploaded with ``POST /api/v1/sites`` (:mod:`server.sites`): its floor altitudes and landmarks
  as ``site`` gives them, and with ``start`` (``[E, N]`` or ``[E, N, FLOOR]``, m in the site's frame; the floor
  defaults to the site's only one) the map matcher on its floor plans, online, as ``pdr track --site --start``;
* ``calibration``: the file ``pdr calibrate`` writes (``{"step_length": {...}}``), the walker's step-length
  model;
* ``foot``: ``{"zaru": true}`` turns on the zero angular-rate update of the shoe IMUs' gyroscope bias,
  ``{"imu_samples": "interval"}`` takes their samples as means over the interval ending at each
  (``pdr foot --imu-samples``; default ``"instant"``; :class:`pdr.foot.zupt.ZuptConfig`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from pdr.errors import InputError
from pdr.foot.zupt import ZuptConfig
from pdr.phone.landmarks import Site
from pdr.phone.step_length import StepLengthModel
from server.schemas import check_representable

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
    site_id: str | None = None
    start: tuple[float, ...] | None = None

    @classmethod
    def from_json(cls, d: Any) -> ProcessingOptions:
        """Options from the client's ``processing`` object; :class:`InputError` naming the bad field."""
        if d is None:
            return cls()
        if not isinstance(d, dict):
            raise InputError("must be an object", field="processing")
        unknown = sorted(set(d) - {"site", "site_id", "start", "calibration", "foot"})
        if unknown:
            raise InputError(f"unknown option(s) {unknown}; expected site, site_id, start, calibration, foot",
                             field="processing")
        site_id, start = _site_id(d.get("site_id")), _start(d.get("start"))
        if site_id is not None and d.get("site") is not None:
            raise InputError("give either 'site' (a description) or 'site_id' (an uploaded site), not both",
                             field="processing.site_id")
        if start is not None and site_id is None:
            raise InputError("a start needs 'site_id', the uploaded site whose frame it is in",
                             field="processing.start")
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
        return cls(site, model, bool(foot.get("zaru", False)), foot.get("imu_samples") == "interval", site_id, start)

    @classmethod
    def from_text(cls, text: str | None) -> ProcessingOptions:
        """Options from the JSON text of a form field (``None`` or empty: none)."""
        if not text:
            return cls()
        try:
            options = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON ({exc})", field="processing") from None
        except RecursionError:  # the JSON parser recurses per nesting level
            raise InputError("JSON nested too deeply", field="processing") from None
        check_representable(options, text.encode("utf-8", "surrogatepass"), "processing", prefix="processing")
        return cls.from_json(options)

    def to_json(self) -> dict[str, Any]:
        """The options as stored and shown (only those set)."""
        out: dict[str, Any] = {}
        if self.site is not None:
            out["site"] = self.site.to_dict()
        if self.site_id is not None:
            out["site_id"] = self.site_id
        if self.start is not None:
            out["start"] = [*self.start[:2], int(self.start[2])] if len(self.start) == 3 else list(self.start)
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


def _site_id(v: Any) -> str | None:
    if v is None:
        return None
    if not isinstance(v, str) or not 0 < len(v) <= 64:
        raise InputError("site_id must be the id string POST /api/v1/sites answered", field="processing.site_id")
    return v


def _start(v: Any) -> tuple[float, ...] | None:
    """``[E, N]`` or ``[E, N, FLOOR]`` (m, site frame; an integer floor)."""
    if v is None:
        return None
    ok = (isinstance(v, list) and len(v) in (2, 3)
          and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in v)
          and (len(v) == 2 or float(v[2]).is_integer()))
    if not ok:
        raise InputError("start must be [E, N] or [E, N, FLOOR]: metres in the site's frame and an integer floor",
                         field="processing.start")
    return tuple(float(x) for x in v)


def site_id_of(meta: dict[str, Any]) -> str | None:
    """The uploaded site a session's ``meta`` names (its processor then needs the session's copy of it)."""
    opts = meta.get(META_KEY)
    return opts.get("site_id") if isinstance(opts, dict) and isinstance(opts.get("site_id"), str) else None


def map_matched(meta: dict[str, Any]) -> bool:
    """Whether a session's ``meta`` asks for online map matching (an uploaded site and a start)."""
    opts = meta.get(META_KEY)
    return site_id_of(meta) is not None and isinstance(opts, dict) and opts.get("start") is not None
