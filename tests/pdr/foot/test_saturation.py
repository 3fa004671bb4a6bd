"""Gyroscope clipping: detection and the attitude process noise it adds (pdr.foot.saturation)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.foot.saturation import clip_variance, clip_variance_peak, clipped_samples


def _pulse_train(amplitudes: np.ndarray, rate_hz: float = 200.0, pulse_s: float = 0.3,
                 gap_s: float = 0.8) -> np.ndarray:
    """(N, 3) angular rate: half-sine pitch-rate pulses of the given amplitudes (rad/s) on the y axis."""
    n_p, n_g = int(pulse_s * rate_hz), int(gap_s * rate_hz)
    pulse = np.sin(np.pi * np.arange(n_p) / n_p)
    y = np.concatenate([np.concatenate([a * pulse, np.zeros(n_g)]) for a in amplitudes])
    w = np.zeros((y.size, 3))
    w[:, 1] = y
    w[:, 0] = 0.3 * np.random.default_rng(1).standard_normal(y.size)
    return w


def test_clipped_pulses_are_found_and_free_ones_are_not() -> None:
    rng = np.random.default_rng(3)
    free = _pulse_train(rng.uniform(5.0, 11.0, 20))
    limit = np.radians(500.0)
    clipped = free.copy()
    clipped[:, 1] = np.clip(clipped[:, 1], -limit, limit)
    flags = clipped_samples(clipped)
    truth = np.abs(clipped[:, 1]) >= 0.98 * limit       # at full scale, within the 2 % tolerance
    assert np.sum(np.abs(free[:, 1]) >= limit) > 50
    assert np.array_equal(flags[:, 1], truth)
    assert not flags[:, [0, 2]].any()
    assert not clipped_samples(free).any()


def test_clip_variance_grows_like_a_constant_unknown_excess() -> None:
    limit = np.radians(500.0)
    w = _pulse_train(np.array([12.0, 6.0, 12.0, 7.0, 11.0, 13.0, 12.0]))
    w[:, 1] = np.clip(w[:, 1], -limit, limit)
    fraction = 0.5
    v = clip_variance(w, fraction)
    assert np.all(v[:, [0, 2]] == 0.0)
    runs = np.flatnonzero(np.diff(np.concatenate([[0], (v[:, 1] > 0).astype(int), [0]])))
    starts, ends = runs[::2], runs[1::2]
    assert starts.size == 5
    for s, e in zip(starts, ends, strict=True):
        # Summed over a run of n samples: (n * fraction * limit)^2, the variance of a constant excess.
        n = e - s
        excess_sd = fraction * np.abs(w[s:e, 1])
        assert np.isclose(v[s:e, 1].sum(), np.sum((2 * np.arange(1, n + 1) - 1) * excess_sd**2))
        assert np.isclose(v[s:e, 1].sum(), (n * fraction * limit) ** 2, rtol=0.04)
    assert np.all(clip_variance(w, 0.0) == 0.0)


def test_peak_clip_variance_matches_the_lost_rotation() -> None:
    # Half-sine pitch-rate pulses cut at 500 deg/s: the rotation lost in each clipped run (the area of the pulse
    # above full scale) is what the peak model's standard deviation should be of the size of; a barely clipped
    # peak gets up to the area of the 2 % tolerance band the flags include (about 0.01 rad here) on top.
    limit = np.radians(500.0)
    amps = np.array([9.0, 12.0, 15.0, 6.0, 10.0, 18.0])
    free = _pulse_train(amps)
    w = free.copy()
    w[:, 1] = np.clip(w[:, 1], -limit, limit)
    v = clip_variance_peak(w)
    assert np.all(v[:, [0, 2]] == 0.0) and np.all(v >= 0.0)
    runs = np.flatnonzero(np.diff(np.concatenate([[0], (v[:, 1] > 0).astype(int), [0]])))
    starts, ends = runs[::2], runs[1::2]
    assert starts.size == 5                              # the 6 rad/s pulse is not clipped
    dt = 1.0 / 200.0
    sds = []
    for s, e in zip(starts, ends, strict=True):
        lost = float(np.sum(np.clip(np.abs(free[s - 3:e + 3, 1]) - limit, 0.0, None))) * dt     # rad
        sd = math.sqrt(v[s:e, 1].sum()) * dt             # rad
        assert 0.8 * lost < sd < 1.3 * lost + 0.025
        sds.append(sd)
    assert np.all(np.diff(np.array(sds)[np.argsort(amps[amps > 7.0])]) > 0)    # a larger peak loses more


def test_bad_input() -> None:
    with pytest.raises(InputError):
        clipped_samples(np.full((10, 3), np.nan))
    with pytest.raises(InputError):
        clip_variance(np.zeros((10, 3)), -1.0)
