""":func:`pdr.io.android.rotation_vector_to_q_nb` compiled, for the readers of a process that has loaded numba: one
pass over the rows instead of a dozen whole-array numpy calls and their temporary arrays (175 000 rotation vectors, the
one-hour IPIN bench log: 20 ms by numpy, about 2 ms here).

The same operations in numpy's order, so the same bits (``tests/pdr/io/test_android_kernel.py`` compares them):
numpy's sum of a row of three or four squares (``np.sum(v * v, axis=1)``, ``np.linalg.norm(q, axis=-1)``) adds them
one after the other from the first; ``np.clip`` keeps a NaN; ``np.sqrt`` and ``math.sqrt`` are both the correctly
rounded square root; no product is fused into an addition (numba does not contract without ``fastmath``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel


@kernel
def q_nb_of_rotation_vectors(v: NDArray[np.float64]) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """(N, 4) unit ``q_nb`` (scalar first, non-negative) of the (N, 3) Android rotation vectors ``v`` (unitless
    quaternion parts) without their 4th value: ``w = sqrt(clip(1 - |v|^2, 0, 1))``, then ``[w, v]`` normalised
    (:func:`pdr.io.android.rotation_vector_to_q_nb`).
    """
    n = v.shape[0]
    out = np.empty((n, 4))
    for i in range(n):
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        s = 1.0 - (x * x + y * y + z * z)
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        w = math.sqrt(s)
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        q0, q1, q2, q3 = w / norm, x / norm, y / norm, z / norm
        if q0 < 0.0:
            q0, q1, q2, q3 = -q0, -q1, -q2, -q3
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = q0, q1, q2, q3
    return out
