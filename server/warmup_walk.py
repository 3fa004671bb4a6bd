"""The service's warm-up walk (:mod:`server.warmup`): :func:`pdr.phone.warm_up.warm_up` (pipeline and smoother on a
short simulated walk), then the text reader's compiled number parser and the motion-mode classifier's features.
``python -m server.warmup_walk`` runs it with the stand-in attitude filter: the child process of
:func:`server.warmup.start` (:mod:`pdr.phone.warm_up` module doc, "Compiling in two processes").
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from pdr.phone import warm_up as phone_warm_up
from pdr.recording import Recording

#: A few GetSensorData records, for the text reader's compiled number parser.
_IPIN_TEXT = (b"% 'GetSensorData'\nACCE;0.05;100.000;0.1;0.2;9.8;3\nACCE;0.07;100.020;0.1;0.2;9.8;3\n"
              b"POSI;0.08;1;49.4611;11.1110;0;100\n")


def warm_reader(recording: Recording) -> None:
    """The GetSensorData reader's compiled number parser, on a few records (``recording`` unused)."""
    from pdr.io import ipin

    with tempfile.TemporaryDirectory(prefix="pdr-warm-up-") as tmp:
        p = Path(tmp) / "warm_up.txt"
        p.write_bytes(_IPIN_TEXT)
        ipin.read(p)


def warm_classifier(recording: Recording) -> None:
    """The motion-mode classifier's compiled features, on the warm-up walk."""
    from classifiers.streaming import StreamingClassifier
    StreamingClassifier().update(recording)


def warm_up(attitude_filter: bool = True) -> float:
    """The phone path, the reader and the classifier once (:func:`pdr.phone.warm_up.warm_up`); wall time in s."""
    return phone_warm_up.warm_up(extra=(warm_reader, warm_classifier), attitude_filter=attitude_filter)


def main() -> int:
    """The child process of :func:`server.warmup.start`: the walk with the stand-in attitude; prints its seconds."""
    print(f"{warm_up(attitude_filter=False):.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
