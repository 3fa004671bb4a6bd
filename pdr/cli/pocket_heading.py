"""Check the trouser-pocket walking direction of the phone pipeline (180-degree rule of :mod:`pdr.phone.heading`).

Simulated pocket walks (truth ``walking_heading_rad``): mean absolute heading error, share of steps more than
90 degrees off, median step-to-step change, over seeds, both thighs and random mounts.

Real pocket walks (no direction truth):
- flips: consecutive steps (less than 2 s apart) whose headings differ by more than 120 degrees;
- turn check (MobiFall, which has a gyroscope): in a turn at yaw rate ``Omega`` the mean horizontal specific
  force over a stride is the centripetal acceleration ``V Omega (u x f)`` plus a slowly varying tilt error,
  removed as the median over the straight strides within 6 s. The step's output heading agrees when
  ``sign(Omega) (a x u) . f > 0``. Strides with ``|Omega| > 0.35 rad/s`` count.

Simulated walks through landmarks (:func:`landmark_scenarios`: stairs and an elevator), each processed twice:
without and with the site description of its scenario (:func:`pdr.sim.site_document`), so the landmark
corrections of seed 003 (attitude row eqs. 14-32, second UKF eqs. 41-42) are measured against the same walk.

Usage: ``pdr eval pocket-heading [--sim-seeds N] [--data DIR] [--no-real] [--no-sim] [--method ukf|ekf]
[--json]``. JSON keys: ``method``; ``sim`` (the flat walks: ``walks``, ``steps``, ``mean_abs_err_deg``,
``median_abs_err_deg``, ``within_10_deg``, ``share_over_90_deg``, ``walks_mean_over_90_deg``; ``smoothed``: the
figures of the offline-smoothed tracks, :mod:`pdr.phone.heading_smoother`); ``sim_landmarks`` (``without`` and ``with``:
the same figures, ``without_smoothed`` and ``with_smoothed`` those of the smoothed tracks; ``staircases``,
``staircases_matched``, ``landmark_heading_updates``, ``landmark_attitude_updates``); ``mobifall`` and ``oxford``
(steps, flips, turn-check counts).
"""

from __future__ import annotations

import argparse
import glob
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from pdr import quaternion as quat
from pdr.frames import heading_deg_to_yaw, wrap_angle
from pdr.io.registry import read_recording
from pdr.phone.heading_smoother import smooth_track
from pdr.phone.history import SampleHistory
from pdr.phone.landmarks import Site
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.recording import Recording
from pdr.sim import simulate, site_document

FLIP_DEG = 120.0
TURN_RATE = 0.35
STRAIGHT_RATE = 0.1


class _Probe:
    """A step observer (:class:`pdr.phone.stage.StepObserver`) recording per step the stride's mean horizontal
    specific force (m/s^2, ENU) and vertical rotation rate (rad/s), keyed by the step's start time (s).
    """

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self.probe: dict[float, tuple[float, float, float]] = {}
        self._probe_prev: int | None = None

    def confirmed(self, s: int, e: int, h: SampleHistory) -> None:
        ps = self._probe_prev
        s0 = ps if ps is not None and 0 < s - ps <= 2 * (e - s) else s - (e - s)
        self._probe_prev = s
        q, f = h.q[h.sl(s0, e)], h.f_n[h.sl(s0, e)]
        if q.shape[0] > 3 and np.all(np.isfinite(q)) and np.all(np.isfinite(f)):
            om = quat.to_rotvec(quat.multiply(q[1:], quat.conjugate(q[:-1])))[:, 2] * self.rate_hz
            self.probe[float(h.t[h.sl(s, e)][0])] = (float(f[:, 0].mean()), float(f[:, 1].mean()), float(om.mean()))


def _flips(t: np.ndarray, yaw: np.ndarray) -> int:
    near = np.diff(t) < 2.0
    return int(np.sum(near & (np.degrees(np.abs(wrap_angle(np.diff(yaw)))) > FLIP_DEG)))


