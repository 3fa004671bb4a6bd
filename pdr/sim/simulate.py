"""``simulate(scenario, seed) -> Recording``: a synthetic recording with its ground truth.

Pipeline: scenario -> path (:mod:`pdr.sim.trajectory`) -> device kinematics at each sensor's sample
times (:mod:`pdr.sim.placement` for phones, :mod:`pdr.sim.shoe` for shoe IMUs) -> ideal measurements
(specific force ``f_b = C_bn (a_n - g_n)`` with ``g_n = (0, 0, -9.80665)``, body angular rate, the magnetic
field of :mod:`pdr.sim.magnetic` in the body frame, pressure of the device's altitude via
:func:`pdr.frames.altitude_to_pressure_hpa`) -> sensor errors (:mod:`pdr.sim.sensors`).

Determinism: the path depends on the scenario only; everything random (an arbitrary mount, magnetic
anomalies, each sensor's errors) comes from independent streams spawned from ``seed``, so the same seed
gives bit-identical output and two scenarios that differ only in placement describe the same walk.

Ground truth (on the recording's time axis, seconds from ``start_time_ns``): dense device positions with
floor (``truth.positions``, kind ``dense``, frame ``enu``), heel-strike times and step lengths
(horizontal distance walked since the previous step of the bout), motion modes and landmarks, and in
``truth.extra``: ``trajectory_t_s`` (K,), ``q_nb`` (K, 4) device attitude, ``vel_n`` (K, 3) device velocity
in m/s, ``walking_heading_rad`` (K,) yaw of the walking direction (counter-clockwise from east, wrapped),
``floor`` (K,), ``step_foot`` (M,) +1 right / -1 left foot per step; for shoe IMUs also
``zero_velocity`` (K,) bool (foot still) with ``zero_velocity_t_s``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import altitude_to_pressure_hpa, wrap_angle
from pdr.recording import DeviceInfo, GroundTruth, PositionTruth, Recording, SensorStream
from pdr.sim.kinematics import Motion
from pdr.sim.magnetic import build_environment
from pdr.sim.placement import DEFAULT_MOUNTS, phone_motion
from pdr.sim.scenario import Scenario, parse_scenario
from pdr.sim.sensors import apply
from pdr.sim.shoe import foot_motion
from pdr.sim.trajectory import Path, build_path

Array = NDArray[np.float64]

_STREAMS = ("acc", "gyro", "mag", "baro")


def random_rotation(rng: np.random.Generator) -> Array:
    """A uniformly distributed attitude quaternion (normalised 4-D Gaussian)."""
    return quat.normalize(rng.normal(0.0, 1.0, 4))


def mount_quaternion(scenario: Scenario, rng: np.random.Generator) -> Array:
    """Segment -> device orientation of the scenario: default, default then roll/pitch/yaw, or random."""
    default = DEFAULT_MOUNTS[scenario.placement]
    m = scenario.mount_rpy_rad
    if m is None:
        return default
    if isinstance(m, str):
        return random_rotation(rng)
    return quat.normalize(quat.multiply(default, quat.from_euler(*m)))


def sample_times(rate_hz: float, duration_s: float) -> Array:
    """Uniform sample times ``k / rate`` in s covering ``[0, duration]``."""
    return np.arange(int(np.floor(duration_s * rate_hz + 1e-9)) + 1) / rate_hz


def device_motion(path: Path, t_s: Array, q_mount: Array) -> tuple[Motion, Array | None]:
    """Kinematics of the scenario's device at ``t_s``, and the foot's at-rest flags (shoe IMUs only)."""
    sc = path.scenario
    if sc.placement == "foot":
        return foot_motion(path, t_s, sc.side, q_mount, sc.height_m)
    return phone_motion(path, t_s, sc.placement, sc.side, q_mount, sc.height_m), None


def simulate(scenario: Scenario | Mapping[str, Any], seed: int) -> Recording:
    """Simulate ``scenario`` (a :class:`Scenario` or its JSON object) with random seed ``seed`` (>= 0)."""
    if not isinstance(seed, int | np.integer) or isinstance(seed, bool) or seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed!r}", field="seed")
    sc = scenario if isinstance(scenario, Scenario) else parse_scenario(scenario)
    rng_mount, rng_field, *rng_sensor = (np.random.default_rng(s)
                                         for s in np.random.SeedSequence(int(seed)).spawn(2 + len(_STREAMS)))
    rngs = dict(zip(_STREAMS, rng_sensor, strict=True))
    path = build_path(sc)
    q_mount = mount_quaternion(sc, rng_mount)
    env = build_environment(path, sc.magnetic, rng_field)
    duration = sc.duration_s

    motions: dict[float, Motion] = {}

    def motion_at(rate: float) -> tuple[Array, Motion]:
        t = sample_times(rate, duration)
        if rate not in motions:
            motions[rate] = device_motion(path, t, q_mount)[0]
        return t, motions[rate]

    streams = {}
    for kind in _STREAMS:
        if kind not in sc.rates_hz:
            continue
        t, mo = motion_at(sc.rates_hz[kind])
        if kind == "acc":
            ideal = mo.specific_force_b()
        elif kind == "gyro":
            ideal = mo.angular_rate_b()
        elif kind == "mag":
            ideal = quat.rotate(quat.conjugate(mo.frame.q_nb), env.field_n(t, mo.pos_n))
        else:
            ideal = altitude_to_pressure_hpa(sc.altitude_m + mo.pos_n[:, 2] - sc.start_position_m[2],
                                             sc.sea_level_pressure_hpa)[:, None]
        values = apply(sc.errors[kind], ideal, t, rngs[kind])
        t_ns = sc.start_time_ns + np.round(t * 1e9).astype(np.int64)
        streams[kind] = SensorStream(kind, t_ns, values)

    truth = _truth(path, q_mount)
    role = "phone" if sc.placement != "foot" else f"{sc.side}_foot"
    device = DeviceInfo(platform="imu" if sc.placement == "foot" else "unknown", model="pdr.sim", role=role,
                        placement=sc.placement, device_id=sc.name or "sim")
    meta = {"simulator": "pdr.sim", "seed": int(seed), "scenario": dict(sc.document),
            "mount_q": [float(x) for x in q_mount]}
    return Recording(streams, device, t0_ns=sc.start_time_ns, truth=truth,
                     source=f"sim:{sc.name or 'scenario'}:seed={seed}", format="sim", meta=meta)


def _truth(path: Path, q_mount: Array) -> GroundTruth:
    sc = path.scenario
    t = sample_times(sc.truth_rate_hz, sc.duration_s)
    mo, at_rest = device_motion(path, t, q_mount)
    floor = path.floor(path.position(t).value[:, 2])
    extra: dict[str, np.ndarray] = {
        "trajectory_t_s": t,
        "q_nb": quat.normalize(mo.frame.q_nb),
        "vel_n": mo.vel_n,
        "walking_heading_rad": wrap_angle(path.heading.value(t).value),
        "floor": floor,
        "step_foot": path.steps.foot,
    }
    if at_rest is not None:
        extra["zero_velocity"] = at_rest
        extra["zero_velocity_t_s"] = t
    return GroundTruth(
        positions=PositionTruth(t, mo.pos_n, floor, kind="dense", frame="enu"),
        step_times_s=path.steps.t_s,
        step_lengths_m=path.step_lengths_m(),
        modes=path.modes(),
        landmarks=path.landmarks() if any(s.landmark for s in sc.segments) else None,
        extra=extra,
    )
