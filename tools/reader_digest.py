"""Digest of what the log readers make of every file of a data folder, to compare two versions of the readers.

``python tools/reader_digest.py ../shared/data --out new.json`` reads every file and folder a reader recognises
(:func:`pdr.io.detect_format`) and writes, per path, a SHA-256 of each stream's ``t_ns`` and values bytes, of the
ground truth's arrays and of the metadata (JSON, key order kept), or the error message. Run it once with the old
readers on ``PYTHONPATH`` (e.g. ``git archive BASE pdr | tar -x -C /tmp/base`` and ``PYTHONPATH=/tmp/base``) and
once with the new, then ``python tools/reader_digest.py --compare old.json new.json`` lists every difference:
bit-identical arrays give identical digests.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.io import detect_format, read_recording
from pdr.io.registry import _by_name


def _hash(*arrays: Any) -> str:
    h = hashlib.sha256()
    for a in arrays:
        arr = np.ascontiguousarray(a)
        h.update(str(arr.dtype).encode() + str(arr.shape).encode())
        h.update(arr.tobytes())
    return h.hexdigest()[:16]


def _truth_digest(truth: Any) -> dict[str, str]:
    out = {}
    for f in dataclasses.fields(truth):
        v = getattr(truth, f.name)
        if v is None:
            continue
        if dataclasses.is_dataclass(v):
            out[f.name] = _hash(*[np.asarray(x) for x in dataclasses.asdict(v).values()
                                  if isinstance(x, np.ndarray)]) + json.dumps(
                {k: x for k, x in dataclasses.asdict(v).items() if not isinstance(x, np.ndarray)}, default=str)
        else:
            out[f.name] = json.dumps(v, default=str)[:200]
    return out


def digest(path: Path) -> dict[str, Any]:
    """Per-stream, truth and metadata digests of the recordings read from ``path`` (or its error)."""
    try:
        fmt = detect_format(path)
        module = _by_name()[fmt]
        recs = module.read_all(path) if hasattr(module, "read_all") else [read_recording(path, fmt)]
    except InputError as exc:
        return {"error": str(exc)}
    out: dict[str, Any] = {"format": fmt, "recordings": []}
    for rec in recs:
        out["recordings"].append({
            "t0_ns": int(rec.t0_ns),
            "device": json.dumps(dataclasses.asdict(rec.device), default=str),
            "streams": {k: _hash(s.t_ns, s.values) for k, s in rec.streams.items()},
            "truth": _truth_digest(rec.truth),
            "meta": hashlib.sha256(json.dumps(rec.meta, default=str).encode()).hexdigest()[:16],
        })
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", nargs="?", help="data folder to read")
    ap.add_argument("--out", help="digest JSON to write")
    ap.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"), help="compare two digest files")
    args = ap.parse_args(argv)
    if args.compare:
        old, new = (json.loads(Path(p).read_text()) for p in args.compare)
        diff = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
        for k in diff:
            print(f"DIFFERENT {k}\n  old {old.get(k)}\n  new {new.get(k)}")
        read = sum(1 for v in new.values() if "format" in v)
        print(f"{len(new)} paths ({read} read, {len(new) - read} refused), {len(diff)} differ")
        return 1 if diff else 0
    root = Path(args.data)
    result = {}
    for p in sorted([root, *root.rglob("*")]):
        try:
            detect_format(p)
        except InputError:
            continue
        result[str(p.relative_to(root))] = digest(p)
        print(p, file=sys.stderr)
    Path(args.out).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
