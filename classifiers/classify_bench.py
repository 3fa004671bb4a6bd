"""``pdr bench classify LOG [--model NAME] [--repeat N] [--tile K]``: the speed of ``pdr classify LOG --model NAME``
on a real log, per stage in process and as a separate process.

Stages, in the order the command runs them: ``read`` (the log reader), ``load`` (the model), ``windows`` (resampling
and cutting the windows, :func:`classifiers.windows.make_windows`), ``features``
(:func:`classifiers.features.extract_features`), ``model`` (the rest of the model's ``classify``: posteriors, the
barometric stage, smoothing over the sequence, decisions and gating) and ``write`` (the CSV). The two inner stages
are timed by wrapping the functions that :mod:`classifiers.model` calls, for the run only; the code is not changed.
Wall and CPU time per stage as in ``pdr bench track`` (:class:`pdr.evaluation.track_bench.StageClock`); the separate
process runs as an installed package does (:func:`pdr.evaluation.track_bench.process_env`), warm: best of ``repeat``
after one untimed run.

Light on purpose: registering the command imports nothing of the classifiers (its arguments are ``pdr bench
track``'s, :func:`pdr.cli.bench_track.add_log_arguments`).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any

from pdr.cli.bench_track import add_log_arguments, log_arguments_error

#: Stage names in the order they are printed.
STAGES = ("read", "load", "windows", "features", "model", "write")


def register(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("classify", help="pdr classify on a real log with a model: wall time per stage and "
                                            "total, in process and as a separate process")
    add_log_arguments(p)
    p.add_argument("--model", default="motion_mode", help="model name or folder (default: motion_mode)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run_bench)


def time_classify(log: str | Path, model_name: str, out_csv: Path) -> dict[str, Any]:
    """One ``pdr classify LOG --model MODEL --out OUT`` in this process, timed per stage (module doc): wall seconds
    (``stages_s``, ``total_s``), CPU seconds (``stages_cpu_s``, ``total_cpu_s``), the windows and the log's length.
    """
    import classifiers.model as model_module
    from classifiers.artifacts import load_model
    from classifiers.classify_cli import write_modes_csv
    from pdr.evaluation.track_bench import StageClock
    from pdr.io import read_recording

    clock = StageClock(STAGES)
    t_start = clock.now()
    rec = read_recording(log)
    clock.add("read", t_start)
    t0 = clock.now()
    model = load_model(model_name)
    clock.add("load", t0)
    inner = {"make_windows": "windows", "extract_features": "features"}
    originals = {name: clock.wrap(model_module, name, stage) for name, stage in inner.items()}
    try:
        t0 = clock.now()
        res = model.classify(rec)
        clock.add("model", t0)
    finally:
        for name, fn in originals.items():
            setattr(model_module, name, fn)
    for times in (clock.seconds, clock.cpu_seconds):     # "model": classify's time less its timed stages
        times["model"] -= sum(times[s] for s in inner.values())
    t0 = clock.now()
    rows = res.rows(rec.origin_ns / 1e9)
    write_modes_csv(rows, out_csv)
    clock.add("write", t0)
    wall, cpu = clock.now()
    return {"stages_s": clock.seconds, "total_s": wall - t_start[0], "stages_cpu_s": clock.cpu_seconds,
            "total_cpu_s": cpu - t_start[1], "windows": len(rows), "duration_s": rec.duration_s}


def run(log: str | Path, model_name: str = "motion_mode", repeat: int = 1, tile: int = 1) -> dict[str, Any]:
    """Best-of-``repeat`` stage times of ``pdr classify`` on ``log`` (tiled ``tile`` times first when > 1) in this
    process (``least_cpu``: each stage's least CPU time over the runs), and the wall time of a separate warm process
    (``process_s``); ``same_output``: the process wrote the CSV this process did.
    """
    from pdr.evaluation.track_bench import process_env, tile_ipin_log, time_command
    from pdr.machine import environment

    with tempfile.TemporaryDirectory(prefix="pdr-bench-classify-") as tmp_dir:
        tmp = Path(tmp_dir)
        src = Path(log)
        if tile > 1:
            src = tile_ipin_log(log, tile, tmp / f"tiled{tile}_{Path(log).name}")
        runs = [time_classify(src, model_name, tmp / "modes.csv") for _ in range(max(1, repeat))]
        env = process_env(tmp / "pycache")
        command = ["classify", str(src), "--model", model_name, "--out", str(tmp / "modes_process.csv")]
        first = time_command(command, env)
        process_s = min(time_command(command, env) for _ in range(max(1, repeat)))
        same = (tmp / "modes.csv").read_bytes() == (tmp / "modes_process.csv").read_bytes()
        size = src.stat().st_size
    best = min(runs, key=lambda r: r["total_s"])
    least_cpu = {k: min(r["stages_cpu_s"][k] for r in runs) for k in STAGES}
    least_cpu["total"] = min(r["total_cpu_s"] for r in runs)
    return {"environment": environment(), "log": str(log), "model": model_name, "tile": tile, "bytes": size,
            "repeat": repeat, "best": best, "all_totals_s": [r["total_s"] for r in runs], "least_cpu": least_cpu,
            "process_first_s": first, "process_s": process_s, "same_output": same}


def run_bench(args: argparse.Namespace) -> int:
    from pdr.machine import environment_line

    if (error := log_arguments_error(args)) is not None:
        print(f"error: {error}", flush=True)
        return 2
    res = run(args.log, args.model, args.repeat, args.tile)
    if args.json:
        print(json.dumps(res, indent=2, default=str))
        return 0
    best, cpu = res["best"], res["least_cpu"]
    print(f"environment: {environment_line(res['environment'])}")
    print(f"log: {res['log']} x{res['tile']} ({res['bytes'] / 1e6:.1f} MB, {best['duration_s']:.0f} s, "
          f"{best['windows']} windows); model {res['model']}; best of {res['repeat']}")
    print(f"  {'stage':9s} {'wall':>8s}   {'CPU':>8s} (wall: the best run's; CPU: the least over the runs)")
    for stage in STAGES:
        print(f"  {stage:9s} {best['stages_s'][stage]:8.3f} s {cpu[stage]:8.3f} s")
    print(f"  {'total':9s} {best['total_s']:8.3f} s {cpu['total']:8.3f} s (in process)")
    print(f"  {'process':9s} {res['process_s']:8.3f} s (a separate `pdr classify` process, start-up and imports "
          f"included; warm: bytecode and compiled kernels cached, as after an install and one run; the first run, "
          f"its bytecode compiled, {res['process_first_s']:.3f} s)"
          + ("" if res["same_output"] else "; ITS CSV DIFFERS FROM THE IN-PROCESS ONE"))
    return 0 if res["same_output"] else 1