def real_walk(rec: Recording, method: str = "ukf") -> dict[str, float]:
    """Flips and turn-check agreement of one real pocket walk."""
    cfg = PipelineConfig(placement="pocket", attitude_method=method)
    p = _Probe(cfg.rate_hz)
    rows = track_rows(PdrPipeline(cfg, observers=[p]).run(rec))
    t = np.array([r["t_start_s"] for r in rows])
    yaw = heading_deg_to_yaw(np.array([r["heading_deg"] for r in rows]))
    out: dict[str, float] = {"steps": float(len(rows)), "flips": float(_flips(t, yaw))}
    keep = [i for i, ti in enumerate(t) if float(ti) in p.probe]
    if keep and not np.isnan(p.probe[float(t[keep[0]])][2]):
        tk, yk = t[keep], yaw[keep]
        a = np.array([p.probe[float(x)][:2] for x in tk])
        om = np.array([p.probe[float(x)][2] for x in tk])
        agree = []
        for i in np.flatnonzero(np.abs(om) > TURN_RATE):
            near = (np.abs(tk - tk[i]) < 6.0) & (np.abs(om) < STRAIGHT_RATE)
            if near.sum() < 3:
                continue
            ac = a[i] - np.median(a[near], axis=0)
            agree.append(math.copysign(1.0, om[i]) * (ac[1] * math.cos(yk[i]) - ac[0] * math.sin(yk[i])) > 0)
        out["turn_strides"] = float(len(agree))
        out["turn_agree"] = float(np.mean(agree)) if agree else math.nan
    return out


def sim_scenario(side: str) -> dict[str, Any]:
    """A pocket walk with a left, a right and a U turn and three speeds, phone turned at random on the thigh."""
    return {"name": f"pocket_{side}", "placement": "trouser_pocket", "side": side, "mount_rpy_deg": "random",
            "start": {"position_m": [0, 0, 0], "heading_deg": 30, "floor": 0},
            "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "distance_m": 20, "speed_mps": 1.2},
                         {"type": "turn", "angle_deg": 90, "duration_s": 2},
                         {"type": "walk", "duration_s": 10, "speed_mps": 1.4},
                         {"type": "turn", "angle_deg": -180, "duration_s": 3},
                         {"type": "walk", "duration_s": 10, "speed_mps": 1.0}, {"type": "stand", "duration_s": 2}]}


def landmark_scenarios(side: str) -> list[dict[str, Any]]:
    """Pocket walks through a building with landmarks (seed 003 Sec. 6.1: walk, downstairs, walk, elevator,
    walk; and a walk with two different staircases), phone turned at random on the thigh.
    """
    pocket = {"placement": "trouser_pocket", "side": side, "mount_rpy_deg": "random"}
    return [
        {"name": f"pocket_{side}_stairs_elevator", **pocket,
         "start": {"position_m": [0, 0, 0], "heading_deg": 30, "floor": 1},
         "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "distance_m": 15, "speed_mps": 1.2},
                      {"type": "turn", "angle_deg": 90, "duration_s": 2},
                      {"type": "walk", "distance_m": 8, "speed_mps": 1.3},
                      {"type": "stairs", "direction": "down", "floors": 1},
                      {"type": "walk", "distance_m": 6, "speed_mps": 1.1},
                      {"type": "turn", "angle_deg": -90, "duration_s": 2},
                      {"type": "walk", "distance_m": 10, "speed_mps": 1.3}, {"type": "stand", "duration_s": 2},
                      {"type": "elevator", "direction": "up", "floors": 1},
                      {"type": "turn", "angle_deg": 180, "duration_s": 3, "speed_mps": 0},
                      {"type": "walk", "distance_m": 8, "speed_mps": 1.2},
                      {"type": "turn", "angle_deg": 90, "duration_s": 2},
                      {"type": "walk", "distance_m": 6, "speed_mps": 1.0}, {"type": "stand", "duration_s": 2}]},
        {"name": f"pocket_{side}_two_stairs", **pocket,
         "start": {"position_m": [0, 0, 0], "heading_deg": 200, "floor": 0},
         "segments": [{"type": "stand", "duration_s": 3}, {"type": "walk", "distance_m": 10, "speed_mps": 1.3},
                      {"type": "stairs", "direction": "up", "floors": 1},
                      {"type": "walk", "distance_m": 12, "speed_mps": 1.2},
                      {"type": "turn", "angle_deg": -90, "duration_s": 2},
                      {"type": "walk", "distance_m": 10, "speed_mps": 1.4},
                      {"type": "turn", "angle_deg": -90, "duration_s": 2},
                      {"type": "walk", "distance_m": 6, "speed_mps": 1.1},
                      {"type": "stairs", "direction": "down", "floors": 1},
                      {"type": "walk", "distance_m": 8, "speed_mps": 1.2}, {"type": "stand", "duration_s": 2}]},
    ]


