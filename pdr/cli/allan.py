"""``pdr allan LOG [LOG ...] --out DIR``: Allan-variance characterisation report of static recordings.

Reads any supported log through :func:`pdr.io.read_recording`, characterises the gyroscope and/or
accelerometer (:mod:`pdr.allan`) and writes ``report.json``, ``<sensor>.png``, ``report.html``,
``imu.yaml`` and ``filter_params.json`` into DIR (into DIR/<log name>/ for several logs, plus
``comparison.json`` with the spread of N and B across the units).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pdr.allan.characterise import AXES, Settings, characterise_recording
from pdr.allan.confidence import ONE_SIGMA
from pdr.allan.estimators import allan_curve
from pdr.allan.pdr_impact import Walker
from pdr.allan.report import report_dict, write_comparison, write_report
from pdr.cli.progress import Progress
from pdr.errors import InputError
from pdr.io import read_recording


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "allan", help="Allan-variance noise characterisation of a static recording (report: JSON, PNG, HTML)",
        description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("logs", nargs="+", metavar="LOG", help="static recording(s) in any supported format")
    p.add_argument("--out", required=True, type=Path, help="report directory")
    p.add_argument("--format", default=None, help="force the log format (default: detect)")
    p.add_argument("--sensor", choices=("gyro", "acc", "both"), default="both")
    p.add_argument("--axis", nargs="+", choices=AXES, default=list(AXES), help="axes to analyse")
    p.add_argument("--taus-per-decade", type=_positive, default=6.0, help="density of the log-spaced averaging times")
    p.add_argument("--all-taus", action="store_true", help="every averaging factor m (slow for long records)")
    p.add_argument("--tau-min", type=_positive, default=None, help="shortest averaging time [s]")
    p.add_argument("--tau-max", type=_positive, default=None,
                   help="longest averaging time [s] (default: a quarter of the record)")
    p.add_argument("--estimators", nargs="+", choices=("overlapping", "nonoverlapping", "modified"),
                   default=["overlapping"], help="curves in the report (the fit always uses the overlapping one)")
    p.add_argument("--confidence", type=_fraction, default=ONE_SIGMA, help="confidence level of the intervals")
    p.add_argument("--disagreement", type=_non_negative, default=0.25,
                   help="relative difference between fit and slope reading that is flagged")
    p.add_argument("--gaps", choices=("longest", "error"), default="longest",
                   help="on gaps: analyse the longest unbroken segment, or refuse")
    p.add_argument("--motion", choices=("flag", "error"), default="flag",
                   help="on motion during the record: flag the report, or refuse")
    p.add_argument("--scale-factor-error", type=_finite, default=None, metavar="PCT",
                   help="stated gyro scale-factor error in %% for the PDR impact (default: Table 1 value of the grade)")
    p.add_argument("--step-length", type=_positive, default=0.75, help="walker step length [m] for the PDR impact")
    p.add_argument("--step-rate", type=_positive, default=2.0, help="walker step rate [steps/s] for the PDR impact")
    p.add_argument("--benchmark", action="store_true",
                   help="also time the overlapping estimator on all axes against allantools.oadev (if installed)")
    p.set_defaults(func=run)


def _number(kind: str, ok: Callable[[float], bool]) -> Callable[[str], float]:
    """An argparse ``type``: a float that ``ok`` accepts, else an argument error naming the option and ``kind``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and ok(value)):
            raise argparse.ArgumentTypeError(f"must be {kind}, got {text!r}")
        return value
    return parse


_finite = _number("a finite number", lambda v: True)
_positive = _number("a positive number", lambda v: v > 0)
_non_negative = _number("a number >= 0", lambda v: v >= 0)
_fraction = _number("a number between 0 and 1 (exclusive)", lambda v: 0 < v < 1)


def _best_of(fn, repeats: int = 3) -> tuple[float, float]:  # noqa: ANN001
    """(wall, cpu) seconds of the fastest of ``repeats`` runs (the machine may be shared)."""
    best = (float("inf"), float("inf"))
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        fn()
        best = min(best, (time.perf_counter() - w, time.process_time() - c))
    return best


