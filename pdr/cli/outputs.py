"""Files a command writes (``--out``, ``--geojson``, ``--plot``): their folder is made when it does not exist yet
(``pdr track LOG --out runs/today/walk.csv``), as ``pdr classify`` and ``pdr track`` do, and a command that works
for a while checks first that it can write them (:func:`check_writable`), so that a bad path is reported before
the work, not after it. A ``--plot`` name without an extension is given ``.png``, and the user is told; one with an
extension matplotlib cannot write is refused before the work (:func:`plot_path`). What the reader dropped or
repaired on the way in is said on stderr (:func:`print_warnings`).
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path

from pdr.errors import InputError


def in_made_folder(path: str | Path) -> Path:
    """``path``, its parent folder (and any missing ancestor) made."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return p


def check_writable(*paths: str | Path | None) -> None:
    """Make each output's folder and open the file for appending, as writing it later will (None: no such
    output). Raises the :class:`OSError` that writing would raise (it names the file: the command line prints it
    as ``error: PATH: reason``). A file that did not exist is removed again; an existing one is left as it was.
    """
    for path in paths:
        if path is None:
            continue
        p = in_made_folder(path)
        existed = p.exists()
        with p.open("ab"):
            pass
        if not existed:
            p.unlink()


def plot_path(path: str | Path | None) -> Path | None:
    """The file a ``--plot PATH`` is written to (None: no plot). A name without an extension gets ``.png`` (the
    image format matplotlib then writes, and the name it gives the file), said on stderr as a ``note:``.

    Raises
    ------
    InputError
        naming the path and the formats matplotlib writes, when its extension is none of them (matplotlib would
        refuse it only once the plot is drawn, after the work).
    """
    if path is None:
        return None
    p = Path(path)
    if not p.suffix:
        written = p.with_name(p.name + ".png")
        print(f"note: --plot {p} has no extension: the PNG is written to {written}", file=sys.stderr)
        return written
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    if p.suffix[1:].lower() not in formats:
        raise InputError(f"{p}: matplotlib cannot write '{p.suffix}' images; use one of "
                         f"{', '.join('.' + f for f in sorted(formats))}", field="--plot")
    return p


def print_warnings(warnings: Iterable[str], side: str | None = None) -> None:
    """One ``warning: ...`` line on stderr per problem the reader found and repaired (a cut-off last line, repeated
    samples dropped, ...; :attr:`pdr.recording.Recording.warnings`), ``warning (left): ...`` for a ``side``.
    """
    label = f"warning ({side})" if side else "warning"
    for w in warnings:
        print(f"{label}: {w}", file=sys.stderr)
