"""pdr.io.android_kernel: the compiled rotation-vector conversion gives numpy's bits."""

from __future__ import annotations

import numpy as np

from pdr import quaternion as quat
from pdr.io.android_kernel import q_nb_of_rotation_vectors


def _numpy(v: np.ndarray) -> np.ndarray:
    """The numpy expressions of pdr.io.android.rotation_vector_to_q_nb without a logged w."""
    w = np.sqrt(np.clip(1.0 - np.sum(v * v, axis=1), 0.0, 1.0))
    return quat.normalize(np.column_stack([w, v]))


def test_the_kernel_gives_numpys_bits_on_random_vectors_strided_and_edge_rows() -> None:
    rng = np.random.default_rng(11)
    rows = rng.normal(size=(200_000, 9)) * rng.choice([1e-6, 0.3, 0.6, 2.0], size=(200_000, 1))
    v = rows[:, 5:8]                                       # a strided view, as the readers pass it
    edges = np.array([[0.0, 0.0, 0.0], [-0.0, -0.0, -0.0], [1.0, 0.0, 0.0], [0.6, 0.8, 0.0], [2.0, -3.0, 1.0],
                      [np.nan, 0.1, 0.2], [1e-300, -1e-300, 1e-160], [0.5, 0.5, 0.5]])
    for x in (v, edges, np.ascontiguousarray(v[:7])):
        got, want = q_nb_of_rotation_vectors(x), _numpy(x)
        assert got.tobytes() == want.tobytes()
