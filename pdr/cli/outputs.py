"""Files a command writes (``--out``, ``--geojson``, ``--plot``): their folder is made when it does not exist yet
(``pdr track LOG --out runs/today/walk.csv``), as ``pdr classify`` and ``pdr track`` do.
"""

from __future__ import annotations

from pathlib import Path


def in_made_folder(path: str | Path) -> Path:
    """``path``, its parent folder (and any missing ancestor) made."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return p
