"""Plausibility checks of an uploaded batch before it is stored: device, units and time axis.

A batch that parses can still be wrong in ways that would silently corrupt its session: sensor values in
the wrong unit (an accelerometer in g, a barometer in Pa, a magnetometer in Gauss, where the batch format
promises SI), or timestamps from another clock (a batch days away from the rest of its session, or
spanning days by itself). Those are refused with 422 and a message naming the stream and what to fix;
the session is left as it was.

A location fix (``meta.location``) that is not one (not an object, a latitude off the globe, a time in ms) is refused
422 naming its field rather than ignored, which would also lose the session's origin as the place of the earth's
field.

The device's role picks the processing (phone PDR or foot navigation); a placement that contradicts it (a
``phone`` placed on the ``foot``, a shoe IMU placed in the ``hand``) is refused rather than sent to the wrong one.

Units are judged by the physics of :mod:`pdr.units` (median norm of specific force ~1 g, geomagnetic
field 25-65 uT, air pressure 300-1100 hPa); only a *confident* detection of another unit is refused, an
undecidable stream (free fall, a magnet nearby) is accepted. Angular rate cannot be judged on a short
batch and is not checked. A barometer sample outside 300-1100 hPa is no air pressure where people walk, whatever
the rest of its stream: refused naming the stream and the sample.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from sqlalchemy import Engine, func, select

from pdr import units
from pdr.recording import FOOT_ROLES, LOCATION_META, DeviceInfo, Recording
from server import db
from server.errors import APIError
from server.schemas import LOCATION_FIX, validate

#: Longest time span of one uploaded batch, s (a day: batches are seconds to minutes long).
MAX_BATCH_SPAN_S = 86_400.0
#: Farthest a batch may start from the time span of its session's other batches, s.
MAX_SESSION_GAP_S = 86_400.0

#: Client-chosen identifiers (batch ids): the pattern of session ids (:data:`server.schemas.CLIENT_ID`).
ID_PATTERN = re.compile(r"[A-Za-z0-9._:\-]{1,200}")
#: Longest device text fields (the ``devices`` columns are VARCHAR(200), which PostgreSQL enforces).
MAX_DEVICE_TEXT = 200

_SI = {"acc": "m/s^2", "mag": "uT", "pressure": "hPa"}
_DETECT = {"acc": units.detect_acc_unit, "mag": units.detect_mag_unit, "pressure": units.detect_pressure_unit}
_FAMILY = {"acc": "acc", "acc_uncal": "acc", "gravity": "acc", "mag": "mag", "mag_uncal": "mag", "baro": "pressure"}



def check_device(d: DeviceInfo) -> None:
    """422 if the device's placement contradicts its role (phone PDR and foot navigation need their own sensor)."""
    foot_role = d.role in FOOT_ROLES
    if d.is_foot and not foot_role:
        raise APIError(422, f"device role '{d.role}' with placement 'foot': a shoe IMU's batches need role "
                            f"{' or '.join(FOOT_ROLES)} (foot navigation), phone PDR cannot use them; batch not stored",
                       details={"field": "device.role"})
    if foot_role and d.placement not in (None, "foot"):
        raise APIError(422, f"device role '{d.role}' with placement '{d.placement}': a phone's batches need role "
                            f"'phone' (phone PDR), foot navigation cannot use them; batch not stored",
                       details={"field": "device.placement"})


def check_units(recording: Recording) -> None:
    """422 if a stream's values are confidently in a non-SI unit (said first: a barometer in Pa is also beyond any
    sensor in hPa, and the unit is what the client must fix) or physically impossible.
    """
    for kind, stream in recording.streams.items():
        family = _FAMILY.get(kind)
        checks_unit = family is not None and len(stream) > 0 and not (kind == "gravity" and len(stream) < 2)
        if family is not None and checks_unit:
            detected = _DETECT[family](stream.values)
            if detected is not None and detected != _SI[family]:
                raise APIError(422, f"stream '{kind}' looks like {detected}, but batches carry {_SI[family]} "
                                    f"(multiply by {units._UNITS_OF[family][detected]:g}); batch not stored",
                               details={"field": f"streams.{kind}.values", "detected_unit": detected})
        limit = units.MAX_ABS_SI.get(kind)        # beyond any sensor: the readers' limits
        if limit is not None and len(stream):
            i = _first_sample(np.abs(stream.values) > limit)
            if i is not None:
                raise APIError(422, f"stream '{kind}' sample {i} holds a value of magnitude "
                                    f"{float(np.abs(stream.values[i]).max()):.3g}, beyond any sensor (limit {limit:g} "
                                    "in SI units); batch not stored",
                               details={"field": f"streams.{kind}.values[{i}]", "index": i})
        if family == "pressure" and checks_unit:
            _check_air_pressure(kind, stream.values)


