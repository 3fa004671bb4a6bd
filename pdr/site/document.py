"""Reading a site description file (JSON): one place for the error a user sees when it cannot be read.

Both halves of a site parse the same document: the landmarks (:class:`pdr.phone.landmarks.Site`) and the floor plans
(:class:`pdr.site.plan.SitePlan`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pdr.errors import InputError
from pdr.json_number import json_number

#: Tallest storey (m): atria and halls included, a floor height beyond it is in other units or a typing slip.
MAX_FLOOR_HEIGHT_M = 100.0
#: Largest floor altitude (m, either sign, about the site's reference): Everest is 8.8 km above the sea.
MAX_ALTITUDE_M = 10_000.0


def read_site_document(path: str | Path) -> Any:
    """The parsed JSON of the site description at ``path``; :class:`InputError` naming the file if unreadable."""
    try:
        return json.loads(Path(path).read_text())
    # ValueError: invalid JSON, UTF-8 or an integer of more than 4300 digits; RecursionError: nested too deeply
    except (OSError, ValueError, RecursionError) as exc:
        raise InputError(f"cannot read site description ({exc})", source=str(path)) from None


def floors_list(document: dict[str, Any], source: str, required: bool = True) -> list[Any]:
    """The ``floors`` list of a site description: its floor plans (:class:`pdr.site.plan.SitePlan`: ``required``),
    or where they are optional (the floor altitudes :class:`pdr.phone.landmarks.Site` reads) ``[]`` when absent.
    A ``floors`` given is a non-empty list in both (an empty one describes no floor). One check, so both halves of a
    site refuse a bad ``floors`` with the same :class:`InputError` naming the field.
    """
    floors = document.get("floors")
    if floors is None and not required:
        return []
    if not isinstance(floors, list) or not floors:
        raise InputError("expected a non-empty 'floors' list of floor plans", source=source, field="floors")
    return floors


def floor_height_m(document: dict[str, Any], source: str) -> float:
    """The site's ``floor_height_m`` (m; 4 when absent): a JSON number in (0, :data:`MAX_FLOOR_HEIGHT_M`]. One check,
    so both halves of a site refuse the same floor heights with the same :class:`InputError`.
    """
    fh = json_number(document.get("floor_height_m", 4.0), source, "floor_height_m")
    if not 0 < fh <= MAX_FLOOR_HEIGHT_M:
        raise InputError(f"floor_height_m must be positive and at most {MAX_FLOOR_HEIGHT_M:g} m, not {fh:g}",
                         source=source, field="floor_height_m")
    return fh


def floor_altitude_m(value: Any, source: str) -> float:
    """A floor's ``altitude_m`` (m, about the site's reference): a JSON number within +/-:data:`MAX_ALTITUDE_M`."""
    alt = json_number(value, source, "altitude_m")
    if abs(alt) > MAX_ALTITUDE_M:
        raise InputError(f"altitude_m must be within +/-{MAX_ALTITUDE_M:g} m, not {alt:g}", source=source,
                         field="altitude_m")
    return alt
