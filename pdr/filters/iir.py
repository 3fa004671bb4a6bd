"""Butterworth low-pass design and IIR filtering (direct form II transposed) without importing :mod:`scipy.signal`.

``scipy.signal`` costs about a second of imports; the phone pipeline needs only first- and second-order
Butterworth low-passes, their steady-state initial conditions and the filter itself. These give the values
``scipy.signal.butter``, ``lfilter_zi`` and ``lfilter`` give (the same operations in the same order: tested equal
to the last bit on the pipeline's filters):

* :func:`butter_lowpass`: the analogue prototype's poles ``-exp(i pi m / 2N)``, ``m = -N+1, -N+3, ..., N-1``,
  frequency pre-warping ``4 tan(pi Wn / 2)`` (sampling rate 2), the bilinear transform of the zeros, poles and
  gain, and the polynomials of the zeros and poles (S. Butterworth 1930; A. V. Oppenheim and R. W. Schafer,
  *Discrete-Time Signal Processing*, 3rd ed., sect. 7.2 and eq. 7.20 for the bilinear transform).
* :func:`lfilter`: ``y[n] = b0 x[n] + z0``, ``z_k = z_{k+1} + b_{k+1} x[n] - a_{k+1} y[n]`` (Oppenheim and
  Schafer, fig. 6.26), with the state carried between calls.
* :func:`lfilter_zi`: the state of a filter at rest under a unit step, ``(I - A^T) zi = b[1:] - a[1:] b0`` with
  ``A`` the companion matrix of ``a``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pdr.filters.compiled import kernel

Array = NDArray[np.float64]


def butter_lowpass(order: int, wn: float) -> tuple[Array, Array]:
    """Numerator ``b`` and denominator ``a`` ((order + 1,) each) of a digital Butterworth low-pass.

    ``wn`` is the -3 dB frequency as a fraction of the Nyquist frequency, ``0 < wn < 1`` (cut-off in Hz over half
    the sampling rate in Hz), as ``scipy.signal.butter(order, wn)``.
    """
    if int(order) != order or order < 1:
        raise ValueError(f"filter order must be a positive integer, got {order!r}")
    if not 0.0 < float(wn) < 1.0:
        raise ValueError(f"digital filter critical frequency must be 0 < wn < 1 (fraction of Nyquist), got {wn!r}")
    n = int(order)
    m = np.arange(-n + 1, n, 2, dtype=np.float64)
    poles = -np.exp(1j * np.pi * m / (2 * n))                     # analogue prototype, cut-off 1 rad/s
    fs = 2.0
    warped = 2 * fs * np.tan(np.pi * np.float64(wn) / fs)          # pre-warped analogue cut-off
    poles = float(warped) * poles
    gain = 1.0 * float(warped) ** n
    fs2 = 2.0 * fs
    zeros_z = -np.ones(n)                                          # the analogue zeros at infinity -> Nyquist
    poles_z = (fs2 + poles) / (fs2 - poles)                        # bilinear transform
    gain_z = gain * np.real(np.prod(fs2 - np.zeros(0)) / np.prod(fs2 - poles))
    b = np.multiply(np.atleast_1d(np.float64(gain_z)), _poly(zeros_z))
    a = _poly(poles_z)
    return np.asarray(b, dtype=np.float64), np.asarray(a, dtype=np.float64)


def _poly(roots: NDArray[np.generic]) -> NDArray[np.generic]:
    """Coefficients (highest power first) of the monic polynomial with these roots (real for conjugate pairs)."""
    out = np.ones((1,), dtype=roots.dtype)
    one = np.ones_like(roots[0])
    for r in roots:
        out = np.convolve(out, np.stack((one, -r)), mode="full")
    if np.iscomplexobj(out):
        c = np.asarray(roots, dtype=np.complex128)
        if np.all(np.sort(np.imag(c)) == np.sort(np.imag(np.conj(c)))):
            out = np.array(np.real(out), copy=True)
    return out


def _normalised(b: ArrayLike, a: ArrayLike) -> tuple[Array, Array]:
    bb = np.atleast_1d(np.asarray(b, dtype=np.float64))
    aa = np.atleast_1d(np.asarray(a, dtype=np.float64))
    if bb.ndim != 1 or aa.ndim != 1 or bb.size == 0 or aa.size == 0:
        raise ValueError("filter coefficients b and a must be non-empty 1-D sequences")
    while aa.size > 1 and aa[0] == 0.0:
        aa = aa[1:]
    if aa[0] == 0.0:
        raise ValueError("there must be at least one nonzero coefficient in a")
    if aa[0] != 1.0:
        bb, aa = bb / aa[0], aa / aa[0]
    n = max(aa.size, bb.size)
    return np.concatenate([bb, np.zeros(n - bb.size)]), np.concatenate([aa, np.zeros(n - aa.size)])


def lfilter_zi(b: ArrayLike, a: ArrayLike) -> Array:
    """(max(len(a), len(b)) - 1,) state of the filter in steady state under a unit step input (module doc)."""
    bb, aa = _normalised(b, a)
    n = bb.size
    companion = np.zeros((n - 1, n - 1))
    if n > 1:
        companion[0, :] = -aa[1:] / (1.0 * aa[0])
        companion[1:, :-1] = np.eye(n - 2)
    zi: Array = np.linalg.solve(np.eye(n - 1) - companion.T, bb[1:] - aa[1:] * bb[0])
    return zi


def lfilter(b: ArrayLike, a: ArrayLike, x: ArrayLike, zi: ArrayLike) -> tuple[Array, Array]:
    """Filter ``x`` ((N,) or (N, C), along axis 0) from the state ``zi``; returns the output and the final state.

    ``zi`` has shape (K,) for a 1-D ``x`` and (K, C) or (K, 1) (broadcast over the channels) for a 2-D one, with
    ``K = max(len(a), len(b)) - 1``.
    """
    bb, aa = _normalised(b, a)
    k = bb.size - 1
    xx = np.asarray(x, dtype=np.float64)
    if xx.ndim not in (1, 2):
        raise ValueError(f"x must be (N,) or (N, C), got shape {xx.shape}")
    x2 = xx.reshape(xx.shape[0], -1)
    z = np.asarray(zi, dtype=np.float64)
    ok = z.shape == (k,) if xx.ndim == 1 else (z.ndim == 2 and z.shape[0] == k and z.shape[1] in (1, x2.shape[1]))
    if not ok:
        raise ValueError(f"zi must have shape ({k},) for x of shape (N,) or ({k}, C) for (N, C); got {z.shape}")
    z2 = np.array(np.broadcast_to(z.reshape(k, -1), (k, x2.shape[1])))
    y = np.empty_like(x2)
    _df2t(bb, aa, np.ascontiguousarray(x2), y, z2)
    return y.reshape(xx.shape), (z2.reshape(k) if xx.ndim == 1 else z2)


@kernel
def _df2t(b: Array, a: Array, x: Array, y: Array, z: Array) -> None:  # pragma: no cover - compiled
    """Direct form II transposed, channel by channel: ``x``, ``y`` (N, C), state ``z`` (K, C) updated in place."""
    k = b.size - 1
    for c in range(x.shape[1]):
        for n in range(x.shape[0]):
            xn = x[n, c]
            if k > 0:
                yn = z[0, c] + b[0] * xn
                for j in range(k - 1):
                    z[j, c] = z[j + 1, c] + xn * b[j + 1] - yn * a[j + 1]
                z[k - 1, c] = xn * b[k] - yn * a[k]
            else:
                yn = xn * b[0]
            y[n, c] = yn