def walk_errors(scenario: dict[str, Any], seed: int, site: Site | None = None, method: str = "ukf",
                pocket_axis: str = "auto") -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]], PdrPipeline]:
    """Absolute heading errors (deg) of the steps of one simulated walk (truth at mid-step), causal and after the
    offline smoother (:mod:`pdr.phone.heading_smoother`), its events and the pipeline that processed it (landmark
    counters). ``pocket_axis``: :attr:`pdr.phone.pipeline.PipelineConfig.pocket_axis`.
    """
    rec = simulate(scenario, seed)
    pipe = PdrPipeline(PipelineConfig(attitude_method=method, pocket_axis=pocket_axis), site=site)
    events = pipe.run(rec)
    rows = track_rows(events)
    assert rec.truth is not None
    tt, wh = rec.truth.extra["trajectory_t_s"], np.unwrap(rec.truth.extra["walking_heading_rad"])
    t = np.array([0.5 * (r["t_start_s"] + r["t_s"]) for r in rows])
    truth = np.interp(t, tt, wh)

    def errors(rr: list[dict[str, Any]]) -> np.ndarray:
        yaw = heading_deg_to_yaw(np.array([r["heading_deg"] for r in rr]))
        return np.degrees(np.abs(wrap_angle(yaw - truth)))

    return errors(rows), errors(smooth_track(rows)[0]), events, pipe