def _check_air_pressure(kind: str, values: np.ndarray) -> None:
    """422 naming the stream and the first sample that is no air pressure where people walk
    (:data:`pdr.units.AIR_PRESSURE_HPA`): a barometer's -5, 0 or 5000 hPa would be taken for an altitude kilometres
    off, and the floors of the whole session with it.
    """
    lo, hi = units.AIR_PRESSURE_HPA
    i = _first_sample((values < lo) | (values > hi))
    if i is not None:
        raise APIError(422, f"stream '{kind}' sample {i}: {float(np.ravel(values[i])[0]):g} hPa is no air pressure "
                            f"where people walk ({lo:g}-{hi:g} hPa); batch not stored",
                       details={"field": f"streams.{kind}.values[{i}]", "index": i})


def _first_sample(bad: np.ndarray) -> int | None:
    """Index of the first sample (row) of a stream with a ``bad`` value, None when there is none."""
    rows = np.flatnonzero(bad.reshape(len(bad), -1).any(axis=1))
    return int(rows[0]) if rows.size else None


def check_location(recording: Recording) -> None:
    """422 naming the field (``meta.location.lat_deg``, ...) if the recording's location fix is not a
    :data:`server.schemas.LOCATION_FIX` (whose numbers are finite, :func:`server.schemas.validate`); nothing without
    one.
    """
    if LOCATION_META not in recording.meta:
        return
    fix = recording.meta[LOCATION_META]
    validate({"meta": {LOCATION_META: fix}}, {"properties": {"meta": {"properties": {LOCATION_META: LOCATION_FIX}}}},
             "batch")


def check_span(t_first_ns: int, t_last_ns: int, max_span_s: float = MAX_BATCH_SPAN_S) -> None:
    """422 naming ``streams.*.t_ns`` if the batch's first and last sample (ns) are more than ``max_span_s`` apart."""
    span_s = (t_last_ns - t_first_ns) / 1e9
    if span_s > max_span_s:
        span = f"{span_s / 86400:.1f} days" if span_s >= 86400 else f"{span_s:.0f} s"
        raise APIError(422, f"the batch's timestamps span {span} (at most {max_span_s:g} s); a batch covers seconds "
                            f"to minutes (timestamps from another clock or another unit?); batch not stored",
                       details={"field": "streams.*.t_ns"})


def check_time(engine: Engine, session_id: str, role: str, payload_format: str, t_first_ns: int,
               t_last_ns: int) -> None:
    """422 if the batch spans more than a day (:func:`check_span`), or lies more than a day away from the session's
    other batches of the same device and format (each device has its own clock).
    """
    check_span(t_first_ns, t_last_ns)
    b = db.batches
    with engine.connect() as conn:
        lo, hi = conn.execute(select(func.min(b.c.t_first_ns), func.max(b.c.t_last_ns))
                              .where(b.c.session_id == session_id, b.c.device_role == role,
                                     b.c.payload_format == payload_format)).one()
    if lo is None or hi is None:
        return
    gap_s = max(lo - t_last_ns, t_first_ns - hi, 0) / 1e9
    if gap_s > MAX_SESSION_GAP_S:
        raise APIError(422, f"the batch is {gap_s / 86400:.1f} days away from the session's other batches "
                            f"(clock reset, or a batch of another session?); batch not stored",
                       details={"field": "streams.*.t_ns"})


def check_batch(engine: Engine, session_id: str, payload_format: str, recording: Recording, t_first_ns: int,
                t_last_ns: int) -> None:
    """Every plausibility check of a batch about to be stored in ``session_id``."""
    check_device(recording.device)
    check_units(recording)
    check_location(recording)
    check_time(engine, session_id, recording.device.role, payload_format, t_first_ns, t_last_ns)


def check_identity(engine: Engine, session_id: str, batch_id: str, labelled_session: Any,
                   recording: Recording) -> None:
    """422 for a batch id or device fields that are not plain identifiers of bounded length; 409 for a batch
    labelled (its ``session_id``) for another of the user's sessions, i.e. sent to the wrong session.
    """
    if not ID_PATTERN.fullmatch(batch_id):
        raise APIError(422, "'batch_id' must be 1 to 200 letters, digits or . _ : - characters",
                       details={"field": "batch_id"})
    dev = recording.device
    for field, value in (("device_id", dev.device_id), ("model", dev.model)):
        if len(value or "") > MAX_DEVICE_TEXT:
            raise APIError(422, f"'device.{field}' is longer than {MAX_DEVICE_TEXT} characters",
                           details={"field": f"device.{field}"})
    if not isinstance(labelled_session, str) or not labelled_session:
        return
    s = db.sessions
    with engine.connect() as conn:
        own = conn.execute(select(s.c.user_id, s.c.client_session_id).where(s.c.id == session_id)).one()
        if labelled_session == own.client_session_id:
            return
        other = conn.execute(select(s.c.id).where(s.c.user_id == own.user_id,
                                                 s.c.client_session_id == labelled_session)).first()
    if other is not None:
        raise APIError(409, f"the batch is labelled for your session '{labelled_session}', not this one; "
                            "send it to that session; batch not stored", details={"field": "session_id"})
