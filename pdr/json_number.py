"""A number read from a JSON document as it was given: finite, within a float, and neither a string nor a boolean
(Python's ``float()`` would take ``"3"`` and ``true``; the document's author meant something else, or made a slip).
"""

from __future__ import annotations

import math
from typing import Any

from pdr.errors import InputError


def json_number(value: Any, source: str, field: str) -> float:
    """``value`` as a float, or an :class:`InputError` naming ``field`` of ``source`` when it is not a finite JSON
    number (a string, a boolean, another type, NaN or an infinity, or an integer beyond any float).
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{field} must be a number, not {type(value).__name__} {value!r:.40}", source=source,
                         field=field)
    try:
        number = float(value)
    except OverflowError:
        raise InputError(f"{field} is beyond any number", source=source, field=field) from None
    if not math.isfinite(number):
        raise InputError(f"{field} must be finite", source=source, field=field)
    return number
