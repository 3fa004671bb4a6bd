"""``pdr bench track LOG [--repeat N] [--tile K] [--cold]``: wall time per stage of ``pdr track``
(:mod:`pdr.evaluation.track_bench`), and of separate processes (start-up).

Light on purpose: the parser imports nothing of the pipeline; the bench module is imported when the command runs.
"""

from __future__ import annotations

import argparse
import json


def register(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("track", help="pdr track on a real log: wall time per stage and total, against the "
                                         "ahrs package's EKF on the same data when it is installed")
    add_log_arguments(p)
    p.add_argument("--cold", action="store_true",
                   help="also time one pdr track process with empty bytecode and compiled-kernel caches (a fresh "
                        "install's first run: every kernel compiles, a minute or more)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run)


def add_log_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of a benchmark of a command on one real log: ``LOG``, ``--repeat``, ``--tile``
    (:func:`log_arguments_error`).
    """
    p.add_argument("log", help="log file (any supported format; --tile needs a GetSensorData .txt)")
    p.add_argument("--repeat", type=int, default=1, help="runs; the best is reported (default 1)")
    p.add_argument("--tile", type=int, default=1,
                   help="first tile the GetSensorData log this many times in a temporary folder (24: a 154 s "
                        "walk becomes one hour)")


def log_arguments_error(args: argparse.Namespace) -> str | None:
    """What is wrong with the arguments of :func:`add_log_arguments`, or None."""
    return "--repeat and --tile must be at least 1" if args.repeat < 1 or args.tile < 1 else None


def run(args: argparse.Namespace) -> int:
    from pdr.evaluation import track_bench as bench_track
    from pdr.machine import environment_line
    if (error := log_arguments_error(args)) is not None:
        print(f"error: {error}", flush=True)
        return 2
    res = bench_track.run(args.log, args.repeat, args.tile, args.cold)
    if args.json:
        print(json.dumps(res, indent=2, default=str))
        return 0
    best = res["best"]
    print(f"environment: {environment_line(res['environment'])}")
    print(f"log: {res['log']} x{res['tile']} ({res['bytes'] / 1e6:.1f} MB, {best['duration_s']:.0f} s, "
          f"{best['acc_samples']} acc samples, {best['steps']} steps); best of {res['repeat']}")
    cpu = res["least_cpu"]
    print(f"  {'stage':9s} {'wall':>8s}   {'CPU':>8s} (wall: the best run's; CPU: the least over the runs)")
    for stage in bench_track.STAGES:
        print(f"  {stage:9s} {best['stages_s'][stage]:8.3f} s {cpu[stage]:8.3f} s")
    print(f"  {'total':9s} {best['total_s']:8.3f} s {cpu['total']:8.3f} s = {res['samples_per_s']:.0f} samples/s "
          "(in process)")
    up = res["start_up"]
    print(f"  {'process':9s} {res['process_s']:8.3f} s = {res['process_samples_per_s']:.0f} samples/s "
          f"(a separate `pdr track` process, start-up and imports included; warm: bytecode and compiled kernels "
          f"cached, as after an install and one run)")
    print(f"start-up (separate processes): `pdr track` with the bytecode cache empty (every module compiled from "
          f"source, the dependencies' too) {up['track_first_s']:.3f} s; "
          f"warm `pdr --help` {up['help_s']:.3f} s, `pdr inspect LOG` (the log as given, not tiled) "
          f"{up['inspect_s']:.3f} s")
    if up["track_cold_s"] is not None:
        print(f"  cold `pdr track` (bytecode and compiled-kernel caches empty: a fresh install's first run) "
              f"{up['track_cold_s']:.1f} s")
    e = res["ahrs_ekf"]
    if e is None:
        print("ahrs EKF: n/a (the ahrs package is not installed)")
    else:
        print(f"ahrs {e.get('version', '?')} EKF: {e['wall_s']:.3f} s = {e['samples_per_s']:.0f} samples/s "
              f"(attitude only); "
              f"pdr track is {res['ratio_to_ahrs_ekf']:.1f}x its rate in process, "
              f"{res['process_ratio_to_ahrs_ekf']:.1f}x as a process")
    return 0
