"""``pdr bench phone``: the phone pipeline's speed on a simulated recording, and the attitude UKF against filterpy."""

from __future__ import annotations

import argparse
import json

from pdr.cli.track import parse_start
from pdr.errors import InputError


def register_bench(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("phone", help="phone pipeline speed on a simulated recording; attitude UKF vs filterpy")
    p.add_argument("--duration", type=float, default=3600.0, help="simulated recording length in s (default 1 h)")
    p.add_argument("--rate", type=float, default=100.0, help="sensor rate in Hz (default 100)")
    p.add_argument("--batch", type=float, default=0.0, help="feed batches of this many seconds (0: one batch)")
    p.add_argument("--site", nargs="?", const="", metavar="SITE.json",
                   help="also time the pipeline with the map-matching stage (pdr.mapmatch.stage) on this site from "
                        "--start; without a file, on a corridor 3 m wide about the walk's PDR track (a building the "
                        "steps fit)")
    p.add_argument("--start", metavar="E,N[,FLOOR]", help="start of the simulated walk on --site (m, its frame)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run_bench)


def run_bench(args: argparse.Namespace) -> int:
    from pdr.evaluation import phone_bench
    from pdr.machine import environment_line
    plan = start = None
    if args.site:
        if args.start is None:
            raise InputError("--site SITE.json needs --start E,N[,FLOOR] (or --site alone: a corridor about the "
                             "simulated walk)", source="command line", field="start")
        from pdr.site.plan import SitePlan
        plan = SitePlan.load(args.site)
        start_en, floor = parse_start(args.start, plan)
        plan.check_walkable(start_en, floor, "--start")
        start = (start_en, floor)
    res = phone_bench.run(args.duration, args.rate, args.batch, plan, start, corridor=args.site == "")
    if args.json:
        print(json.dumps(res, indent=2))
        return 0
    pl, at = res["pipeline"], res["attitude"]
    print(f"environment: {environment_line(res['environment'])}")
    print(f"recording: {res['recording']['duration_s']:.0f} s at {args.rate:g} Hz "
          f"(simulated in {res['recording']['simulate_s']:.1f} s)")
    print(f"pipeline: {pl['samples']} time steps in {pl['wall_s']:.2f} s = {pl['samples_per_s']:.0f} steps/s "
          f"({pl['times_real_time']:.0f}x real time), pipeline peak memory {pl['pipeline_peak_traced_mb']:.0f} MB "
          f"(process peak RSS incl. the simulated input {pl['peak_rss_mb']:.0f} MB), "
          f"{pl['steps']} steps; quarter/full wall {pl['linear_check']['quarter_s']:.2f}/"
          f"{pl['linear_check']['full_s']:.2f} s")
    fp = at.get("filterpy_samples_per_s")
    print(f"attitude: UKF {at['ukf_samples_per_s']:.0f} samples/s, EKF {at['ekf_samples_per_s']:.0f} samples/s, "
          f"filterpy UKF {'n/a (not installed)' if fp is None else f'{fp:.0f} samples/s'}")
    if "map" in res:
        m = res["map"]
        print(f"with map matching ({m['site']}, {m['walls']} walls, {m['particles']} particles): "
              f"{m['samples_per_s']:.0f} time steps/s ({m['times_real_time']:.0f}x real time; without the stage "
              f"{pl['samples_per_s']:.0f} above); the stage: {m['stage_steps']} step events in "
              f"{m['stage_wall_s']:.2f} s = {m['stage_steps_per_s']:.0f} steps/s (CPU time {m['stage_cpu_s']:.2f} s = "
              f"{m['stage_steps_per_cpu_s']:.0f} steps/s, {m['stage_times_real_time_cpu']:.0f}x real time), "
              f"{m['map_notices']} map-matching notices")
    return 0
