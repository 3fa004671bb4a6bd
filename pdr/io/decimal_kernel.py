"""Compiled (numba) parser of the numeric fields of text log lines: one pass over the bytes.

Each field must be a decimal (blanks around it allowed, as :func:`float` allows them; optional ``-``, digits,
at most one ``.``, at least one digit, optionally an exponent ``e``/``E`` with an optional sign and one to three
digits, as Java's ``Float.toString`` writes ``7.171631E-4``) of at most 18 mantissa digits. With the integer
mantissa ``m`` and the power of ten ``k`` (exponent minus decimals) within +-22, and ``m <= 2**53`` unless
``k = 0``, the value is ``m * 10**k`` or ``m / 10**-k`` of exact float64 operands, which one IEEE multiplication
or division rounds correctly (a whole number, ``k = 0``, is one correctly rounded int64 conversion): the value
:func:`float` gives (Clinger's fast path, W. D. Clinger, "How to read floating point numbers accurately", PLDI
1990). Anything else (a leading ``+``, a blank inside a number, other white space, more digits, a larger power,
a long mantissa with decimals, an empty field, a field too many or too few) stops the kernel at that line, and
the caller takes a slower exact path.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pdr.filters.compiled import kernel

_DOT, _MINUS, _PLUS, _ZERO, _NINE, _E, _E_UPPER, _SPACE = 46, 45, 43, 48, 57, 101, 69, 32
#: Digits of a field's mantissa the fast path takes (10**18 < 2**63: no int64 overflow).
MAX_DIGITS = 18
#: Largest mantissa that is exact in float64 (2**53); a larger one only as a whole number (no power of ten).
MAX_EXACT_INT = 2**53
#: Largest power of ten exact in float64 (5**22 < 2**53).
MAX_EXACT_POWER = 22


@kernel
def powers_of_ten() -> NDArray[np.float64]:  # pragma: no cover - compiled
    """``10.0**k`` for ``k = 0..MAX_EXACT_POWER``, each exact (the table :func:`parse_row` scales by)."""
    pow10 = np.empty(MAX_EXACT_POWER + 1)
    p10 = 1.0
    for k in range(MAX_EXACT_POWER + 1):
        pow10[k] = p10
        p10 *= 10.0
    return pow10


@kernel
def parse_lines(buf: NDArray[np.uint8], start: NDArray[np.int64], length: NDArray[np.int64], ncol: int,
                trailing_separator: bool, sep: int, out: NDArray[np.float64]) -> int:  # pragma: no cover - compiled
    """Parse line ``i`` (``buf[start[i]:start[i] + length[i]]``, ``ncol`` fields separated by ``sep``) into
    ``out[i]`` for every line (:func:`parse_row`); returns -1, or the index of the first line that is not of that
    plain form.
    """
    pow10 = powers_of_ten()
    flat = out.reshape(out.size)
    for i in range(start.size):
        if not parse_row(buf, start[i], start[i] + length[i], ncol, trailing_separator, sep, pow10, flat, i * ncol):
            return i
    return -1


@kernel
def parse_row(buf: NDArray[np.uint8], p: int, end: int, ncol: int, trailing_separator: bool, sep: int,
              pow10: NDArray[np.float64], out: NDArray[np.float64], at: int) -> bool:  # pragma: no cover - compiled
    """Parse the line ``buf[p:end]`` (``ncol`` fields separated by ``sep``) into ``out[at:at + ncol]`` (1-D); False
    when it is not of the plain form (module doc; those values may then be written in part). ``pow10``:
    :func:`powers_of_ten`.

    With ``trailing_separator`` one separator ending a line (an empty last field) is accepted and dropped.
    A field is read part by part: blanks, a sign, the integer digits, a point and the decimals, an exponent, blanks;
    a run of digits in a loop of its own, which tests each byte once.
    """
    ended = False
    for c in range(ncol):
        if ended:
            return False
        while p < end and buf[p] == _SPACE:
            p += 1          # blanks around a number: float() ignores them
        negative = False
        if p < end and buf[p] == _MINUS:
            negative = True
            p += 1
        m = 0
        digits = 0
        decimals = -1
        for part in range(2):               # the integer digits, then the decimals after a point
            first = p
            while p < end:
                d = int(buf[p]) - _ZERO
                if d < 0 or d > 9:
                    break
                m = m * 10 + d
                p += 1
            if part == 1:
                decimals = p - first
                digits += decimals
            else:
                digits = p - first
                if not (p < end and buf[p] == _DOT):
                    break
                p += 1
        exponent = 0
        if p < end and buf[p] != sep:
            ch = buf[p]
            if (ch == _E or ch == _E_UPPER) and digits > 0:
                p += 1
                exp_negative = False
                if p < end and (buf[p] == _MINUS or buf[p] == _PLUS):
                    exp_negative = buf[p] == _MINUS
                    p += 1
                exp_digits = 0
                while p < end and buf[p] != sep and buf[p] != _SPACE and exp_digits <= 3:
                    ch = buf[p]
                    if not _ZERO <= ch <= _NINE:
                        return False
                    exponent = exponent * 10 + (ch - _ZERO)
                    exp_digits += 1
                    p += 1
                if exp_digits == 0 or exp_digits > 3:
                    return False
                if exp_negative:
                    exponent = -exponent
            while p < end and buf[p] == _SPACE:
                p += 1
            if p < end and buf[p] != sep:
                return False            # a second point, a blank inside the number, another character
        if digits == 0 or digits > MAX_DIGITS:
            return False
        scale = exponent - max(decimals, 0)
        if scale < -MAX_EXACT_POWER or scale > MAX_EXACT_POWER or (scale != 0 and m > MAX_EXACT_INT):
            return False
        value = m * pow10[scale] if scale >= 0 else m / pow10[-scale]
        out[at + c] = -value if negative else value
        if p < end:
            p += 1          # the separator
        else:
            ended = True
    return ended or (trailing_separator and p == end)       # else more fields than ncol
