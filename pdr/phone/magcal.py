"""Online magnetometer hard-iron offset from the gyroscope (no calibration motion, no reference field).

A field ``h`` fixed in the navigation frame reads ``m = C_bn h + b`` in the body frame, with ``b`` the
hard-iron offset (constant in the body frame). Since ``dC_bn/dt = -[w]x C_bn``,

    dm/dt = -w x (m - b)        i.e.        dm/dt + w x m = [w]x b.

Over one sample interval (trapezoid: ``w_bar``, ``m_bar`` the means of the two samples, ``ts`` the interval)
each pair of samples gives three linear rows

    y = (m_{k+1} - m_k) + ts w_bar x m_bar = ts [w_bar]x b.

The rows constrain the two components of ``b`` across ``w_bar``; a device that rotates about varied axes
(the thigh swing of a pocket walk, a hand-held phone turned) determines all three. The estimator is a
recursive least squares with exponential forgetting (time constant ``tau_s``): the normal equations of the
rows are summed per block of ``block_s`` and the estimate is refreshed at each block's end, so the offset
applied to a sample comes from earlier blocks only (causal, independent of the batch sizes). The residual sum
of squares gives the row noise, and with it the standard deviation of the estimate.

Gating (real phones): phone operating systems usually deliver calibrated fields, and a building's field is not
fixed in the navigation frame while the user walks through it. The estimate is applied only when it is
significant (``|b| >= apply_min_ut`` and ``|b| >= apply_sigmas`` standard deviations) and well conditioned
(every component's standard deviation at most ``max_std_ut``); otherwise the last applied offset is held (zero
until the gate first opens); a well-conditioned estimate that is not significant withdraws the offset (back to
zero). On a calibrated magnetometer the estimate stays near zero and nothing is applied. ``apply_min_ut`` (8 uT)
sits above what calibrated phones show: on the IPIN 2023 track-3 logs (hand-held, OS-calibrated) the estimates
end at 0.2-7.8 uT, spread by the building's field and by soft iron (a few uT on simulated consumer parts too), with
residual-based standard deviations of only 0.1-0.7 uT, so the standard deviation alone would open the gate there.
An uncalibrated hard-iron offset is typically tens of uT. Applying every significant, well-conditioned estimate
(``apply_min_ut`` 0) cost the IPIN walks: ``pdr eval ipin`` p75 causal 3.54 -> 3.74 m, smoothed 2.96 -> 3.19 m
(trial 23 repetition 01 1.07 -> 4.13 m causal): there the estimate is the building's field, not the phone's.

The OS's own calibration (:func:`mag_os_calibrated`): where the log also holds the raw field (Android's
TYPE_MAGNETIC_FIELD_UNCALIBRATED, iOS's uncalibrated field) and the calibrated one differs from it, the OS has
removed its hard-iron estimate already, and what this estimator would find is the building's field, not the
phone's: the pipeline does not run it there. On the motion-capture benchmark (Nexus 5, whose OS removes an offset
of about 420 uT) the estimate passed the gate in nine of the eighteen walks, with offsets of 8-31 uT (largest in the
disturbed fields): the other walker's disturbed front pocket, with 31 uT, has an attitude yaw error of 14.4 deg with
it and 11.3 without; on the tuning walker's disturbed swinging hand (10 uT) it goes 17.8 -> 20.0 deg, the building's
offset there happening to cancel part of a gyro bias's lag. Over all the walks the attitude's yaw error goes
5.8 -> 5.6 deg, and the walking direction 12.5 -> 12.5 deg causal and 11.3 -> 11.2 smoothed (``pdr eval heading``).
No other dataset's figures change: IPIN logs carry no raw field, on the MS traces the estimate never passes the
gate, and the Sensor Logger walks' tracks are byte-identical.

Rows at low rotation rate (``|w_bar| < min_rate_rps``) carry no information and are skipped; the gyro bias
estimated by the attitude filter is removed from the rate first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters import iir
from pdr.filters.compiled import kernel
from pdr.filters.numpy_reductions import segment_sum
from pdr.os_calibration import os_calibrated

FloatArray = NDArray[np.float64]

#: Smallest median difference (uT, norm) between the uncalibrated and the calibrated magnetometer streams that shows
#: the OS removing a hard-iron estimate (one LSB of a phone magnetometer is 0.06-0.6 uT; equal streams differ by 0).
MAG_OS_OFFSET_MIN_UT = 1e-3


def mag_os_calibrated(t_mag_s: FloatArray, mag: FloatArray, t_uncal_s: FloatArray, mag_uncal: FloatArray) -> bool:
    """Whether a log's ``mag`` stream (N, 3, uT, at times ``t_mag_s``) is the OS's hard-iron calibrated one: its
    ``mag_uncal`` stream (M, 3) differs from it by an offset (:func:`pdr.os_calibration.os_calibrated`, median norm
    above :data:`MAG_OS_OFFSET_MIN_UT`). The pipeline then leaves the field to the OS's calibration (module doc).
    """
    return os_calibrated(t_mag_s, mag, t_uncal_s, mag_uncal, MAG_OS_OFFSET_MIN_UT)


@dataclass(frozen=True)
class MagCalConfig:
    """Parameters of :class:`HardIronEstimator`.

    Attributes
    ----------
    enabled
        Estimate and apply the offset (False: the field passes unchanged).
    block_s
        Length of the blocks whose rows are summed before the estimate is refreshed (s).
    tau_s
        Forgetting time constant of the least squares (s).
    min_rate_rps
        Rows whose mean angular rate is below this (rad/s) are skipped.
    ridge_ut2
        Weight of a zero prior on the offset, as information in units of ``ts^2 rad^2/s^2`` per uT^2
        (keeps the normal equations solvable before any rotation).
    apply_min_ut, apply_sigmas, max_std_ut
        Gate: apply the estimate only when ``|b| >= apply_min_ut`` (uT), ``|b| >= apply_sigmas`` standard
        deviations, and every component's standard deviation is at most ``max_std_ut`` (uT).
    min_rows_s
        Gate: the (forgotten) rows must amount to at least this much rotating time (s) first; the earliest
        estimates rest on a few swings and their residuals understate the error.
    """

    enabled: bool = True
    block_s: float = 1.0
    tau_s: float = 600.0
    min_rate_rps: float = 0.3
    ridge_ut2: float = 1e-4
    apply_min_ut: float = 8.0
    apply_sigmas: float = 5.0
    max_std_ut: float = 2.5
    min_rows_s: float = 10.0

    def __post_init__(self) -> None:
        for name in ("block_s", "tau_s"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} must be positive", field=name, source="magcal config")


@dataclass
class HardIronState:
    """Serialisable state: normal equations (``info`` 3x3, ``vec`` 3, ``yy``, ``rows``), estimate, applied
    offset (uT), the last sample (field uT, rate rad/s) and the number of samples seen.
    """

    info: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))
    vec: FloatArray = field(default_factory=lambda: np.zeros(3))
    yy: float = 0.0
    rows: float = 0.0
    estimate: FloatArray = field(default_factory=lambda: np.zeros(3))
    std: FloatArray = field(default_factory=lambda: np.full(3, np.inf))
    applied: FloatArray = field(default_factory=lambda: np.zeros(3))
    last_m: FloatArray | None = None
    last_w: FloatArray | None = None
    n_seen: int = 0

    def state(self) -> dict[str, Any]:
        return {"info": self.info.tolist(), "vec": self.vec.tolist(), "yy": self.yy, "rows": self.rows,
                "estimate": self.estimate.tolist(), "std": [min(float(s), 1e300) for s in self.std],
                "applied": self.applied.tolist(),
                "last_m": None if self.last_m is None else self.last_m.tolist(),
                "last_w": None if self.last_w is None else self.last_w.tolist(), "n_seen": self.n_seen}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> HardIronState:
        try:
            return cls(np.array(d["info"], dtype=np.float64).reshape(3, 3), np.array(d["vec"], dtype=np.float64),
                       float(d["yy"]), float(d["rows"]), np.array(d["estimate"], dtype=np.float64),
                       np.array(d["std"], dtype=np.float64), np.array(d["applied"], dtype=np.float64),
                       None if d["last_m"] is None else np.array(d["last_m"], dtype=np.float64),
                       None if d["last_w"] is None else np.array(d["last_w"], dtype=np.float64), int(d["n_seen"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad magnetometer calibration state ({exc})", source="magcal state") from None


# The per-pair rows and their block sums are two compiled loops with the bits of the numpy expressions they replaced
# (a chain of whole-array calls, most of the calibration's time): the same products and differences in the same
# order, numpy's reduceat sums (pdr.filters.numpy_reductions); the two squared norms stay numpy's einsum, whose
# vectorised sum of three products a loop would not reproduce on every machine.
@kernel
def _pair_rows(m: FloatArray, w: FloatArray, m_prev: FloatArray, w_prev: FloatArray, ts: float, tw: FloatArray,
               y: FloatArray, w_norm: FloatArray) -> None:  # pragma: no cover - compiled
    """Per pair of samples ``(k-1, k)`` of the field ``m`` (uT) and the rate ``w`` (rad/s), body frame (``m_prev``,
    ``w_prev``: the sample before ``k = 0``; ``ts`` the interval, s): fills ``tw = ts w_bar`` (N, 3, rad), the row
    ``y = (m_k - m_{k-1}) + ts w_bar x m_bar`` (N, 3, uT), and ``|w_bar|`` (N, rad/s) as ``np.linalg.norm``.
    """
    for k in range(m.shape[0]):
        mp, wp = (m_prev, w_prev) if k == 0 else (m[k - 1], w[k - 1])
        wb0, wb1, wb2 = 0.5 * (w[k, 0] + wp[0]), 0.5 * (w[k, 1] + wp[1]), 0.5 * (w[k, 2] + wp[2])
        mb0, mb1, mb2 = 0.5 * (m[k, 0] + mp[0]), 0.5 * (m[k, 1] + mp[1]), 0.5 * (m[k, 2] + mp[2])
        y[k, 0] = (m[k, 0] - mp[0]) + ts * (wb1 * mb2 - wb2 * mb1)      # np.cross's products and differences
        y[k, 1] = (m[k, 1] - mp[1]) + ts * (wb2 * mb0 - wb0 * mb2)
        y[k, 2] = (m[k, 2] - mp[2]) + ts * (wb0 * mb1 - wb1 * mb0)
        tw[k, 0], tw[k, 1], tw[k, 2] = ts * wb0, ts * wb1, ts * wb2
        w_norm[k] = math.sqrt(((0.0 + wb0 * wb0) + wb1 * wb1) + wb2 * wb2)


@kernel
def _block_sums(tw: FloatArray, y: FloatArray, tw2: FloatArray, yy: FloatArray, w_norm: FloatArray, min_rate: float,
                first_pair: bool, starts: NDArray[np.int64]) -> FloatArray:  # pragma: no cover - compiled
    """The normal-equation terms of the rows ``y = [tw]x b`` kept (``|w_bar| >= min_rate``, finite ``y.y``; the
    first only with ``first_pair``), summed per block of pairs from ``starts`` as ``np.add.reduceat`` sums (J, 14):
    ``[tw]x^T [tw]x = |tw|^2 I - tw tw^T`` (9), ``[tw]x^T y = -tw x y`` (3), ``y.y`` and the row count.
    ``tw2``, ``yy``: ``|tw|^2`` and ``y.y`` (N,).
    """
    n = tw.shape[0]
    terms = np.empty((14, n))                  # term by term, each summed over its blocks below
    for k in range(n):
        keep = w_norm[k] >= min_rate and math.isfinite(yy[k]) and (k > 0 or first_pair)
        kf = 1.0 if keep else 0.0
        for i in range(3):
            for j in range(3):
                terms[3 * i + j, k] = (tw2[k] * (1.0 if i == j else 0.0) - tw[k, i] * tw[k, j]) * kf
        terms[9, k] = -(tw[k, 1] * y[k, 2] - tw[k, 2] * y[k, 1]) * kf
        terms[10, k] = -(tw[k, 2] * y[k, 0] - tw[k, 0] * y[k, 2]) * kf
        terms[11, k] = -(tw[k, 0] * y[k, 1] - tw[k, 1] * y[k, 0]) * kf
        terms[12, k] = yy[k] if keep else 0.0
        terms[13, k] = kf
    x = np.empty((starts.shape[0], 14))
    for c in range(14):
        t = terms[c]
        for b in range(starts.shape[0]):
            end = starts[b + 1] if b + 1 < starts.shape[0] else n
            x[b, c] = segment_sum(t, starts[b], end - starts[b])
    return x


class HardIronEstimator:
    """Online hard-iron offset of a magnetometer from the gyroscope (see the module docstring).

    Parameters
    ----------
    rate_hz
        Sample rate of the uniform batches (Hz).
    config
        Block length, forgetting and the gate.
    """

    def __init__(self, rate_hz: float, config: MagCalConfig | None = None) -> None:
        if not rate_hz > 0:
            raise InputError(f"rate must be positive, got {rate_hz}", field="rate_hz")
        self.rate_hz = float(rate_hz)
        self.config = config or MagCalConfig()
        self.hard_iron = HardIronState()

    def update(self, mag_b: FloatArray, gyro_b: FloatArray, gyro_bias: FloatArray | None = None) -> FloatArray:
        """Feed a batch and return the field with the applied offset removed.

        Parameters
        ----------
        mag_b
            (N, 3) magnetic field, body frame (uT).
        gyro_b
            (N, 3) angular rate, body frame (rad/s), on the same samples.
        gyro_bias
            (3,) gyro bias to remove (rad/s), e.g. the attitude filter's estimate.

        Returns
        -------
        (N, 3) corrected field (uT): each sample minus the offset applied at its block.
        """
        m = np.asarray(mag_b, dtype=np.float64)
        n = m.shape[0]
        if m.shape != (n, 3) or np.shape(gyro_b) != (n, 3):
            raise InputError("mag and gyro must both be (N, 3)", source="magcal")
        if n == 0 or not self.config.enabled:
            return m
        c, s = self.config, self.hard_iron
        ts = 1.0 / self.rate_hz
        m = np.ascontiguousarray(m)
        w = np.ascontiguousarray(np.asarray(gyro_b, dtype=np.float64)
                                 - (np.zeros(3) if gyro_bias is None else gyro_bias))
        # Pairs (k-1, k) for k = 0..n-1 (k = 0 pairs with the previous batch's last sample, the first with itself).
        tw, y, w_norm = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        _pair_rows(m, w, m[0] if s.last_m is None else s.last_m, w[0] if s.last_w is None else s.last_w, ts,
                   tw, y, w_norm)
        # Blocks at absolute sample indices; the offset of block j is the one applied after block j-1 ended.
        blk_len = max(1, round(c.block_s * self.rate_hz))
        idx = s.n_seen + np.arange(n)
        blk = idx // blk_len
        starts = np.flatnonzero(np.r_[True, np.diff(blk) != 0])
        x = _block_sums(tw, y, np.einsum("ni,ni->n", tw, tw), np.einsum("ni,ni->n", y, y), w_norm,
                        c.min_rate_rps, s.last_m is not None, starts)              # (J, 14) block sums
        ends = np.r_[starts[1:], n]
        # Only the batch's last block may continue into the next batch: its rows wait in the state and are
        # forgotten together with the block they belong to.
        nc = x.shape[0] - int(bool((idx[-1] + 1) % blk_len))
        prev = np.hstack([s.info.ravel(), s.vec, [s.yy, s.rows]])
        decay = math.exp(-c.block_s / c.tau_s)
        # S_j = decay (S_{j-1} + x_j) for the complete blocks (lfilter: y_j = d x_j + d y_{j-1}, y_{-1} = prev).
        sums = iir.lfilter([decay], [1.0, -decay], x[:nc], decay * prev[None, :])[0] if nc else x[:0]
        applied = self._refresh(sums, ts)                                          # (nc, 3) after each block
        last = sums[-1] if nc else prev
        if nc < x.shape[0]:
            last = last + x[-1]
        s.info, s.vec = last[:9].reshape(3, 3).copy(), last[9:12].copy()
        s.yy, s.rows = float(last[12]), float(last[13])
        # Block j uses the offset applied after block j - 1 (the first one the state's).
        used = np.vstack([s.applied[None, :], applied])[:x.shape[0]]
        if nc:
            s.applied = applied[-1].copy()
        s.last_m, s.last_w = m[-1].copy(), w[-1].copy()
        s.n_seen += n
        return m - np.repeat(used, ends - starts, axis=0)

    def _refresh(self, sums: FloatArray, ts: float) -> FloatArray:
        """Solve the normal equations after each complete block (``sums`` (J, 14): info, vec, yy, rows), estimate
        the row noise, open, hold or close the gate; returns the (J, 3) offsets applied after each block.
        """
        c, s = self.config, self.hard_iron
        out = np.empty((sums.shape[0], 3))
        if not sums.shape[0]:
            return out
        info, vec, yy, rows = sums[:, :9].reshape(-1, 3, 3), sums[:, 9:12], sums[:, 12], sums[:, 13]
        cov_unit = np.linalg.inv(info + c.ridge_ut2 * ts * ts * np.eye(3))
        b = np.einsum("nij,nj->ni", cov_unit, vec)
        rss = np.maximum(yy - 2.0 * np.einsum("ni,ni->n", b, vec) + np.einsum("ni,nij,nj->n", b, info, b), 0.0)
        # Three rows per pair, two of them informative (the component along w is not constrained).
        var_row = rss / np.maximum(2.0 * rows - 3.0, 1.0)
        std = np.sqrt(np.maximum(np.diagonal(cov_unit, axis1=1, axis2=2), 0.0) * var_row[:, None])
        solved = rows >= 10
        if solved.any():
            k = int(np.flatnonzero(solved)[-1])
            s.estimate, s.std = b[k].copy(), std[k].copy()
        # Not yet (or no longer) well conditioned: hold. Well conditioned: apply a significant estimate, and
        # withdraw the offset when the estimate is small.
        well = (rows >= c.min_rows_s / ts) & np.all(std <= c.max_std_ut, axis=1)
        norm = np.linalg.norm(b, axis=1)
        significant = (norm >= c.apply_min_ut) & (norm >= c.apply_sigmas * np.linalg.norm(std, axis=1))
        cand = np.where(significant[:, None], b, 0.0)
        # Forward fill the held value (the state's before the first decision).
        src = np.maximum.accumulate(np.where(well, np.arange(well.size), -1))
        out[:] = np.where((src >= 0)[:, None], cand[np.maximum(src, 0)], s.applied[None, :])
        return out

    def state(self) -> dict[str, Any]:
        return self.hard_iron.state()

    @classmethod
    def from_state(cls, d: dict[str, Any], rate_hz: float, config: MagCalConfig | None = None
                   ) -> HardIronEstimator:
        est = cls(rate_hz, config)
        est.hard_iron = HardIronState.from_state(d)
        return est
