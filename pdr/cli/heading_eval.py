"""``pdr eval heading DIR``: walking direction and attitude against motion capture (:mod:`pdr.evaluation.heading`)."""

from __future__ import annotations

import argparse
import csv
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from pdr.cli.progress import Progress
from pdr.cli.track import compile_ahead, config_from_args
from pdr.evaluation.heading import evaluate, placement_for, recordings_in, report_lines
from pdr.phone.heading_smoother import smoothed_rows
from pdr.phone.pipeline import PipelineConfig
from pdr.recording import Recording


def write_step_table(table: dict[str, Any], path: Path) -> None:
    """One row per step of :attr:`pdr.evaluation.heading.RecordingScore.step_table` (headings to 0.1 deg)."""
    names = list(table)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for i in range(len(table["t_s"])):
            w.writerow([table[n][i] if n == "placement" else
                        f"{table[n][i]:.3f}" if n.endswith("_s") else f"{table[n][i]:.1f}" for n in names])


def register_eval(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("heading", help="walking direction per step and attitude against motion capture "
                                           "(Tyrex attitude benchmark), with the phone's rotation vector as reference")
    p.add_argument("dir", help="dataset folder (e.g. ../shared/data/attitude_smartphones), or one recording folder")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.add_argument("--limit", type=int, default=0, help="only the first N recordings (0: all)")
    p.add_argument("--steps", metavar="DIR", help="also write one CSV per recording into DIR: per step its times, "
                                                  "placement, true, causal, smoothed and rotation-vector +y headings")
    p.add_argument("--placement", default="auto", choices=("auto", "pocket", "torso", "hand", "swinging", "label"),
                   help="where the phone is carried: auto (as pdr track), pocket, torso, hand, swinging, or label "
                        "(each recording's own carriage: FrontPocket/BackPocket/RunningPocket -> pocket, "
                        "Swinging -> swinging, Texting -> hand)")
    p.add_argument("--calibration", help="step-length calibration JSON from `pdr calibrate`")
    p.add_argument("--method", default="ukf", choices=("ukf", "ekf"), help="attitude filter")
    p.add_argument("--perfect-attitude", action="store_true",
                   help="also run the pipeline on the motion capture's own attitude in place of its filter's, and "
                        "print what the walking-direction methods leave when the attitude is exact (twice the time)")
    p.add_argument("--use-phone-orientation", action="store_true",
                   help="ours WITH the phone's rotation vector as a gated yaw measurement of our attitude filter "
                        "(as pdr track --use-phone-orientation); the headline figures are without it")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # The configuration pdr track builds from the same options; `label` is resolved per recording.
    base = config_from_args(argparse.Namespace(**{**vars(args), "placement": "auto"}))

    def cfg_for(rec: Recording) -> PipelineConfig:
        return replace(base, placement=placement_for(rec, args.placement))

    folders = recordings_in(args.dir)
    compile_ahead(base.attitude_method)
    with Progress(min(len(folders), args.limit) if args.limit else len(folders), "eval heading") as bar:
        def progress(msg: str) -> None:
            # "NAME: done" advances the bar; anything else (a recording skipped) is a message for the user.
            if msg.endswith(": done"):
                bar.advance(note=msg.removesuffix(": done"))
            else:
                bar.write(msg)
                bar.advance()

        scores, agg = evaluate(args.dir, cfg_for, smoothed_rows, args.limit, progress, args.perfect_attitude)
    if args.steps:
        out = Path(args.steps)
        out.mkdir(parents=True, exist_ok=True)
        for s in scores:
            write_step_table(s.step_table, out / f"{s.name}.csv")
    if args.json:
        print(json.dumps({"placement": args.placement, "declination_deg": base.attitude.mag_declination_deg,
                          "use_phone_orientation": base.use_phone_orientation,
                          "recordings": [s.to_dict() for s in scores], **agg}, indent=2))
    else:
        if base.use_phone_orientation:
            print("ours WITH --use-phone-orientation (the phone's rotation vector as a yaw measurement of our filter)")
        for line in report_lines(scores, agg):
            print(line)
    return 0
