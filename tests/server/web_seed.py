"""Seeded data for the web page's tests: synthetic walks stored as results, a truth-carrying log, a test processor.

The walks are written straight into the store (a raw batch per device plus its results, as a processed
upload would leave them), so the page can be tested before the real processors exist and with sessions
of any length.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pdr.io.native import batch_to_json
from pdr.phone.events import StepEvent
from pdr.recording import DeviceInfo, GroundTruth, PositionTruth, Recording, SensorStream
from server import auth
from server.processing import NATIVE_JSON, ProcessorOutput, SessionContext
from server.store import EventRow, Store, StoredStep, TrackRow

#: Drift of the test processor's track from the truth per truth point: east 0.3 m, north 0.4 m -> 0.5 m more error
#: at every later point (k + 1 times it at point k, counted from 0).
TRUTH_OFFSET_M = (0.3, 0.4)
#: The test processor's track starts this long (s) before the first truth point, at LEAD_POSITION_M.
LEAD_S = 2.0
LEAD_POSITION_M = (-6.0, -8.0)


def truth_offset_m(k: int) -> tuple[float, float]:
    """Offset (east, north) of the test processor's track from truth point ``k`` (counted from 0), metres."""
    return (TRUTH_OFFSET_M[0] * (k + 1), TRUTH_OFFSET_M[1] * (k + 1))


class WebTestProcessor:
    """Test double: a log with truth positions gives a track that starts ``LEAD_S`` before the first truth point
    at ``LEAD_POSITION_M``, then a row at every truth time offset by :func:`truth_offset_m` (so the error the
    page shows once the track starts at the first truth point is known: 0.5 k m at point k); any other batch
    gives one walking step at its last sample,
    advancing 0.7 m east per batch (state: batches seen).
    """

    def __init__(self, ctx: SessionContext, state: bytes | None) -> None:
        self.count = json.loads(state)["count"] if state else 0

    def update(self, recording: Recording) -> ProcessorOutput:
        pos = recording.truth.positions
        if pos is not None:
            lead = TrackRow(float(pos.t_s[0]) - LEAD_S, *LEAD_POSITION_M, 0.0, 0.0, 90.0, 0.7, "walking")
            track = [TrackRow(float(t), float(p[0]) + truth_offset_m(k)[0], float(p[1]) + truth_offset_m(k)[1],
                              0.0, 0.0, 90.0, 0.7, "walking")
                     for k, (t, p) in enumerate(zip(pos.t_s, pos.pos_m, strict=True))]
            return ProcessorOutput(track=[lead, *track])
        self.count += 1
        last_ns = max(int(s.t_ns[-1]) for s in recording.streams.values())
        t = (last_ns - recording.origin_ns) / 1e9 + self.count
        return ProcessorOutput(track=[TrackRow(t, 0.7 * self.count, 0.0, 0.0, 0.0, 90.0, 0.7, "walking")])

    def to_bytes(self) -> bytes:
        return json.dumps({"count": self.count}).encode()


@dataclass(frozen=True)
class Walk:
    """A synthetic walk: one row per step (local metres, heading clockwise from north)."""

    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    floor: np.ndarray
    heading_deg: np.ndarray
    step_length_m: np.ndarray
    mode: list[str]

    def rows(self, offset_east_m: float = 0.0) -> list[TrackRow]:
        return [TrackRow(float(t), float(e) + offset_east_m, float(n), 3.5 * float(f), float(f), float(h), float(s), m)
                for t, e, n, f, h, s, m in zip(self.t_s, self.east_m, self.north_m, self.floor, self.heading_deg,
                                               self.step_length_m, self.mode, strict=True)]


