"""The warm-up walk of :mod:`server.warmup`: the phone path (pipeline, smoother, reader) and the motion-mode
classifier run once on a short simulated walk, so that their numba kernels are compiled into (or loaded from) the
cache. ``python -m server.warmup_walk`` runs it with :class:`TiltOnlyAttitude` in place of the attitude filter: the
child process of :func:`server.warmup.start` (:mod:`server.warmup` module doc, "Two processes on a fresh cache").
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr import quaternion as quat
from pdr.phone.attitude import AttitudeFilter

#: A short hand-held walk: straight, a turn, straight, so that steps, headings and the smoother all run.
_WALK = {"name": "warm_up", "placement": "hand", "start": {"position_m": [0, 0, 0], "heading_deg": 0},
         "rates_hz": {"acc": 100.0, "gyro": 100.0, "mag": 100.0, "baro": 10.0},
         "segments": [{"type": "stand", "duration_s": 2.0}, {"type": "walk", "duration_s": 12.0, "speed_mps": 1.3},
                      {"type": "turn", "angle_deg": 90, "duration_s": 2.0},
                      {"type": "walk", "duration_s": 12.0, "speed_mps": 1.3}]}
#: A few GetSensorData records, for the text reader's compiled number parser.
_IPIN_TEXT = (b"% 'GetSensorData'\nACCE;0.05;100.000;0.1;0.2;9.8;3\nACCE;0.07;100.020;0.1;0.2;9.8;3\n"
              b"POSI;0.08;1;49.4611;11.1110;0;100\n")



def warm_classifier(recording: Any) -> None:
    """The motion-mode classifier's compiled features, on the warm-up walk."""
    from classifiers.streaming import StreamingClassifier
    StreamingClassifier().update(recording)


def warm_up(extra: Sequence[Callable[[Any], object]] = (warm_classifier,), attitude_filter: bool = True) -> float:
    """Run the phone path once on a short simulated walk (pipeline, smoother, reader) and each of ``extra`` on
    that recording; returns the wall time in s. ``attitude_filter=False``: the pipeline's attitude filter is
    :class:`TiltOnlyAttitude` (the child process of :func:`start`, module doc).
    """
    from pdr.io import ipin
    from pdr.phone.heading_smoother import smooth_track
    from pdr.phone.pipeline import PdrPipeline, track_rows
    from pdr.sim import simulate

    t0 = time.perf_counter()
    rec = simulate(_WALK, 0)
    pipeline = PdrPipeline()
    if not attitude_filter:
        att = pipeline.attitude
        pipeline.attitude = TiltOnlyAttitude(att.rate_hz, att.config, att.method)
    smooth_track(track_rows(pipeline.run(rec)))
    with tempfile.TemporaryDirectory(prefix="pdr-warm-up-") as tmp:
        p = Path(tmp) / "warm_up.txt"
        p.write_bytes(_IPIN_TEXT)
        ipin.read(p)
    for f in extra:
        f(rec)
    return time.perf_counter() - t0


class TiltOnlyAttitude(AttitudeFilter):
    """Stand-in for the attitude filter in the warm-up's child process (module doc): each sample's attitude is the
    shortest rotation taking the specific force (body frame) onto up (ENU), yaw left free; no gyro, no field, no
    kernel, and the filter's state is left as it starts.
    """

    def run(self, acc_b: NDArray[np.float64], gyro_b: NDArray[np.float64] | None = None,
            mag_b: NDArray[np.float64] | None = None, carried: NDArray[np.bool_] | None = None
            ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        acc = np.ascontiguousarray(acc_b, dtype=np.float64)
        q = quat.from_two_vectors(acc, np.broadcast_to([0.0, 0.0, 1.0], acc.shape)) if acc.shape[0] else (
            np.zeros((0, 4)))
        return np.ascontiguousarray(q), np.zeros(acc.shape[0], dtype=np.int64)


def main() -> int:
    """The child process of :func:`server.warmup.start`: the walk with the stand-in attitude; prints its seconds."""
    print(f"{warm_up(attitude_filter=False):.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
