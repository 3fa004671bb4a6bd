"""``pdr eval coop``: the cooperative-localization simulations of seed 001 Sec. 5.1 and the fusion's cost."""

from __future__ import annotations

import argparse
import json
import os
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.evaluation.coop import (
    cost_experiment,
    influence_function,
    kalman_config,
    march_experiment,
    static_experiment,
)


def _int_list(text: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise InputError(f"expected comma-separated integers, got '{text}'", field="--agents") from None
    if not values or min(values) < 1:
        raise InputError("group sizes must be positive integers", field="--agents")
    return values


def _at(distance: np.ndarray, values: np.ndarray, marks: list[float]) -> list[float]:
    return [float(values[int(np.argmin(np.abs(distance - m)))]) for m in marks]


def evaluate(args: argparse.Namespace) -> dict[str, Any]:
    """All figures as a JSON-serialisable dict."""
    counts = _int_list(args.agents)
    if args.runs < 2 or args.duration <= 0 or args.static_duration <= 0:
        raise InputError("needs --runs >= 2 and positive durations", field="--runs")
    if args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}", field="--workers")
    march = march_experiment(counts, args.duration, args.runs, args.seed, workers=args.workers)
    kalman = march_experiment((2,), args.duration, args.runs, args.seed, fusion=kalman_config(), workers=args.workers)
    robust_rel = float(march.rel_rmse_m[list(march.agent_counts).index(2), -1]) if 2 in counts else None
    marks = [d for d in (10.0, 50.0, 100.0, 200.0, 500.0) if d <= march.distance_m[-1]] + [float(march.distance_m[-1])]
    static = static_experiment(args.static_duration, args.runs, args.seed, workers=args.workers)
    third = static.t_s.size // 3
    infl = influence_function(np.array([-5.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 5.0, 10.0, 50.0]))
    out: dict[str, Any] = {
        "march": {
            "runs": march.runs, "distance_m": float(march.distance_m[-1]),
            "exponent": march.exponent, "coefficient_m": march.coefficient_m,
            "rmse_by_agents": {str(n): float(r) for n, r in zip(march.agent_counts, march.abs_rmse_m[:, -1],
                                                                  strict=True)},
            "relative_rmse_by_agents": {str(n): float(r) for n, r in zip(march.agent_counts, march.rel_rmse_m[:, -1],
                                                                           strict=True)},
            "max_relative_rmse_m": float(np.max(march.rel_rmse_m[march.agent_counts > 1])) if np.any(
                march.agent_counts > 1) else None,
            "correlation": {"distance_m": marks,
                            **{f"{ax}_mc": _at(march.distance_m, march.correlation_mc[:, i], marks)
                               for i, ax in enumerate("xyz")},
                            **{f"{ax}_filter": _at(march.distance_m, march.correlation_filter[:, i], marks)
                               for i, ax in enumerate("xyz")}},
            "kalman_relative_rmse_2_agents_m": float(kalman.rel_rmse_m[0, -1]),
            "robust_relative_rmse_2_agents_m": robust_rel,
        },
        "static": {
            "runs": static.runs, "duration_s": float(static.t_s[-1]),
            "max_rmse_m": float(np.max(static.rmse_m)),
            "final_rmse_m": float(static.rmse_m[-1]),
            "middle_third_mean_rmse_m": float(np.mean(static.rmse_m[third:2 * third])),
            "last_third_mean_rmse_m": float(np.mean(static.rmse_m[2 * third:])),
            "dead_reckoning_final_rmse_m": float(static.rmse_dead_reckoning_m[-1]),
            "static_agents_rmse_m": static.static_rmse_m,
        },
        "influence": {
            "residual_m": infl.residual_m.tolist(),
            **{f"robust_p{v:g}": infl.robust_m[i].tolist() for i, v in enumerate(infl.prior_variance_m2)},
            **{f"kalman_p{v:g}": infl.kalman_m[i].tolist() for i, v in enumerate(infl.prior_variance_m2)},
        },
    }
    if not args.no_cost:
        cost = cost_experiment(_int_list(args.cost_agents), args.cost_duration, args.seed)
        out["cost"] = {str(n): {"uplink_values_per_s": float(cost.uplink_values_per_s[i]),
                                "downlink_values_per_s": float(cost.downlink_values_per_s[i]),
                                "step_update_ms": float(cost.step_update_ms[i]),
                                "range_update_ms": float(cost.range_update_ms[i]),
                                "realtime_factor": float(cost.realtime_factor[i])}
                       for i, n in enumerate(cost.group_sizes)}
    return out


