"""numpy's float64 reductions as compiled kernels, bit for bit: its sums (:func:`pairwise_sum`, :func:`column_sums`,
and ``np.add.reduceat``'s :func:`segment_sum`) and whether every value is finite (:func:`all_finite`), for code that
replaces numpy calls on a few dozen samples (about a microsecond each, most of it numpy's dispatch) or a chain of
whole-array numpy calls, and whose results must not move by a rounding.

numpy's ``np.add.reduce`` (what ``.sum()`` and ``.mean()`` call) starts from the identity 0.0 and, over a 1-D array,
adds its elements by pairwise summation (``pairwise_sum`` of numpy's ``loops_utils.h``): blocks of fewer than 8
elements one after the other; blocks of up to 128 in eight interleaved partial sums, combined as
``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, the remainder added after; longer runs split in two halves,
the first a multiple of 8 elements, summed alone and added. Over the first axis of a 2-D array (``axis=0``) it adds the
rows one after the other. ``np.add.reduceat`` starts each segment from its first element and adds the pairwise sum of
the rest. :func:`pairwise_sum`, :func:`column_sums` and :func:`segment_sum` follow the same orders (the pairwise halving
without recursion: numba's cache cannot reload a recursive kernel). ``tests/pdr/filters/test_numpy_reductions.py``
checks them against numpy on random arrays of every length, contiguous and strided.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel

FloatArray = NDArray[np.float64]
#: numpy's ``PW_BLOCKSIZE``: the longest run summed without halving.
_BLOCK = 128


@kernel
def _block_sum(a: FloatArray, lo: int, n: int) -> float:  # pragma: no cover - compiled
    """The pairwise sum (numpy's) of ``a[lo:lo + n]`` for ``n <= 128`` (module doc)."""
    if n < 8:
        res = -0.0              # numpy starts a short block from -0.0 (so a sum of -0.0 stays -0.0)
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = lo + 8
    end = lo + n - n % 8
    while i < end:
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < lo + n:
        res += a[i]
        i += 1
    return res


@kernel
def _pairwise(a: FloatArray, lo: int, n: int) -> float:  # pragma: no cover - compiled
    """The ``pairwise_sum`` (numpy's) of ``a[lo:lo + n]``, any ``n`` (module doc), without the identity's 0.0."""
    if n <= _BLOCK:
        return _block_sum(a, lo, n)
    # numpy's recursion as a walk over its halves: the pending runs (start, length), and for each run whose first
    # half is summed, that half's sum.
    start = np.empty(64, np.int64)
    length = np.empty(64, np.int64)
    first = np.empty(64)
    first_done = np.zeros(64, np.bool_)
    top = 0
    start[0], length[0] = lo, n
    while True:
        m = length[top]
        if m > _BLOCK:
            half = m // 2
            half -= half % 8
            start[top + 1], length[top + 1], first_done[top + 1] = start[top], half, False
            top += 1
            continue
        s = _block_sum(a, start[top], m)
        top -= 1
        while top >= 0 and first_done[top]:
            s = first[top] + s
            top -= 1
        if top < 0:
            return s
        first[top], first_done[top] = s, True
        half = length[top] // 2
        half -= half % 8
        start[top + 1], length[top + 1], first_done[top + 1] = start[top] + half, length[top] - half, False
        top += 1


@kernel
def pairwise_sum(a: FloatArray) -> float:  # pragma: no cover - compiled
    """``np.add.reduce(a)`` of a 1-D float64 array ``a`` (contiguous or not), bit for bit (module doc)."""
    return 0.0 + _pairwise(a, 0, a.shape[0])


@kernel
def segment_sum(a: FloatArray, lo: int, n: int) -> float:  # pragma: no cover - compiled
    """The sum ``np.add.reduceat`` gives the segment ``a[lo:lo + n]`` (``n >= 1``) of a 1-D float64 array, bit for
    bit: its first element plus numpy's pairwise sum of the others (no identity).
    """
    return a[lo] + _pairwise(a, lo + 1, n - 1) if n > 1 else a[lo]


@kernel
def column_sums(x: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """``np.add.reduce(x, axis=0)`` of a 2-D float64 array ``x`` (N, k), bit for bit: the rows added in order."""
    n, k = x.shape
    out = np.zeros(k)
    for i in range(n):
        for j in range(k):
            out[j] += x[i, j]
    return out


@kernel
def all_finite(x: FloatArray) -> bool:  # pragma: no cover - compiled
    """``np.isfinite(x).all()`` of a float64 array of any shape and layout (True when empty)."""
    for v in x.flat:
        if not math.isfinite(v):
            return False
    return True
