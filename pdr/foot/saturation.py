"""Gyroscope clipping of foot IMUs and the process noise it calls for (issue #5).

A foot IMU clips its angular rate at full scale while the foot swings fast (the LORD 3DM-GX5-25 of
foot_stride_gcp at about 500 deg/s: walk 35 holds 413 samples within 2 % of its largest pitch rate; the
3DM-GX3-25 of PyShoe at about 500-530 deg/s). A clipped sample only says that the true rate is at least the
full-scale value, so integrating it loses attitude: during a sprint swing several degrees of pitch, which the
specific force of 30-80 m/s^2 turns into metres per second of velocity error by the next foot-down. A navigator
that decides the stance from the likelihood of the zero-velocity constraint (the filter bank, seed 002 eq. 6c;
belief condensation, seed 000 eq. 15) must carry that error in its covariance, otherwise the stance likelihood
vanishes and the unconstrained mode wins every later sample (the divergence of foot_stride_gcp walk 35).

:func:`clipped_samples` finds the clipped samples of a recording (a pile-up of samples at the largest absolute
value of an axis), :func:`clip_variance` gives the attitude process noise that the unknown excess rate adds:
the clipped value is the rate's lower bound, the excess stays (one sign) for the whole run of clipped samples.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: A sample within this fraction of an axis's largest absolute value counts as at full scale.
CLIP_TOLERANCE = 0.02
#: Samples at full scale needed before an axis counts as clipped.
CLIP_MIN_SAMPLES = 10
#: Separate excursions to full scale needed before an axis counts as clipped: a free signal reaches its largest
#: value in one event (at most 3 events within 2 % on the unclipped axes of the foot datasets), a clipped one
#: in every fast swing (foot_stride_gcp walk 35: 42; PyShoe running trials: 6-22).
CLIP_MIN_EVENTS = 4
#: Standard deviation of the unknown excess rate of a clipped sample, as a fraction of the full-scale value.
CLIP_EXCESS_FRACTION = 0.5


def clipped_samples(values: ArrayLike, tolerance: float = CLIP_TOLERANCE,
                    min_samples: int = CLIP_MIN_SAMPLES, min_events: int = CLIP_MIN_EVENTS) -> BoolArray:
    """(N, axes) flags of samples at full scale, per axis.

    An axis is clipped when ``min_samples`` or more of its samples, in ``min_events`` or more separate runs,
    lie within ``tolerance`` (fraction) of its largest absolute value; its flagged samples are those.
    """
    v = np.abs(np.asarray(values, dtype=np.float64))
    if v.ndim != 2 or not np.all(np.isfinite(v)):
        raise InputError("expected finite (N, axes) samples", field="values")
    if not (0.0 <= tolerance < 1.0) or min_samples < 1 or min_events < 1:
        raise InputError("tolerance must be in [0, 1), min_samples and min_events at least 1", field="tolerance")
    peak = v.max(axis=0)
    near = v >= (1.0 - tolerance) * peak[None, :]
    near &= peak[None, :] > 0
    starts = np.sum(np.diff(near.astype(np.int8), axis=0, prepend=0) == 1, axis=0)
    clipped = (near.sum(axis=0) >= min_samples) & (starts >= min_events)
    return np.asarray(near & clipped[None, :])


def clip_variance(gyro_b: ArrayLike, fraction: float = CLIP_EXCESS_FRACTION) -> Array:
    """(N, 3) attitude process-noise rate of clipped samples, (rad/s)^2 per body axis; 0 where not clipped.

    The excess rate of a run of clipped samples is one unknown constant with standard deviation ``fraction *
    |w|`` (the rate stays above full scale for the whole run): after ``n`` clipped samples its attitude error
    has the variance ``(n dt fraction |w|)^2``, so the ``n``-th sample of a run adds ``(2 n - 1) (fraction
    |w|)^2 dt^2``; the returned value is ``(2 n - 1) (fraction |w|)^2``, to be multiplied by ``dt^2``.
    """
    if not (np.isfinite(fraction) and fraction >= 0):
        raise InputError(f"must be a non-negative number, got {fraction}", field="fraction")
    w = np.asarray(gyro_b, dtype=np.float64)
    out = np.zeros(w.shape)
    if fraction == 0.0:
        return out
    flags = clipped_samples(w)
    for axis in range(w.shape[1]):
        f = flags[:, axis]
        if not f.any():
            continue
        # Position of each sample within its run of clipped samples (1, 2, ...).
        idx = np.arange(f.size)
        run_start = np.maximum.accumulate(np.where(~f, idx + 1, 0))
        n = np.where(f, idx - run_start + 1, 0)
        out[:, axis] = np.where(f, (2.0 * n - 1.0) * (fraction * np.abs(w[:, axis])) ** 2, 0.0)
    return np.ascontiguousarray(out)
