"""The BLAS of a ``pdr`` process runs on one thread unless the user says otherwise (:func:`single_threaded_blas`).

What the commands ask of BLAS and LAPACK is small: a classifier's 167 x 167 covariance factored once, 3 x 3 and
9 x 9 products in the filters. OpenBLAS spreads even these over its threads, and waking them costs more than the
work, most of all on a busy machine: loading the shipped motion-mode model (one Cholesky factor and one inverse)
took 0.37-0.42 s with OpenBLAS's default threads and 0.014 s with one, and ``pdr classify`` of a one-hour log with
that model 3.4-4.1 s (3.5-3.8 s of CPU) against 2.7-3.3 s (2.3-2.8 s of CPU), on two cores while another process
ran (``OPENBLAS_NUM_THREADS=1`` against the default). The service's processes (``pdr serve``, ``pdr worker``) then set
their own count, ``PDR_NATIVE_THREADS`` (:func:`server.config.limit_native_threads`, also 1 by default).

The environment variables are read when numpy loads its BLAS, so they are set before numpy is imported, and only
where the user has not set them: ``OPENBLAS_NUM_THREADS=4 pdr ...`` still gives four.
"""

from __future__ import annotations

import os
import sys

#: The variables OpenBLAS, and the OpenMP and MKL builds of BLAS, read for their thread count.
VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def single_threaded_blas() -> bool:
    """Ask for one BLAS thread, where the user did not set a count; True if numpy was not loaded yet (so it
    applies).
    """
    if "numpy" in sys.modules:
        return False
    for name in VARIABLES:
        os.environ.setdefault(name, "1")
    return True
