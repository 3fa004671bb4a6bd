"""Site descriptions of simulated scenarios: simulate, then recover the landmarks and their corrections."""

import json
import math

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.frames import heading_deg_to_yaw, wrap_angle
from pdr.phone.attitude import AttitudeConfig
from pdr.phone.heading import f_of_q, scatter_in_frame, scatter_of
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.sim import parse_scenario, simulate, site_document
from pdr.sim.trajectory import build_path


def _stairs_walk(side: str = "right") -> dict:
    return {"name": "stairs_walk", "placement": "trouser_pocket", "side": side, "mount_rpy_deg": "random",
            "start": {"position_m": [5, -3, 0], "heading_deg": 200, "floor": 0},
            "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "distance_m": 10, "speed_mps": 1.3},
                         {"type": "stairs", "direction": "up", "floors": 1},
                         {"type": "walk", "distance_m": 12, "speed_mps": 1.2},
                         {"type": "turn", "angle_deg": -90, "duration_s": 2},
                         {"type": "walk", "distance_m": 6, "speed_mps": 1.1},
                         {"type": "elevator", "direction": "down", "floors": 1},
                         {"type": "walk", "distance_m": 4, "speed_mps": 1.1}]}


def test_site_of_a_scenario_places_its_landmarks_and_round_trips():
    doc = site_document(_stairs_walk())
    site = Site.from_dict(json.loads(json.dumps(doc)))
    assert site.to_dict() == doc
    assert [lm.type for lm in site.landmarks] == ["stairs_up", "elevator"]
    assert site.floor_height_m == 3.0
    stairs, elevator = site.landmarks
    sc = parse_scenario(_stairs_walk())
    path = build_path(sc)
    t0 = sc.boundaries_s[2]                                   # the flight starts after stand + walk
    foot = path.position(np.array([t0])).value[0]
    assert (stairs.east_m, stairs.north_m) == pytest.approx((foot[0], foot[1]), abs=1e-9)
    # 10 m walked at heading 200 deg from the start: the foot of the flight.
    assert stairs.east_m == pytest.approx(5 + 10 * math.sin(math.radians(200)), abs=0.2)
    assert stairs.north_m == pytest.approx(-3 + 10 * math.cos(math.radians(200)), abs=0.2)
    assert stairs.floor == 0 and elevator.floor == 1
    yaw, var = stairs.yaw_and_var()
    assert yaw == pytest.approx(float(heading_deg_to_yaw(200.0)), abs=1e-9)
    assert math.sqrt(var) == pytest.approx(math.radians(20.0) / 6)   # +/-10 deg interval, three sigma
    assert elevator.yaw_and_var()[0] == pytest.approx(float(heading_deg_to_yaw(290.0)), abs=1e-9)


def test_site_without_landmarks_and_custom_widths():
    flat = {"segments": [{"type": "walk", "duration_s": 5}]}
    assert site_document(flat)["landmarks"] == []
    doc = site_document(_stairs_walk(), half_width_deg={"stairs": 4.0}, radius_m=3.0)
    lo, hi = doc["landmarks"][0]["heading_deg"]
    assert (hi - lo) % 360 == pytest.approx(8.0) and doc["landmarks"][0]["radius_m"] == 3.0


def test_scatter_carried_to_another_attitude_keeps_the_measurement():
    rng = np.random.default_rng(1)
    f_n = rng.normal(size=(60, 3)) * [2.0, 0.5, 1.0]
    q1, q2 = quat.normalize(rng.normal(size=4)), quat.normalize(rng.normal(size=4))
    m1 = scatter_of(f_n, q1)
    m2 = scatter_in_frame(m1, q1, q2)
    np.testing.assert_allclose(m2, scatter_of(f_n, q2), atol=1e-9)
    assert f_of_q(q2, m2, 0.3) == pytest.approx(f_of_q(q1, m1, 0.3), abs=1e-9)