def _benchmark(values: np.ndarray, rate: float, per_decade: float) -> str:
    curve = allan_curve(values, rate, per_decade=per_decade)
    ours = _best_of(lambda: allan_curve(values, rate, per_decade=per_decade))
    line = (f"benchmark (best of 3): overlapping ADEV of {values.shape[1]} axes x {values.shape[0]} samples at "
            f"{curve.m.size} taus: pdr.allan {ours[0]:.2f} s wall / {ours[1]:.2f} s CPU")
    try:
        import allantools
    except ImportError:
        return line + "; allantools not installed (pip install -e '.[test]') for the comparison"

    def reference() -> np.ndarray:
        return np.column_stack([allantools.oadev(values[:, j], rate=rate, data_type="freq", taus=curve.tau_s)[1]
                                for j in range(values.shape[1])])

    theirs = _best_of(reference)
    agree = float(np.max(np.abs(reference() / curve.adev - 1.0)))
    return (line + f" | allantools.oadev {theirs[0]:.2f} s wall / {theirs[1]:.2f} s CPU | speed ratio "
            f"{theirs[0] / ours[0]:.1f}x wall, {theirs[1] / ours[1]:.1f}x CPU | max rel. difference {agree:.1e}")


def run(args: argparse.Namespace) -> int:
    if args.tau_min is not None and args.tau_max is not None and args.tau_min > args.tau_max:
        raise InputError(f"{args.tau_min:g} s is above --tau-max {args.tau_max:g} s", field="--tau-min")
    settings = Settings(per_decade=args.taus_per_decade, tau_min_s=args.tau_min, tau_max_s=args.tau_max,
                        all_taus=args.all_taus,
                        extra_estimators=tuple(e for e in args.estimators if e != "overlapping"),
                        confidence=args.confidence, disagreement_tolerance=args.disagreement, gap_policy=args.gaps,
                        motion_policy=args.motion,
                        scale_factor_error=None if args.scale_factor_error is None else args.scale_factor_error / 100.0,
                        walker=Walker(step_length_m=args.step_length, step_rate_hz=args.step_rate))
    sensors = ("gyro", "acc") if args.sensor == "both" else (args.sensor,)
    reports = []
    names = [Path(p).name for p in args.logs]
    for log in args.logs:
        t0 = time.perf_counter()
        # Stages of one log on stderr (a TTY only): reading, the Allan analysis, the report's files and plots.
        with Progress(3, f"allan {Path(log).name}") as bar:
            bar.set_note("reading")
            rec = read_recording(log, format=args.format)
            t_read = time.perf_counter() - t0
            bar.advance(note="analysis")
            try:
                res = characterise_recording(rec, sensors=sensors, axes=tuple(args.axis), settings=settings)
            except InputError as exc:   # e.g. "stream 'gyro': has 3 samples": say which of the logs
                if exc.source is not None and str(log) in str(exc.source):
                    raise
                where = f"{log}, {exc.source}" if exc.source else str(log)
                raise InputError(exc.message, source=where, line=exc.line, field=exc.field) from None
            t_char = time.perf_counter() - t0 - t_read
            bar.advance(note="writing the report")
            out = args.out if len(args.logs) == 1 else args.out / _unique(Path(log).name, names)
            paths = write_report(res, out)
            bar.advance()
        data = report_dict(res)
        reports.append(data)
        t_all = time.perf_counter() - t0
        print(f"{log}: read {t_read:.2f} s, analysis {t_char:.2f} s, total {t_all:.2f} s -> {paths['html']}")
        for s, sr in res.sensors.items():
            terms = []
            for ax_name, ax in sr.axes.items():
                terms.append(f"{ax_name}: " + ", ".join(
                    f"{k}={v:.3g}" if v is not None else f"{k}=unresolved" for k, v in ax.fit.value.items()
                    if k in ("N", "B", "K")))
            print(f"  {s} [{sr.unit}] grade {sr.grade}; " + "; ".join(terms))
        for f in data["flags"]:
            print(f"  flag: {f}")
        if args.benchmark:
            vals = [rec.values(s)[:, [AXES.index(a) for a in args.axis]] for s in sensors if rec.has(s)]
            n = min(v.shape[0] for v in vals)
            rate = next(sr.rate_hz for sr in res.sensors.values())
            print("  " + _benchmark(np.column_stack([v[:n] for v in vals]), rate, args.taus_per_decade))
    if len(reports) > 1:
        p = write_comparison(reports, args.out)
        comp = json.loads(p.read_text())
        for s, sens in comp["sensors"].items():
            for a in args.axis:
                if a in sens:
                    row = sens[a]
                    print(f"  spread across units, {s} {a}: " + "; ".join(
                        f"{k} mean {row[k]['mean']:.3g} cv {row[k]['cv_pct']:.2g} %" if row[k]["cv_pct"] is not None
                        else f"{k} resolved in {row[k]['n_resolved']}" for k in ("N", "B")))
        print(f"comparison: {p}")
    return 0


def _unique(name: str, names: list[str]) -> str:
    return name if names.count(name) == 1 else f"{name}_{names.index(name)}"
