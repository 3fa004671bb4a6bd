"""Reading a site description file (JSON): one place for the error a user sees when it cannot be read.

Both halves of a site parse the same document: the landmarks (:class:`pdr.phone.landmarks.Site`) and the floor plans
(:class:`pdr.site.plan.SitePlan`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pdr.errors import InputError


def read_site_document(path: str | Path) -> Any:
    """The parsed JSON of the site description at ``path``; :class:`InputError` naming the file if unreadable."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
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
