"""``pdr eval placement DATA``: the online placement detector against the datasets' carriage labels
(:mod:`pdr.evaluation.placement`).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pdr.cli.progress import Progress
from pdr.evaluation.placement import evaluate, report_lines, summary
from pdr.evaluation.walking_recordings import recordings


def register_eval(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("placement", help="the online placement detector against the carriage labels of the "
                                             "shared datasets (confusion matrix per dataset)")
    p.add_argument("data", help="folder holding the shared datasets (../shared/data)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    data = Path(args.data)
    total = sum(1 for _, _, walking in recordings(data) if walking)
    with Progress(total, "eval placement") as bar:
        results = evaluate(data, progress=lambda name: bar.advance(note=name))
    s = summary(results)
    if args.json:
        print(json.dumps(s, indent=1))
    else:
        print("\n".join(report_lines(s)))
    return 0
