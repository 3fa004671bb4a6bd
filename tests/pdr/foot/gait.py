"""Synthetic foot IMU: stance at rest, swing with a smooth forward and vertical motion and a heading change."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pdr import quaternion as quat
from pdr.frames import GRAVITY_MPS2


@dataclass(frozen=True)
class Gait:
    t_s: np.ndarray
    acc_b: np.ndarray
    gyro_b: np.ndarray
    pos_n: np.ndarray
    yaw: np.ndarray
    stance: np.ndarray


def simulate_gait(n_strides: int = 10, stride_m: float = 1.4, turn_rad: float = 0.0, rate_hz: float = 200.0,
                  stance_s: float = 0.5, swing_s: float = 0.6, lift_m: float = 0.1, tilt=(0.1, -0.2),
                  sigma_acc: float = 0.0, sigma_gyro: float = 0.0, seed: int = 0) -> Gait:
    """Foot IMU with exact kinematics; measurements are evaluated at mid-interval (what the integrator holds)."""
    period = stance_s + swing_s
    duration = stance_s + n_strides * period
    n = int(round(duration * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    q_tilt = quat.from_euler(tilt[0], tilt[1], 0.0)

    def kin(tt: np.ndarray):
        k = np.clip(np.floor((tt - stance_s) / period), -1, n_strides - 1).astype(int)
        tau = tt - stance_s - k * period
        swing = (k >= 0) & (tau < swing_s) & (tt >= stance_s)
        done = np.where(swing, k, k + 1)        # completed strides
        u = np.where(swing, tau / swing_s, 0.0)
        w = 2 * np.pi / swing_s
        s = stride_m * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
        ds = stride_m / swing_s * (1 - np.cos(2 * np.pi * u)) * swing
        dds = stride_m / swing_s * w * np.sin(2 * np.pi * u) * swing
        h = lift_m * (1 - np.cos(2 * np.pi * u)) / 2 * swing
        ddh = lift_m * w**2 / 2 * np.cos(2 * np.pi * u) * swing
        yaw = turn_rad * (done + s / stride_m * swing)
        dyaw = turn_rad * ds / stride_m
        return done, s * swing, ds, dds, h, ddh, yaw, dyaw, swing

    done, s, ds, dds, h, ddh, yaw, dyaw, swing = kin(t)
    # Position: completed strides are straight chords only when turn_rad == 0; integrate numerically otherwise.
    fine = np.linspace(0.0, duration, 40 * n)
    _, _, dsf, _, hf, _, yawf, _, _ = kin(fine)
    vx, vy = dsf * np.cos(yawf), dsf * np.sin(yawf)
    dt = fine[1] - fine[0]
    px = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * dt)])
    py = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * dt)])
    pos = np.stack([np.interp(t, fine, px), np.interp(t, fine, py), h], axis=1)

    tm = np.concatenate([[0.0], 0.5 * (t[1:] + t[:-1])])
    _, _, ds_m, dds_m, _, ddh_m, yaw_m, dyaw_m, _ = kin(tm)
    acc_n = np.stack([dds_m * np.cos(yaw_m) - ds_m * dyaw_m * np.sin(yaw_m),
                      dds_m * np.sin(yaw_m) + ds_m * dyaw_m * np.cos(yaw_m), ddh_m], axis=1)
    q_nb = quat.multiply(quat.from_euler(0 * yaw_m, 0 * yaw_m, yaw_m), q_tilt)
    acc_b = quat.rotate(quat.conjugate(q_nb), acc_n + [0.0, 0.0, GRAVITY_MPS2])
    gyro_b = quat.rotate(quat.conjugate(q_tilt), np.stack([0 * dyaw_m, 0 * dyaw_m, dyaw_m], axis=1))
    rng = np.random.default_rng(seed)
    acc_b = acc_b + rng.normal(0.0, sigma_acc, acc_b.shape) if sigma_acc else acc_b
    gyro_b = gyro_b + rng.normal(0.0, sigma_gyro, gyro_b.shape) if sigma_gyro else gyro_b
    return Gait(t, acc_b, gyro_b, pos, yaw, ~swing)


def gyro_drift_walk(drift_deg_s: float, n_strides: int = 40, seed: int = 11) -> tuple[Gait, np.ndarray]:
    """Straight walk (1.4 m strides, light noise) and a gyroscope whose constant bias drifts the heading by
    ``drift_deg_s`` (deg/s): returns the gait and the biased (N, 3) gyroscope samples, rad/s."""
    g = simulate_gait(n_strides=n_strides, stride_m=1.4, sigma_acc=0.02, sigma_gyro=0.002, seed=seed)
    bias_n = np.array([0.0, 0.0, np.radians(drift_deg_s)])
    bias_b = quat.rotate(quat.conjugate(quat.from_euler(0.1, -0.2, 0.0)), bias_n)
    return g, g.gyro_b + bias_b
