"""``pdr simulate SCENARIO.json --seed N --out DIR``: write a simulated recording with ground truth.

``DIR`` becomes a native folder (:mod:`pdr.io.native`); ``.zip`` gives a zip of it, ``.json`` or
``.json.gz`` a ``pdr-batch/1`` document. ``--placement`` (and ``--side``) override the scenario's, so one
scenario yields the same walk seen from every placement. The scenario format is in
``pdr/sim/scenario.schema.json`` and ``mobile_logs/README.md``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from pdr.cli.progress import Progress
from pdr.errors import InputError
from pdr.io import native
from pdr.sim.scenario import SIM_PLACEMENTS, load_scenario, parse_scenario
from pdr.sim.simulate import simulate


def run(args: argparse.Namespace) -> int:
    if args.seed < 0:
        raise InputError(f"must be a non-negative integer, got {args.seed}", field="--seed")
    scenario = load_scenario(args.scenario)
    if args.placement or args.side:
        doc = dict(scenario.document)
        if args.placement:
            doc["placement"] = args.placement
        if args.side:
            doc["side"] = args.side
        scenario = parse_scenario(doc, source=str(args.scenario))
    out = Path(args.out)
    with Progress(2, "simulate") as bar:
        bar.set_note(f"{scenario.document.get('placement', '')} walk, seed {args.seed}")
        rec = simulate(scenario, args.seed)
        bar.advance(note=f"writing {out.name}")
        if out.name.endswith((".json", ".json.gz")):
            native.write_batch(rec, out)
        else:
            native.write(rec, out)
        bar.advance()
    tr = rec.truth
    pos = tr.positions.pos_m if tr.positions is not None else np.zeros((1, 3))
    path_m = float(np.sum(np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1)))
    rates = ", ".join(f"{k} {s.median_rate_hz():g} Hz" for k, s in rec.streams.items())
    print(f"wrote {out}: {rec.device.placement} ({rec.device.role}), {rec.duration_s:.2f} s, {rates}; "
          f"{tr.step_count} steps, {path_m:.1f} m walked, seed {args.seed}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("simulate", help="simulate a recording with ground truth from a scenario",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", metavar="SCENARIO.json", help="scenario file (JSON)")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="random seed (default 0)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder, .zip, .json or .json.gz")
    p.add_argument("--placement", choices=SIM_PLACEMENTS, help="override the scenario's placement")
    p.add_argument("--side", choices=("left", "right"), help="override the pocket leg / shoe side")
    p.set_defaults(func=run)
