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
:func:`clip_variance_peak` sizes that excess from the run itself instead of a fixed fraction of full scale: a
smooth rate peak that enters the clipped range with slope ``s`` and leaves it ``T`` later exceeds full scale by
about ``s t (1 - t / T)`` (a parabola), so short runs add little and long flat runs a lot.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.errors import InputError
from pdr.filters.compiled import cached_njit

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


def _runs(flags: BoolArray) -> zip[tuple[int, int]]:
    """``(start, end)`` sample indices (end exclusive) of each run of flagged samples."""
    d = np.diff(flags.astype(np.int8), prepend=0, append=0)
    return zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True)


def _run_positions(flags: BoolArray) -> NDArray[np.int64]:
    """Position of each flagged sample within its run (1, 2, ...; 0 where not flagged)."""
    idx = np.arange(flags.size)
    run_start = np.maximum.accumulate(np.where(~flags, idx + 1, 0))
    return np.where(flags, idx - run_start + 1, 0)


@cached_njit()
def add_clip_attitude_noise(P: Array, att: int, c_bn: Array, var_b: Array,
                            dt: float) -> None:  # pragma: no cover - compiled
    """``P[att:att+3, att:att+3] += C diag(var_b) C^T dt^2`` in place: the attitude process noise of one step
    whose clipped axes have the rate variances ``var_b`` ((rad/s)^2, body axes; :func:`clip_variance`), turned
    into the navigation frame by the body-to-navigation rotation ``c_bn`` (3, 3); ``att`` is the first attitude
    row of ``P``.
    """
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for c in range(3):
                acc += c_bn[i, c] * var_b[c] * c_bn[j, c]
            P[att + i, att + j] += acc * dt * dt


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
        n = _run_positions(f)
        out[:, axis] = np.where(f, (2.0 * n - 1.0) * (fraction * np.abs(w[:, axis])) ** 2, 0.0)
    return np.ascontiguousarray(out)


def clip_variance_peak(gyro_b: ArrayLike) -> Array:
    """(N, 3) attitude process-noise rate of clipped samples from the shape of each clipped peak, (rad/s)^2.

    A run of ``m`` clipped samples is taken as a smooth peak cut at full scale: entering with the slope ``s``
    (rad/s per sample; the larger of the slopes over the two unclipped samples before the run and the two after
    it, so that the soft compression at the run's edges does not lower it) and crossing full scale again at
    ``M = m + 1`` samples, its excess at the ``u``-th sample is ``e(u) = s u (1 - u / M)`` (peak ``s M / 4``).
    The attitude error after ``j`` samples, ``A_j = dt sum_{u<=j} e(u)``, is taken as the standard deviation
    of that sample's accumulated error (the sign is known, the size only roughly); the returned ``(A_j^2 -
    A_{j-1}^2) / dt^2`` is to be multiplied by ``dt^2``, as :func:`clip_variance`'s. A run summed gives ``(dt s
    m (m + 2) / 6)^2``.
    """
    w = np.asarray(gyro_b, dtype=np.float64)
    flags = clipped_samples(w)
    out = np.zeros(w.shape)
    n_s = w.shape[0]
    for axis in range(w.shape[1]):
        f = flags[:, axis]
        if not f.any():
            continue
        for a, b in _runs(f):
            s_in = abs(w[a - 1, axis] - w[a - 3, axis]) / 2.0 if a >= 3 else 0.0
            s_out = abs(w[b, axis] - w[b + 2, axis]) / 2.0 if b + 2 < n_s else 0.0
            slope = max(s_in, s_out)
            u = np.arange(1, b - a + 1, dtype=np.float64)
            big_m = b - a + 1.0
            cum = np.cumsum(slope * u * (1.0 - u / big_m))           # A_j / dt, rad/s * samples
            out[a:b, axis] = np.diff(cum**2, prepend=0.0)
    return np.ascontiguousarray(out)
