"""The RTS smoother of the ZUPT-aided INS's error-state filter (:mod:`pdr.filters.rts`), checkpointed in
segments: the compiled backward pass and the segment-by-segment driver.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import cached_njit
from pdr.filters.rotation_kernels import quat_exp, quat_mul
from pdr.filters.rts import rts_step
from pdr.foot.zupt.config import ZuptConfig
from pdr.foot.zupt.kernel import FilterState, KernelOutput, KernelSetup, filter_rows
from pdr.foot.zupt.mechanisation import error_transition, propagate_covariance

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@cached_njit()
def zupt_smooth_kernel(t: Array, first: int, qa: float, qg: float, sm_P: Array, sm_fn: Array, sm_dx: Array,
                       pos: Array, vel: Array, qs: Array, pvar: Array, vvar: Array, avar: Array,
                       e_next: Array) -> None:  # pragma: no cover - compiled
    """RTS backward pass of the error-state filter (:mod:`pdr.filters.rts`) over samples ``first - 1..N-1``.

    ``F`` and the predicted covariance ``P_k+1|k = F P_k|k F^T + Q`` are rebuilt from the stored specific
    force instead of being stored. The smoothed errors correct ``pos, vel, qs`` in place as eq. 5 does
    (``q := exp(dtheta) q``); ``sm_P`` is overwritten by the smoothed covariances and ``pvar, vvar, avar`` by
    their diagonals. Without segmentation only (a reset of Algorithm 1 makes ``P_k+1|k`` singular).
    The last sample is taken as smoothed already: its smoothed error is ``e_next`` (zeros at the end of a
    recording) and its smoothed covariance ``sm_P[N-1]``; on return ``e_next`` holds the smoothed error of
    sample ``first - 1``, so that a recording can be smoothed segment by segment, last segment first.
    """
    n = t.size
    e = np.zeros(9)
    zero = np.zeros(9)
    for k in range(n - 2, first - 2, -1):
        dt = t[k + 1] - t[k]
        F = error_transition(sm_fn[k + 1], dt)
        Pp = sm_P[k].copy()
        propagate_covariance(Pp, F, dt, qa, qg)
        rts_step(zero, sm_P[k], F, -sm_dx[k + 1], Pp, e_next, sm_P[k + 1], e, sm_P[k])
        for i in range(3):
            pos[k, i] += e[i]
            vel[k, i] += e[3 + i]
        qk = quat_mul(quat_exp(e[6:9]), qs[k])
        qs[k] = qk / math.sqrt(qk[0] ** 2 + qk[1] ** 2 + qk[2] ** 2 + qk[3] ** 2)
        for i in range(3):
            pvar[k, i] = sm_P[k, i, i]
            vvar[k, i] = sm_P[k, 3 + i, 3 + i]
            avar[k, i] = sm_P[k, 6 + i, 6 + i]
        e_next[:] = e


#: Samples per segment of the checkpointed RTS smoother (:func:`run_kernel`): about 80 s at 200 Hz, 11 MB of
#: stored covariances whatever the recording's length.
SMOOTHER_SEGMENT = 1 << 14


def smooth_segments(t: Array, f_b: Array, w_b: Array, zv: BoolArray, flags: BoolArray, starts: list[int],
                     checkpoints: list[FilterState], segment: int, config: ZuptConfig, setup: KernelSetup,
                     out: KernelOutput) -> None:
    """Backward pass of :func:`run_kernel`, segment by segment from the last; ``out`` holds the filtered track."""
    n = t.size
    e_next = np.zeros(9)
    p_end: Array | None = None
    per_sample = (out.pos, out.vel, out.qs, out.pvar, out.vvar, out.avar)
    for a, checkpoint in zip(reversed(starts), reversed(checkpoints), strict=True):
        b = min(a + segment, n)
        rows = slice(a - 1, b)
        m = b - a + 1
        store = (np.zeros((m, 9, 9)), np.zeros((m, 3)), np.zeros((m, 9)))
        # The segment's last sample was smoothed with the next segment: filtering again must not overwrite it.
        kept = [arr[b - 1].copy() for arr in per_sample]
        filter_rows(t, f_b, w_b, zv, flags, rows, 1, checkpoint.copy(), config, setup, out, store)
        for arr, row in zip(per_sample, kept, strict=True):
            arr[b - 1] = row
        if p_end is not None:
            store[0][m - 1] = p_end
        zupt_smooth_kernel(t[rows], 1, config.sigma_acc**2, config.sigma_gyro**2, *store, out.pos[rows],
                           out.vel[rows], out.qs[rows], out.pvar[rows], out.vvar[rows], out.avar[rows], e_next)
        p_end = store[0][0].copy()
