"""Regenerate the golden files the tests compare against, in place; ``git status`` then shows what changed.

Targets (all by default):

``io``
    the reader fixtures: ``tests/pdr/io/fixtures/*/make_fixtures.py`` (synthetic exports of phyphox and Sensor
    Logger, seeded);
``sim``
    the simulated logs ``mobile_logs/sim/<name>.zip`` from ``<name>.json`` with seed 1 (``pdr simulate``);
``state``
    the rows the current pipeline gives when it resumes the frozen old-format session states in
    ``tests/pdr/phone/fixtures/*_state_v1.pdrstate.gz`` (``tests/pdr/phone/test_state_compat.py``);
``state-v1``
    (only when named) the frozen states themselves: a pipeline of the layout before the stage classes (commit
    9b83f3b) saved half-way through a simulated walk. Run it with that tree first on ``PYTHONPATH``
    (``git archive 9b83f3b pdr | tar -x -C /tmp/v1``, ``PYTHONPATH=/tmp/v1``), never with the current one: the point
    of these files is that an older pipeline wrote them.

Usage: ``python tools/regen_golden.py [TARGET ...] [--check]``; ``--check`` exits with 1 when a golden file changed.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import runpy
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
IO_FIXTURES = ROOT / "tests" / "pdr" / "io" / "fixtures"
SIM = ROOT / "mobile_logs" / "sim"
STATE_FIXTURES = ROOT / "tests" / "pdr" / "phone" / "fixtures"
#: Old-format state fixtures: name -> (scenario, seed, placement). Half of each walk runs before the state is saved.
STATE_WALKS = {"pocket_office": ("pocket_office.json", 2, "auto"), "hand_escalator": ("hand_escalator.json", 1, "hand")}
#: A short history keeps the fixtures small (the stride windows need about 2 s).
STATE_HISTORY_S = 4.0


def regen_io() -> list[Path]:
    paths = sorted(IO_FIXTURES.glob("*/make_fixtures.py"))
    for p in paths:
        runpy.run_path(str(p), run_name="__main__")
    return [p.parent for p in paths]


def regen_sim() -> list[Path]:
    from pdr.io import native
    from pdr.sim import load_scenario, simulate

    out = []
    for scenario in sorted(SIM.glob("*.json")):
        target = scenario.with_suffix(".zip")
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / target.name
            native.write(simulate(load_scenario(scenario), 1), fresh)
            # A zip records when it was written: keep the old file when every member is the same.
            if not target.exists() or _members(fresh) != _members(target):
                shutil.copyfile(fresh, target)
        out.append(target)
    return out


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {n: z.read(n) for n in z.namelist()}


def _walk(name: str) -> Any:
    from pdr.sim import load_scenario, simulate

    scenario, seed, _ = STATE_WALKS[name]
    return simulate(load_scenario(SIM / scenario), seed)


def _halves(rec: Any) -> tuple[Any, Any]:
    t0, t1 = rec.time_span_s()
    mid = 0.5 * (t0 + t1)
    return rec.slice_time(t0, mid), rec.slice_time(mid, t1 + 1.0)


def state_path(name: str) -> Path:
    return STATE_FIXTURES / f"{name}_state_v1.pdrstate.gz"


def rows_path(name: str) -> Path:
    return STATE_FIXTURES / f"{name}_resumed_rows.json"


def resumed_rows(name: str) -> list[dict[str, Any]]:
    """The event rows of the current pipeline resuming the frozen state ``name`` on the second half of its walk."""
    from pdr import state_codec
    from pdr.phone.pipeline import PdrPipeline

    state = state_codec.loads(gzip.decompress(state_path(name).read_bytes()))
    p = PdrPipeline.from_state(state)
    rows: list[dict[str, Any]] = p.update(_halves(_walk(name))[1]) + p.finish()
    return json.loads(json.dumps(rows))


def same_rows(a: Any, b: Any, rel: float = 1e-9) -> bool:
    """Equal event rows, numbers to within floating-point rounding (``rel``): the frozen rows were written with
    the numpy/numba of their day (and machine), and another may round the last bit of a sum differently.
    """
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_rows(a[k], b[k], rel) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_rows(x, y, rel) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        numbers = all(isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b))
        if not numbers:
            return False
        return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=rel, abs_tol=rel)
    return bool(a == b)


def regen_state() -> list[Path]:
    """Rewrite each walk's golden rows, unless the current rows are the same to within rounding (:func:`same_rows`,
    what the test accepts): a rewrite then would only record this machine's last bits.
    """
    out = []
    for name in STATE_WALKS:
        rows = resumed_rows(name)
        path = rows_path(name)
        if not (path.exists() and same_rows(rows, json.loads(path.read_text()))):
            path.write_text(json.dumps(rows, indent=None) + "\n")
        out.append(path)
    return out


def regen_state_v1() -> list[Path]:
    from pdr import state_codec
    from pdr.phone.pipeline import PdrPipeline, PipelineConfig

    STATE_FIXTURES.mkdir(parents=True, exist_ok=True)
    out = []
    for name, (_, _, placement) in STATE_WALKS.items():
        p = PdrPipeline(PipelineConfig(placement=placement, history_s=STATE_HISTORY_S))
        p.update(_halves(_walk(name))[0])
        state_path(name).write_bytes(gzip.compress(state_codec.dumps(p.state()), mtime=0))
        out.append(state_path(name))
    return out


TARGETS = {"io": regen_io, "sim": regen_sim, "state": regen_state, "state-v1": regen_state_v1}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("targets", nargs="*", choices=[*TARGETS, []], help="what to regenerate (default: io sim state)")
    ap.add_argument("--check", action="store_true", help="exit with 1 when a golden file changed")
    args = ap.parse_args(argv)
    written: list[Path] = []
    for t in args.targets or ["io", "sim", "state"]:
        written += TARGETS[t]()
    status = subprocess.run(["git", "status", "--porcelain", "--", *map(str, written)], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout
    print(status or "golden files unchanged", end="" if status else "\n")
    return 1 if args.check and status else 0


if __name__ == "__main__":
    sys.exit(main())