@pytest.mark.parametrize(("side", "seed"), [("left", 1), ("right", 3)])
def test_stairs_landmark_corrects_a_seeded_heading_error(side, seed):
    # A wrong declination (-15 deg) seeds a heading error. Simulate, then recover: the walk's site description
    # makes the flight of stairs correct the attitude (seed 003 eqs. 14-32) and the step headings (eq. 42);
    # the heading error after the flight shrinks. (+15 deg is partly cancelled by the walk's own magnetometer
    # error, 3 deg simulated declination and an uncalibrated offset: right seed 3 then starts 3.6 deg off.)
    sc = _stairs_walk(side)
    rec = simulate(sc, seed)
    seeded = PipelineConfig(attitude=AttitudeConfig(mag_declination_deg=-15.0))
    assert rec.truth is not None
    tt, wh = rec.truth.extra["trajectory_t_s"], np.unwrap(rec.truth.extra["walking_heading_rad"])
    t_after = parse_scenario(sc).boundaries_s[3]               # end of the flight

    def errors(site: Site | None) -> tuple[np.ndarray, np.ndarray, PdrPipeline]:
        pipe = PdrPipeline(seeded, site=site)
        events = pipe.run(rec)
        rows = track_rows(events)
        t = np.array([0.5 * (r["t_start_s"] + r["t_s"]) for r in rows])
        yaw = heading_deg_to_yaw(np.array([r["heading_deg"] for r in rows]))
        err = np.degrees(np.abs(wrap_angle(yaw - np.interp(t, tt, wh))))
        return t, err, pipe

    t, e0, _ = errors(None)
    doc = site_document(sc)
    doc.pop("declination_deg")                                  # else the site's declination replaces -15 deg
    _, e1, pipe = errors(Site.from_dict(doc))
    after = (t > t_after) & (t < t_after + 10.0)
    assert pipe.landmark_updates >= 5 and pipe.landmark_attitude_updates == pipe.landmark_updates
    assert e0[after].mean() > 8.0                               # the wrong declination turns every heading
    assert e1[after].mean() < 0.6 * e0[after].mean()
    assert e1.mean() < e0.mean()
    # Stored state round-trips the landmark bookkeeping.
    state = pipe.state()
    again = PdrPipeline.from_state(state)
    assert again.stairs.stairs_landmark == pipe.stairs.stairs_landmark
    assert again.landmark_updates == pipe.landmark_updates


def test_site_carries_the_scenario_declination_and_the_pipeline_uses_it():
    sc = {**_stairs_walk(), "magnetic": {"declination_deg": -7.5}}
    doc = site_document(sc)
    assert doc["declination_deg"] == pytest.approx(-7.5)
    site = Site.from_dict(doc)
    assert site.declination_deg == pytest.approx(-7.5) and site.to_dict() == doc
    pipe = PdrPipeline(PipelineConfig(attitude=AttitudeConfig(mag_declination_deg=20.0)), site=site)
    assert pipe.attitude.config.mag_declination_deg == pytest.approx(-7.5)
    # Optional: without it the configured declination stays.
    del doc["declination_deg"]
    bare = Site.from_dict(doc)
    assert bare.declination_deg is None and "declination_deg" not in bare.to_dict()
    pipe = PdrPipeline(PipelineConfig(attitude=AttitudeConfig(mag_declination_deg=20.0)), site=bare)
    assert pipe.attitude.config.mag_declination_deg == 20.0
    again = PdrPipeline.from_state(PdrPipeline(site=site).state())
    assert again.attitude.config.mag_declination_deg == pytest.approx(-7.5)


@pytest.mark.parametrize("bad", ["east", 400, None])
def test_site_declination_must_be_degrees(bad):
    from pdr.errors import InputError
    doc = {"landmarks": [], "declination_deg": bad}
    if bad is None:
        assert Site.from_dict(doc).declination_deg is None
        return
    with pytest.raises(InputError, match="declination_deg"):
        Site.from_dict(doc)
