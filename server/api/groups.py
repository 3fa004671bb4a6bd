"""Groups: cooperative localization of several agents by the server as fusion centre (seed 001 Sec. 3.3-4).

An agent (a person with two shoe IMUs and a ranging radio) joins a group with its initial pose, then uploads
batches of events: step-wise dead-reckoning summaries of each foot and range measurements (between agents, to
anchors, position fixes, pressure differences). The upload's events are validated against :data:`EVENT` (the
OpenAPI document's ``GroupUpload``); :mod:`pdr.fusion.measurements` reads them. The API names the feet as
sessions do, ``left_foot``/``right_foot``, everywhere: a group's ``config.feet``, step events, corrections and
tracks (the fusion library's ``left``/``right`` are translated at this boundary, :data:`server.feet.FOOT_SIDES`;
the old names are refused with 422 naming the field and the new name). The server buffers the events, applies them
in time order to the
group's joint state (:class:`pdr.fusion.group.Group`) and answers each upload with the correction for the
uploading agent. Agents that lost contact upload their buffered summaries when they return. An upload whose
ranges are older than the fusion horizon (they could never be fused) is refused with 422 ``stale_range``,
listing them and why; nothing of it is kept.

An agent joined with a ``session_id`` takes its steps from that session as its batches are processed
(:mod:`server.group_feed`); its uploads then carry its ranges and other measurements, not steps.

Time: every ``t_s`` of the group API is on the group's common clock (s), which the clients choose (e.g. Unix time,
or seconds from a mission's start). A session's steps are on its shoe's own clock (``t_ns / 1e9`` of the
samples, the ``t_s`` of the session's foot track rows); an agent joined with a ``session_id`` gives
``clock_offset_s``, group time = session time + ``clock_offset_s`` (default 0: the shoe stamps its samples on the
group's clock).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

from flask import Blueprint, Response, current_app, jsonify, request

from pdr.errors import InputError
from pdr.fusion.centre import FusionConfig
from pdr.fusion.group import Group
from pdr.fusion.measurements import MAX_COORDINATE_M, MAX_STEP_M, MAX_VARIANCE, StepSummary, parse_event
from pdr.units import AIR_PRESSURE_HPA
from server.api import current_user, json_body, no_query_parameters, only_query_parameters, services
from server.api.results import parse_since
from server.errors import APIError
from server.feet import FOOT_SIDES, ROLE_SIDES, foot_role
from server.group_feed import feed_groups
from server.group_store import GroupStore
from server.schemas import validate

bp = Blueprint("groups", __name__, url_prefix="/api/v1/groups")

_NAME = {"type": "string", "minLength": 1, "maxLength": 200}
_NUMBER = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
#: A coordinate, distance or height of the group's local frame (m), within pdr.fusion.measurements.MAX_COORDINATE_M
#: either way (a position of 1e300 m overflowed the fusion and failed every later update of the group).
_METRES = {"type": "number", "minimum": -MAX_COORDINATE_M, "maximum": MAX_COORDINATE_M}
_POSITION3 = {"type": "array", "items": _METRES, "minItems": 3, "maxItems": 3}
_DISTANCE = {"type": "number", "minimum": 0, "maximum": MAX_COORDINATE_M}
#: A barometer's pressure (hPa): air pressure where people walk (pdr.units.AIR_PRESSURE_HPA).
_PRESSURE = {"type": "number", "minimum": AIR_PRESSURE_HPA[0], "maximum": AIR_PRESSURE_HPA[1]}

#: A foot of an agent: the sessions' device roles.
_FOOT = {"enum": list(FOOT_SIDES.values()), "description": "left_foot or right_foot (as in sessions)"}

_POSITIVE = {"type": "number", "exclusiveMinimum": 0}
#: Largest time (s) either way on a group's clock: 3000 years, any clock in seconds (Unix time is 1.7e9 s; Unix
#: milliseconds, 1.7e12, are another unit). A time of 1e300 s carried the group's clock with it and disabled the group;
#: within this bound, pdr.fusion.group refuses a jump of more than a day from the group's newest event.
MAX_TIME_S = 1e11
#: A measurement's standard deviation, m, and a variance (m^2, m rad, rad^2): at most pdr.fusion.measurements'
#: MAX_STEP_M and MAX_VARIANCE (100 m, its square; a 1e300 one broke the group's covariances).
_SIGMA_M = {"maximum": MAX_STEP_M}
_VARIANCE = {"type": "number", "minimum": -MAX_VARIANCE, "maximum": MAX_VARIANCE}
#: Most lattice points per axis a group may ask for: a sampled update costs their cube (25: 15 625 samples, 21 times
#: the default 9); 1001 took 19 GB at the first range, 100 000 failed every update of the group.
MAX_LATTICE_POINTS = 25
#: Largest horizontal distance of the feet a group may set, and largest offset of a joining agent's foot along any
#: axis, m (legs reach about 1.5 m); near the float range (1e160 m) the separation constraint overflowed and failed
#: every update of the group.
MAX_FEET_APART_M = 10.0
_NON_NEGATIVE = {"type": "number", "minimum": 0}
#: The fusion parameters (:class:`pdr.fusion.centre.FusionConfig`; every field optional, defaults there).
_CONFIG: dict[str, Any] = {
    "type": "object", "additionalProperties": False,
    "description": "fusion parameters (pdr.fusion.centre.FusionConfig); each omitted one takes its default",
    "properties": {
        "feet": {"type": "array", "items": _FOOT, "minItems": 1, "uniqueItems": True,
                 "description": "the feet of every agent (default both)"},
        "separation": {"type": "object", "additionalProperties": False,
                       "description": "dual-foot separation constraint (seed 001 eq. 13)", "properties": {
                           "gamma_xy": _POSITIVE | {"maximum": MAX_FEET_APART_M,
                                                    "description": "largest horizontal distance of the feet, m"},
                           "gamma_z": _POSITIVE | {"description": "largest vertical distance of the feet, m"},
                           "eta": {"type": "number", "minimum": 3, "description": "sigma-point spread"},
                           "speed_bound_mps": _NON_NEGATIVE | {"description": "widening for states apart in "
                                                                              "time, m/s"},
                           "grace_s": _NON_NEGATIVE | {"description": "time covered by gamma_xy/gamma_z, s"}}},
        "ranging": {"type": "object", "additionalProperties": False,
                    "description": "inter-agent range likelihood (eqs. 17-20)", "properties": {
                        "gamma_m": _NON_NEGATIVE | {"description": "uniform half-width gamma_r, m"},
                        "sigma_m": _POSITIVE | _SIGMA_M | {"description": "Cauchy scale sigma_r, m"}}},
        "lattice_points": {"type": "integer", "minimum": 2, "maximum": MAX_LATTICE_POINTS,
                           "description": "lattice points per axis (Algorithm 3); an update costs their cube"},
        "lattice_extent": _POSITIVE | {"description": "lattice half-width in prior standard deviations"},
        "robust": {"type": "boolean", "description": "false: the linearised Kalman range update (reference)"},
        "kalman_range_variance_m2": _POSITIVE | {"maximum": MAX_VARIANCE,
                                                 "description": "range variance of the Kalman reference, m^2"},
    },
}

CREATE_GROUP: dict[str, Any] = {
    "type": "object", "additionalProperties": False,
    "properties": {
        "name": {"type": "string", "maxLength": 200},
        "config": _CONFIG,
        "contact_timeout_s": {"type": "number", "exclusiveMinimum": 0},
        "max_range_age_s": {"type": "number", "exclusiveMinimum": 0},
    },
}

JOIN_GROUP: dict[str, Any] = {
    "type": "object", "additionalProperties": False, "required": ["agent", "pos0_n"],
    "properties": {
        "agent": _NAME,
        "session_id": {"type": "string", "maxLength": 36,
                       "description": "the id of one of the user's sessions: the agent takes its steps from "
                                      "its shoes as the session's batches are processed; the agent's uploads "
                                      "then carry no steps"},
        "clock_offset_s": {"type": "number",
                           "description": "with session_id: the group's clock less the session's (s; group time = "
                                          "session time + clock_offset_s; the session's clock is its shoes' own, "
                                          "the t_s of its foot track rows); default 0"},
        "pos0_n": _POSITION3,
        "heading0_deg": {"type": "number", "description": "compass heading, clockwise from north"},
        "cov0": {"type": "array", "items": {"type": "array", "items": _VARIANCE, "minItems": 4, "maxItems": 4},
                 "minItems": 4, "maxItems": 4, "description": "(4, 4) covariance of x, y, z (m) and yaw (rad); each "
                                                              f"entry at most {MAX_VARIANCE:g} either way"},
        "t_s": {"type": "number", "minimum": -MAX_TIME_S, "maximum": MAX_TIME_S,
                "description": "time of the initial pose (s, the group's common clock); default 0"},
        "foot_offsets_n": {"type": "array", "items": _VEC3 | {"items": {"type": "number", "minimum": -MAX_FEET_APART_M,
                                                                        "maximum": MAX_FEET_APART_M}},
                           "description": "each foot's offset from pos0_n (m, ENU), in the order of config.feet"},
    },
}

_COV4 = {"type": "array", "items": {"type": "array", "items": _NUMBER, "minItems": 4, "maxItems": 4},
         "minItems": 4, "maxItems": 4}
_T = {"type": "number", "minimum": -MAX_TIME_S, "maximum": MAX_TIME_S,
      "description": "time of the event (s, the group's common clock)"}
_MODEL = {"gamma_m": {"type": "number", "minimum": 0, "description": "bounded error (m)"},
          "sigma_m": {"type": "number", "minimum": 0, **_SIGMA_M, "description": "noise standard deviation (m)"}}


def _event(kind: str, description: str, required: list[str], properties: dict[str, Any]) -> dict[str, Any]:
    """The form of one event type, applied when ``type`` is ``kind`` (errors then name the field, not the type)."""
    return {"if": {"properties": {"type": {"const": kind}}},
            "then": {"description": description, "additionalProperties": False, "required": ["t_s", *required],
                     "properties": {"type": {"const": kind}, "t_s": _T, **properties}}}


#: One event of an upload (:func:`pdr.fusion.measurements.parse_event` reads it; positions in the group's
#: local east/north/up frame, m).
EVENT: dict[str, Any] = {"type": "object", "required": ["type"], "properties": {"type": {"enum": [
    "step", "range", "anchor_range", "position_fix", "height_difference"]}}, "allOf": [
    _event("step", "a foot's step-wise dead-reckoning summary (seed 001 eq. 7-8): displacement dp (m, the "
           "step's frame), heading change dpsi (rad), their 4x4 covariance", ["agent", "foot", "dp", "dpsi", "cov"],
           {"agent": _NAME, "foot": _FOOT,
            "dp": _VEC3, "dpsi": _NUMBER, "cov": _COV4, "index": {"type": "integer"}}),
    _event("range", "a range between two agents (m)", ["agent_a", "agent_b", "range_m"],
           {"agent_a": _NAME, "agent_b": _NAME, "range_m": _DISTANCE}),
    _event("anchor_range", "a range from an agent to an anchor at a known position (m)",
           ["agent", "anchor_n", "range_m"],
           {"agent": _NAME, "anchor_n": _POSITION3, "range_m": _DISTANCE, **_MODEL}),
    _event("position_fix", "a position of an agent (2 or 3 coordinates, m)", ["agent", "pos_n", *_MODEL],
           {"agent": _NAME, "pos_n": {"type": "array", "items": _METRES, "minItems": 2, "maxItems": 3}, **_MODEL}),
    _event("height_difference", "a height difference between two agents or an agent and a reference: dh_m (m), "
           "or barometric pressures (hPa)", ["agent_a", *_MODEL],
           {"agent_a": _NAME, "agent_b": _NAME, "dh_m": _METRES, "pressure_hpa": _PRESSURE,
            "reference_pressure_hpa": _PRESSURE, "reference_height_m": _METRES, **_MODEL}),
]}

#: Most events in one upload. An upload is fused within its request, at about 0.6 ms an event (two agents' steps and
#: ranges on this project's 2-core test machine): 20 000 take about 12 s, the 100 000 allowed before about a minute,
#: holding a request thread that long. An agent back from a long outage sends its backlog in several uploads (each
#: about three hours of one agent's steps at most).
MAX_UPLOAD_EVENTS = 20_000

UPLOAD: dict[str, Any] = {
    "type": "object", "additionalProperties": False, "required": ["batch_id", "agent", "events"],
    "properties": {
        "batch_id": _NAME,
        "agent": _NAME,
        "events": {"type": "array", "maxItems": MAX_UPLOAD_EVENTS, "items": EVENT},
    },
}


def _refuse_old_foot(name: Any, path: str) -> None:
    """422 naming the field for a foot given by its old name in the API (the library's ``left``/``right``)."""
    if isinstance(name, str) and name in FOOT_SIDES:
        raise APIError(422, f"{path}: the foot '{name}' is now called '{FOOT_SIDES[name]}' (feet are named as "
                            f"sessions' device roles: {', '.join(FOOT_SIDES.values())})",
                       details={"field": "foot", "path": path})


def store() -> GroupStore:
    """The group repository (one per app, over the service's engine)."""
    ext = current_app.extensions
    if "pdr_groups" not in ext:
        ext["pdr_groups"] = GroupStore(services().store.engine)
    repo: GroupStore = ext["pdr_groups"]
    return repo


def _float(value: float) -> float | None:
    return None if not math.isfinite(value) else float(value)


def group_json(row: Any, detail: bool = False) -> dict[str, Any]:
    """Public representation of a group row."""
    repo = store()
    group = repo.state(row.id)
    out: dict[str, Any] = {
        "id": row.id, "name": row.name, "created_at": row.created_at.isoformat(),
        "updated_at": row.updated_at.isoformat(),
        "agents": [{"agent": a.agent, "session_id": a.session_id, "clock_offset_s": a.clock_offset_s,
                    "in_contact": group.in_contact(a.agent)
                    if a.agent in group.latest_s else False, "latest_s": group.latest_s.get(a.agent)}
                   for a in repo.agents(row.id)],
        "clock_s": _float(group.clock_s), "pending": group.pending, "counts": dict(group.counts),
    }
    if detail:
        out["config"] = group.centre.config.to_dict()
        out["config"]["feet"] = [foot_role(f) for f in out["config"]["feet"]]
        out["contact_timeout_s"] = group.contact_timeout_s
        out["max_range_age_s"] = group.max_range_age_s
        out["fusion_counts"] = dict(group.centre.counts)
    return out


def correction_json(group: Group, agent: str) -> dict[str, Any]:
    """The fused estimate of an agent's feet (positions m ENU, yaw rad, covariance) with compass headings."""
    corr = group.correction(agent).to_dict()
    corr["feet"] = [foot_role(f) for f in corr["feet"]]
    corr["heading_deg"] = [(90.0 - math.degrees(corr["mean"][4 * i + 3])) % 360.0 for i in range(len(corr["feet"]))]
    return corr


@bp.post("")
def create_group() -> tuple[Response, int]:
    """Create a group with its fusion parameters."""
    user = current_user()
    body = json_body("group")
    given = body.get("config")
    if isinstance(given, dict) and isinstance(given.get("feet"), list):
        for i, name in enumerate(given["feet"]):
            _refuse_old_foot(name, f"config.feet[{i}]")
    validate(body, CREATE_GROUP, "group")
    config = dict(body.get("config", {}))
    if "feet" in config:
        config["feet"] = [ROLE_SIDES[f] for f in config["feet"]]
    group = Group(FusionConfig.from_dict(config), float(body.get("contact_timeout_s", 10.0)),
                  float(body.get("max_range_age_s", 2.0)))
    gid = store().create(user.id, body.get("name", ""), group)
    return jsonify(group_json(store().row(gid, user.id), detail=True)), 201


@bp.get("")
def list_groups() -> Response:
    user = current_user()
    no_query_parameters()
    return jsonify({"groups": [group_json(r) for r in store().list_for(user.id)]})


@bp.get("/<group_id>")
def get_group(group_id: str) -> Response:
    user = current_user()
    return jsonify(group_json(store().row(group_id, user.id), detail=True))


@bp.delete("/<group_id>")
def delete_group(group_id: str) -> tuple[str, int]:
    """Delete the group: its members, uploads, fused state and tracks (the sessions its agents were fed from stay).
    Not reversible.
    """
    user = current_user()
    store().delete(group_id, user.id)
    return "", 204


@bp.post("/<group_id>/agents")
def join_group(group_id: str) -> tuple[Response, int]:
    """Add an agent with its initial pose (and optionally link it to one of the user's sessions)."""
    user = current_user()
    repo = store()
    repo.row(group_id, user.id)
    body = json_body("agent")
    validate(body, JOIN_GROUP, "agent")
    session_id = body.get("session_id")
    if session_id is not None:
        session_id = services().store.session_row(session_id, user.id).id   # 404 for a session not the user's
    elif "clock_offset_s" in body:
        raise APIError(422, "clock_offset_s relates a session's clock to the group's: give it with session_id",
                       details={"field": "clock_offset_s"})
    clock_offset_s = float(body.get("clock_offset_s", 0.0))     # finite: a schema number (server.schemas.validate)
    agent = body["agent"]
    if any(a.agent == agent for a in repo.agents(group_id)):
        raise APIError(409, f"agent '{agent}' is already in the group", details={"field": "agent"})
    heading = math.radians(90.0 - float(body.get("heading0_deg", 90.0)))

    def join(group: Group) -> dict[str, Any]:
        group.join(agent, body["pos0_n"], heading, body.get("cov0"), float(body.get("t_s", 0.0)),
                   body.get("foot_offsets_n"))
        return correction_json(group, agent)

    corr = repo.modify(group_id, join)
    repo.add_agent(group_id, agent, session_id, clock_offset_s)
    if session_id is not None and _feed_at_join(session_id).get(group_id):
        corr = correction_json(repo.state(group_id), agent)        # the steps the session has already taken
    return jsonify({"agent": agent, "session_id": session_id, "clock_offset_s": clock_offset_s,
                    "correction": corr}), 201


def _feed_at_join(session_id: str) -> dict[str, int]:
    """The steps the session has already taken, fed to the groups that follow it
    (:func:`server.group_feed.feed_groups`); steps a group refuses (a session clock days off the group's, without the
    right ``clock_offset_s``) leave the agent joined and become a session warning, as after a processing pass
    (:mod:`server.processing`).
    """
    try:
        return feed_groups(services().store, session_id)
    except InputError as exc:
        services().store.add_session_warnings(session_id, [f"group feed: {exc}"])
        return {}


@bp.post("/<group_id>/uploads")
def upload(group_id: str) -> tuple[Response, int]:
    """Step summaries and ranges of one agent; re-sending the same ``batch_id`` is a no-op."""
    user = current_user(allow_query_token=True, scope="ingest")
    repo = store()
    repo.row(group_id, user.id)
    body = json_body("upload")
    if isinstance(body.get("events"), list):
        for i, e in enumerate(body["events"]):
            if isinstance(e, dict) and e.get("type") == "step":
                _refuse_old_foot(e.get("foot"), f"events[{i}].foot")
    validate(body, UPLOAD, "upload")
    agent = body["agent"]
    agents = repo.agents(group_id)
    members = {a.agent for a in agents}
    fed = {a.agent: a.session_id for a in agents if a.session_id}
    if agent not in members:
        raise APIError(422, f"agent '{agent}' has not joined the group", details={"field": "agent"})
    events = [parse_event(e, f"events[{i}]") for i, e in enumerate(body["events"])]   # 422 naming the event
    feet = repo.state(group_id).centre.config.feet
    events = [replace(ev, foot=ROLE_SIDES[ev.foot]) if isinstance(ev, StepSummary) else ev
              for ev in events]                                # the API's foot names to the library's
    for i, ev in enumerate(events):                  # everything checked before the raw upload is stored
        unknown = [a for a in ev.agents if a not in members]
        if unknown:
            raise APIError(422, f"events[{i}]: agent '{unknown[0]}' has not joined the group",
                           details={"source": f"events[{i}]", "field": "agent"})
        if isinstance(ev, StepSummary) and ev.foot not in feet:
            raise APIError(422, f"events[{i}]: foot must be one of this group's feet, "
                                f"{', '.join(foot_role(f) for f in feet)}",
                           details={"source": f"events[{i}]", "field": "foot"})
        if isinstance(ev, StepSummary) and ev.agent in fed:
            raise APIError(409, f"events[{i}]: agent '{ev.agent}' takes its steps from session '{fed[ev.agent]}'",
                           details={"source": f"events[{i}]", "field": "agent"})
    uid, created = repo.add_upload(group_id, agent, body["batch_id"], request.get_data())
    if not created:
        return jsonify({"batch_id": body["batch_id"], "id": uid, "duplicate": True}), 200

    def apply(group: Group) -> dict[str, Any]:
        accepted = group.submit(events, reporter=agent)
        report = group.process()
        return {"accepted": accepted, **report, "correction": correction_json(group, agent)}

    try:
        result = repo.modify(group_id, apply)
    except Exception:
        # Nothing of the upload was applied (an input error, e.g. ranges older than the fusion horizon, or a fault of
        # ours): it is not kept either, so a retry is applied, not answered as a duplicate of what was lost.
        repo.remove_upload(uid)
        raise
    return jsonify({"batch_id": body["batch_id"], "id": uid, "duplicate": False, **result}), 201


@bp.post("/<group_id>/flush")
def flush(group_id: str) -> Response:
    """Apply every buffered event now, without waiting for agents out of contact (e.g. at the end of a mission)."""
    user = current_user()
    repo = store()
    repo.row(group_id, user.id)
    return jsonify(repo.modify(group_id, lambda g: g.process(flush=True)))


@bp.get("/<group_id>/agents/<agent>/correction")
def correction(group_id: str, agent: str) -> Response:
    """The fused estimate of an agent's feet, to correct its local dead reckoning."""
    user = current_user()
    repo = store()
    repo.row(group_id, user.id)
    group = repo.state(group_id)
    if agent not in group.latest_s:
        raise APIError(404, f"no agent '{agent[:64]}' in group '{group_id[:64]}'")
    return jsonify(correction_json(group, agent))


@bp.get("/<group_id>/tracks")
def tracks(group_id: str) -> Response:
    """Fused reset poses of every foot: ``{agents: {agent: {foot: [[t_s, east_m, north_m, up_m, heading_deg]]}}}``.

    Query: ``agent`` (repeatable) to select agents, ``since_s`` for rows after a time.
    """
    user = current_user()
    repo = store()
    repo.row(group_id, user.id)
    only_query_parameters("agent", "since_s")
    since_s = parse_since("since_s", status=422)
    out: dict[str, dict[str, list[list[float]]]] = {}
    for r in repo.track(group_id, request.args.getlist("agent") or None, since_s):
        out.setdefault(r.agent, {}).setdefault(foot_role(r.foot), []).append(
            [r.t_s, r.east_m, r.north_m, r.up_m, r.heading_deg])
    return jsonify({"group_id": group_id, "agents": out})