def sim_walk(side: str, seed: int, method: str = "ukf", pocket_axis: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Absolute heading errors (deg) of the steps of one simulated flat pocket walk (:func:`sim_scenario`),
    causal and smoothed.
    """
    causal, smoothed, _, _ = walk_errors(sim_scenario(side), seed, method=method, pocket_axis=pocket_axis)
    return causal, smoothed


def _summary(errs: list[np.ndarray]) -> dict[str, float]:
    e = np.concatenate(errs) if errs else np.zeros(0)
    return {"walks": float(len(errs)), "steps": float(e.size),
            "mean_abs_err_deg": float(e.mean()) if e.size else math.nan,
            "median_abs_err_deg": float(np.median(e)) if e.size else math.nan,
            "within_10_deg": float(np.mean(e < 10)) if e.size else math.nan,
            "share_over_90_deg": float(np.mean(e > 90)) if e.size else math.nan}


def register_eval(targets: argparse._SubParsersAction) -> None:
    ap = targets.add_parser("pocket-heading", help="trouser-pocket walking direction: simulated error, real flips")
    ap.add_argument("--sim-seeds", type=int, default=5, help="simulated walks per thigh and scenario (5)")
    ap.add_argument("--data", default="../shared/data", help="folder of the shared datasets (../shared/data)")
    ap.add_argument("--no-real", action="store_true", help="skip the MobiFall and Oxford walks")
    ap.add_argument("--no-sim", action="store_true", help="skip the simulated walks")
    ap.add_argument("--method", default="ukf", choices=("ukf", "ekf"), help="attitude filter (ukf: seed 003)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.set_defaults(func=run)


def run(a: argparse.Namespace) -> int:
    """Print the figures; returns the exit code."""
    out: dict[str, Any] = {"method": a.method}
    say = (lambda *_: None) if a.json else print
    if not a.no_sim:
        errs, errs_smoothed = [], []
        for side in ("left", "right"):
            for seed in range(a.sim_seeds):
                e, es = sim_walk(side, seed, a.method)
                errs.append(e)
                errs_smoothed.append(es)
                say(f"sim {side:5s} seed {seed}: {e.size} steps, mean |err| {e.mean():5.1f} deg, "
                    f">90 deg {np.mean(e > 90):.2f}; smoothed {es.mean():5.1f} deg")
        allerr, allsm = np.concatenate(errs), np.concatenate(errs_smoothed)
        say(f"SIM pocket ({len(errs)} walks, {allerr.size} steps): mean |err| {allerr.mean():.1f} deg, "
            f"median {np.median(allerr):.1f}, share >90 deg {np.mean(allerr > 90):.3f}, "
            f"walks with mean >90 deg {sum(float(e.mean()) > 90 for e in errs)}; smoothed offline: mean |err| "
            f"{allsm.mean():.1f} deg, median {np.median(allsm):.1f}")
        out["sim"] = {**_summary(errs), "walks_mean_over_90_deg": float(sum(float(e.mean()) > 90 for e in errs)),
                      "smoothed": _summary(errs_smoothed)}
        # Walks through landmarks, each processed without and with the site description of its scenario.
        without, with_site, without_sm, with_sm = [], [], [], []
        n_fix = n_heading = n_att = n_lm = 0
        for side in ("left", "right"):
            for sc in landmark_scenarios(side):
                doc = site_document(sc)
                site = Site.from_dict(doc)
                n_lm_sc = sum(1 for lm in doc["landmarks"] if lm["type"].startswith("stairs"))
                for seed in range(a.sim_seeds):
                    e0, e0s, _, _ = walk_errors(sc, seed, None, a.method)
                    e1, e1s, ev, pipe = walk_errors(sc, seed, site, a.method)
                    without.append(e0)
                    with_site.append(e1)
                    without_sm.append(e0s)
                    with_sm.append(e1s)
                    fixes = [x for x in ev if x.get("type") == "landmark"]
                    n_fix += len(fixes)
                    n_heading += pipe.landmark_updates
                    n_att += pipe.landmark_attitude_updates
                    n_lm += n_lm_sc
                    say(f"sim {sc['name']:28s} seed {seed}: {e1.size} steps, mean |err| {e0.mean():5.1f} deg "
                        f"without landmarks, {e1.mean():5.1f} with ({len(fixes)} of {n_lm_sc} staircases matched)")
        s0, s1, s0s, s1s = _summary(without), _summary(with_site), _summary(without_sm), _summary(with_sm)
        say(f"SIM pocket landmark walks ({len(with_site)} walks, {s1['steps']:.0f} steps): mean |err| "
            f"{s0['mean_abs_err_deg']:.2f} deg without landmarks, {s1['mean_abs_err_deg']:.2f} deg with landmarks "
            f"(median {s0['median_abs_err_deg']:.1f} / {s1['median_abs_err_deg']:.1f}, within 10 deg "
            f"{s0['within_10_deg']:.3f} / {s1['within_10_deg']:.3f}); staircases matched {n_fix}/{n_lm}, landmark "
            f"heading updates {n_heading} (attitude {n_att}); smoothed offline: {s0s['mean_abs_err_deg']:.2f} deg "
            f"without landmarks, {s1s['mean_abs_err_deg']:.2f} deg with (median {s0s['median_abs_err_deg']:.1f} / "
            f"{s1s['median_abs_err_deg']:.1f})")
        out["sim_landmarks"] = {"without": s0, "with": s1, "without_smoothed": s0s, "with_smoothed": s1s,
                                "staircases": float(n_lm),
                                "staircases_matched": float(n_fix), "landmark_heading_updates": float(n_heading),
                                "landmark_attitude_updates": float(n_att)}
    if a.no_real:
        if a.json:
            print(json.dumps(out, indent=2))
        return 0
    data = Path(a.data)
    tot = {"steps": 0.0, "flips": 0.0, "turn_strides": 0.0, "turn_agreeing": 0.0}
    for f in sorted(glob.glob(str(data / "mobifall_v2_pocket/sub*/ADL/WAL/WAL_acc_*.txt*"))):
        r = real_walk(read_recording(f), a.method)
        tot["steps"] += r["steps"]
        tot["flips"] += r["flips"]
        tot["turn_strides"] += r.get("turn_strides", 0.0)
        tot["turn_agreeing"] += r.get("turn_agree", 0.0) * r.get("turn_strides", 0.0) if r.get("turn_strides") else 0
        say(f"MobiFall {Path(f).name}: {r['steps']:.0f} steps, flips {r['flips']:.0f}, "
            f"turn check {r.get('turn_agree', math.nan):.2f} of {r.get('turn_strides', 0):.0f} turning strides")
    if tot["steps"]:
        say(f"MOBIFALL: {tot['flips']:.0f} flips in {tot['steps']:.0f} steps; turn check agrees on "
            f"{tot['turn_agreeing']:.0f}/{tot['turn_strides']:.0f} turning strides")
        out["mobifall"] = tot
    ox_steps = ox_flips = 0
    for d in sorted(glob.glob(str(data / "oxford_step_counter/optimisation/data/*_*ocket_*"))):
        r = real_walk(read_recording(d), a.method)
        ox_steps += int(r["steps"])
        ox_flips += int(r["flips"])
        say(f"Oxford {Path(d).name}: {r['steps']:.0f} steps, flips {r['flips']:.0f}")
    if ox_steps:
        say(f"OXFORD pocket: {ox_flips} flips in {ox_steps} steps")
        out["oxford"] = {"steps": float(ox_steps), "flips": float(ox_flips)}
    if a.json:
        print(json.dumps(out, indent=2))
    return 0