def corridor_walk(duration_s: float, cadence_hz: float = 1.6, seed: int = 0) -> Walk:
    """Laps of a 60 m x 30 m corridor loop, a floor change every 20 minutes, pauses and stair runs."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * cadence_hz)
    t = np.arange(n) / cadence_hz
    length = 0.7 + 0.05 * rng.standard_normal(n)
    s = np.cumsum(length) % 180.0  # arc length along the 180 m loop
    east = np.select([s < 60, s < 90, s < 150], [s, 60.0, 150.0 - s], 0.0)
    north = np.select([s < 60, s < 90, s < 150], [0.0, s - 60.0, 30.0], 180.0 - s)
    heading = np.select([s < 60, s < 90, s < 150], [90.0, 0.0, 270.0], 180.0)
    floor = np.floor(t / 1200.0) % 3
    block = (t // 60).astype(int)
    mode = ["standing" if b % 10 == 9 else ("stairs_up" if (t[i] % 1200.0) < 30 and t[i] > 60 else "walking")
            for i, b in enumerate(block)]
    return Walk(t, east, north, floor, heading, length, mode)


def drifting_compass_walk(duration_s: float = 240.0, cadence_hz: float = 1.8, seed: int = 2) -> list[StepEvent]:
    """A hand-held walk as the phone pipeline streams it: typed step events with the heading smoother's inputs,
    so that ``?heading=smoothed`` moves it.

    The walk goes around the corridor loop of :func:`corridor_walk`; the streamed heading follows a compass
    with noise and a 20 deg disturbance over the second minute that builds up and fades over 15 s (a
    corridor with steel in its walls), while the gyro heading is the true heading plus a constant 40 deg
    (the gyro yaw's arbitrary origin). Smoothing the heading over the walk (gyro yaw plus an offset learnt
    from the compass) takes the disturbance out: the streamed track ends 18 m from the true loop's end, the
    smoothed one 2.3 m.
    """
    rng = np.random.default_rng(seed)
    walk = corridor_walk(duration_s, cadence_hz, seed)
    compass = walk.heading_deg + 4.0 * rng.standard_normal(walk.t_s.size)
    compass = compass + 20.0 * np.clip(np.minimum(walk.t_s - 60.0, 120.0 - walk.t_s) / 15.0, 0.0, 1.0)
    yaw = np.radians(90.0 - compass)
    east = np.cumsum(walk.step_length_m * np.cos(yaw))
    north = np.cumsum(walk.step_length_m * np.sin(yaw))
    steps = []
    for k, t in enumerate(walk.t_s):
        heading = float(compass[k] % 360.0)
        steps.append(StepEvent(
            t_s=float(t), t_start_s=float(t) - 1.0 / cadence_hz, east_m=float(east[k]), north_m=float(north[k]),
            up_m=0.0, floor=0.0, heading_deg=heading, step_length_m=float(walk.step_length_m[k]), turn_deg=0.0,
            mode="walking", placement="hand", heading_sigma_deg=10.0, pos_sigma_m=1.0, patterns=[],
            heading_raw_deg=heading, gyro_heading_deg=float((walk.heading_deg[k] + 40.0) % 360.0), up_time_s=None,
            gyro_bias_dps=None, position_fix=False, landmark_heading=False))
    return steps


def user_id(store: Store, token: str) -> int:
    with store.engine.connect() as conn:
        user = auth.lookup(conn, token)
    assert user is not None
    return user.id


def seed_session(store: Store, token: str, name: str, tracks: dict[str, Sequence[StoredStep]], *,
                 placement: str | None = "pocket", model: str = "Pixel 7", warnings: tuple[str, ...] = (),
                 landmarks: tuple[tuple[float, str], ...] = (), meta: dict[str, Any] | None = None) -> str:
    """A processed session of the token's user with the given steps per device role (track rows, or typed phone
    step events such as :func:`drifting_compass_walk`'s); returns its id.
    """
    sid, _ = store.create_session(user_id(store, token), source="native", client_session_id=name, name=name,
                                  placement=placement, meta=meta)
    for role, rows in tracks.items():
        store.upsert_device(sid, role, device_id=f"{role}-1", platform="android" if role == "phone" else "imu",
                            model=model if role == "phone" else "shoe IMU", placement=placement)
        t_last_ns = int(rows[-1].t_s * 1e9) if rows else 0
        bid, _ = store.add_batch(sid, device_role=role, client_batch_id=f"seed-{role}", payload_format=NATIVE_JSON,
                                 payload=json.dumps({"seed": name, "role": role}).encode(), t_first_ns=0,
                                 t_last_ns=t_last_ns)
        events = ([EventRow("landmark", t, label=label) for t, label in landmarks]
                  if role == next(iter(tracks)) else [])
        store.commit_results(sid, role, bid, b"{}", t_last_ns, rows, events)
    store.add_session_warnings(sid, list(warnings))
    store.set_session(sid, status="done")
    return sid


def truth_log(duration_s: float = 60.0, rate_hz: float = 50.0) -> dict[str, Any]:
    """A ``pdr-batch/1`` log of a phone with waypoint truth every 5 s around a 20 m x 10 m rectangle."""
    n = int(duration_s * rate_hz)
    t0 = 1_700_000_000_000_000_000
    t_ns = (t0 + np.round(np.arange(n) / rate_hz * 1e9)).astype(np.int64)
    tw = np.arange(0.0, duration_s, 5.0)
    s = (tw * 1.0) % 60.0
    east = np.select([s < 20, s < 30, s < 50], [s, 20.0, 50.0 - s], 0.0)
    north = np.select([s < 20, s < 30, s < 50], [0.0, s - 20.0, 10.0], 60.0 - s)
    truth = GroundTruth(positions=PositionTruth(tw, np.column_stack([east, north, np.zeros_like(tw)]),
                                                kind="waypoint"))
    rec = Recording({"acc": SensorStream("acc", t_ns, np.tile([0.0, 0.0, 9.81], (n, 1))),
                     "gyro": SensorStream("gyro", t_ns, np.zeros((n, 3)))},
                    DeviceInfo(platform="android", model="truth-phone", role="phone"), t0_ns=t0, truth=truth)
    return batch_to_json(rec, session_id="truth-walk", batch_id="truth-1")


def expected_truth_errors_m(n_points: int) -> list[float]:
    """Errors (m) at truth points 2..K of the test processor's track once it starts at the first truth point."""
    return [math.hypot(*TRUTH_OFFSET_M) * k for k in range(1, n_points)]


def allan_report(duration_s: float = 600.0, rate_hz: float = 100.0) -> dict[str, Any]:
    """A real ``pdr.allan`` report (``report.json`` content) of a synthetic static IMU record."""
    from pdr.allan.characterise import characterise_recording
    from pdr.allan.report import report_dict
    from pdr.allan.synthetic import random_walk, white_noise

    rng = np.random.default_rng(0)
    n = int(duration_s * rate_hz)
    t_ns = (np.arange(n) * (1e9 / rate_hz)).astype(np.int64)
    gyro = np.column_stack([white_noise(n, rate_hz, 2e-4, rng) + random_walk(n, rate_hz, 1e-5, rng) for _ in range(3)])
    acc = np.column_stack([white_noise(n, rate_hz, 1.5e-3, rng) for _ in range(3)]) + [0.0, 0.0, 9.81]
    rec = Recording({"gyro": SensorStream("gyro", t_ns, gyro), "acc": SensorStream("acc", t_ns, acc)},
                    DeviceInfo(platform="imu", model="synthetic", role="phone"))
    report: dict[str, Any] = report_dict(characterise_recording(rec))
    return report