def _print(out: dict[str, Any]) -> None:
    m = out["march"]
    print(f"march ({m['runs']} runs, {m['distance_m']:.0f} m): final absolute RMSE by agents "
          + ", ".join(f"N={n}: {r:.2f} m" for n, r in m["rmse_by_agents"].items()))
    print(f"march: fitted RMSE = {m['coefficient_m']:.2f} m * N^-{m['exponent']:.2f} (seed: N^-0.5)")
    print("march: final relative RMSE "
          + ", ".join(f"N={n}: {r:.2f} m" for n, r in m["relative_rmse_by_agents"].items())
          + (f"; max over distance {m['max_relative_rmse_m']:.2f} m" if m["max_relative_rmse_m"] is not None else ""))
    c = m["correlation"]
    print("march Fig. 12 correlation (2 agents) at " + ", ".join(f"{d:.0f}" for d in c["distance_m"]) + " m:")
    for ax in "xyz":
        print(f"  {ax}: Monte Carlo " + " ".join(f"{v:+.2f}" for v in c[f"{ax}_mc"])
              + " | filter " + " ".join(f"{v:+.2f}" for v in c[f"{ax}_filter"]))
    if m["robust_relative_rmse_2_agents_m"] is not None:
        print(f"march, 2 agents, Cauchy ranges: final relative RMSE robust {m['robust_relative_rmse_2_agents_m']:.2f} m"
              f" vs Kalman {m['kalman_relative_rmse_2_agents_m']:.2f} m")
    s = out["static"]
    print(f"static ({s['runs']} runs, {s['duration_s']:.0f} s): walker RMSE max {s['max_rmse_m']:.2f} m, "
          f"final {s['final_rmse_m']:.2f} m (mean middle third {s['middle_third_mean_rmse_m']:.2f} m, last third "
          f"{s['last_third_mean_rmse_m']:.2f} m); dead reckoning alone final {s['dead_reckoning_final_rmse_m']:.2f} m")
    i = out["influence"]
    print("influence (Fig. 8, ||z1|| = 10 m) residual m: " + " ".join(f"{r:+6.1f}" for r in i["residual_m"]))
    for key in [k for k in i if k != "residual_m"]:
        print(f"  {key:>12}: " + " ".join(f"{v:+6.2f}" for v in i[key]))
    for n, row in out.get("cost", {}).items():
        print(f"cost N={n}: per agent {row['uplink_values_per_s']:.1f} values/s up, "
              f"{row['downlink_values_per_s']:.1f} down; centre {row['step_update_ms']:.2f} ms per step update, "
              f"{row['range_update_ms']:.2f} ms per range; {row['realtime_factor'] * 100:.1f} % of real time")


def evaluate_real(args: argparse.Namespace) -> dict[str, Any]:
    """``--real``: the group of real foot recordings with simulated ranges (:mod:`pdr.evaluation.coop_real`)."""
    from pathlib import Path

    from pdr.evaluation.coop_real import load_pyshoe_agents, real_coop_report

    root = Path(args.data)
    if not root.is_dir():
        raise InputError(f"no folder {root} (the PyShoe VICON trials, ../shared/data/pyshoe_vicon)", field="--data")
    if args.runs < 1 or args.real_agents < 2:
        raise InputError("needs --runs >= 1 and --real-agents >= 2", field="--real-agents")
    names = [n.strip() for n in args.trials.split(",") if n.strip()] if args.trials else []
    agents = load_pyshoe_agents(root, args.real_agents, names)
    return real_coop_report(agents, args.runs, args.seed, args.spacing, args.bias_deg_per_step)


def _print_real(out: dict[str, Any]) -> None:
    print(f"protocol: {out['protocol']}")
    print(f"agents: {', '.join(f'{a} ({n} resets)' for a, n in zip(out['agents'], out['steps'], strict=True))}; "
          f"{out['duration_s']:.1f} s together, {out['runs']} noise draws, {out['spacing_m']:g} m apart")
    for c in out["conditions"]:
        bias = f"; {c['biased_agent']} drifts {c['bias_deg_per_step']:g} deg/step" if c["biased_agent"] else ""
        print(f"{c['condition']}{bias} ({c['ranges']} ranges): horizontal RMSE alone -> in the group, m:")
        for a in out["agents"]:
            verdict = "helped" if c["helped"][a] else ("hurt" if c["hurt"][a] else "no change")
            print(f"  {a}: {c['rmse_dead_reckoning_m'][a]:.3f} -> {c['rmse_group_m'][a]:.3f} ({verdict})")


def run_eval(args: argparse.Namespace) -> int:
    real = args.real
    out = evaluate_real(args) if real else evaluate(args)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        (_print_real if real else _print)(out)
    return 0


def register_eval(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("coop", help="cooperative localization: seed 001 simulations (march, static), cost")
    p.add_argument("--json", action="store_true", help="print figures as JSON")
    p.add_argument("--runs", type=int, default=30, help="Monte Carlo runs per scenario (default 30)")
    p.add_argument("--agents", default="1,2,4,8", help="group sizes of the march (default 1,2,4,8)")
    p.add_argument("--duration", type=float, default=200.0, help="march duration, s (1 m steps at 1 Hz)")
    p.add_argument("--static-duration", type=float, default=300.0, help="static scenario duration, s")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="processes for the Monte Carlo runs (default: one per CPU; the figures do not depend on it)")
    p.add_argument("--cost-agents", default="2,8,32", help="group sizes timed for the cost figures")
    p.add_argument("--cost-duration", type=float, default=30.0, help="simulated seconds timed per group size")
    p.add_argument("--no-cost", action="store_true", help="skip the timing")
    p.add_argument("--real", action="store_true",
                   help="instead: a group of real foot recordings (PyShoe VICON trials) with ranges simulated from "
                        "their truth, dead reckoning alone vs the group, per agent (protocol in the output)")
    p.add_argument("--data", default="../shared/data/pyshoe_vicon", help="--real: folder of the PyShoe VICON trials")
    p.add_argument("--real-agents", type=int, default=3, help="--real: number of agents (the longest trials)")
    p.add_argument("--trials", default="",
                   help="--real: comma-separated trial names instead (e.g. 2017-11-27-11-18-11)")
    p.add_argument("--spacing", type=float, default=10.0, help="--real: agents walk this far apart (m, north)")
    p.add_argument("--bias-deg-per-step", type=float, default=3.0,
                   help="--real: heading drift given to the first agent in the second set of conditions (0: none)")
    p.set_defaults(func=run_eval)
