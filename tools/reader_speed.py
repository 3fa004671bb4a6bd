"""Wall time of the IPIN text reader (array path: compiled parser, and numpy's text reader that a short log read
without numba takes) and of its line-by-line path on a log tiled 1x, 4x, 16x, 24x.

``python tools/reader_speed.py LOG [--tiles 1 4 16 24] [--repeat 3]``: best of ``repeat`` per size, all paths in
the same process (the compiled number parser loaded first), so the ratios and the linearity in file size show.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from pdr.evaluation.track_bench import tile_ipin_log
from pdr.io import ipin
from pdr.io.text import read_bytes


def _best(f, repeat: int) -> float:  # noqa: ANN001
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("--tiles", type=int, nargs="+", default=[1, 4, 16, 24])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    import pdr.io.decimal_kernel  # noqa: F401  (numba loaded: ipin.read takes the compiled parser at every size)
    ipin.read(args.log)                                   # load the compiled parser
    with tempfile.TemporaryDirectory() as tmp:
        for k in args.tiles:
            p = tile_ipin_log(args.log, k, Path(tmp) / f"x{k}.txt")
            fast = _best(lambda p=p: ipin.read(p), args.repeat)
            text = _best(lambda p=p: ipin._read_text_fast(p, read_bytes(p), compiled=False), args.repeat)
            exact = _best(lambda p=p: ipin._read_text_exact(p, read_bytes(p)), max(1, args.repeat - 1))
            mb = p.stat().st_size / 1e6
            print(f"x{k:<3d} {mb:6.1f} MB  array path {fast:7.3f} s ({fast / mb * 1e3:5.1f} ms/MB)  "
                  f"numpy text reader {text:7.3f} s ({text / mb * 1e3:5.1f} ms/MB)  "
                  f"line-by-line {exact:7.3f} s ({exact / mb * 1e3:5.1f} ms/MB)  ratio {exact / fast:5.1f}x",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
