"""Multi-file logs: a folder or a zip of it, with members looked up by relative name (``.gz`` members transparently).

Apps export one file per sensor plus metadata (Sensor Logger, phyphox, the native folder). Users hand
them over as the folder, as a zip of the folder, or as a zip of the files themselves; :class:`Bundle`
hides the difference: a zip's members are found at its root or under its one top folder (the folder that
holds ``anchor``).
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path

from pdr.errors import InputError
from pdr.io.gz import decompressed_prefix, gunzip
from pdr.io.text import SNIFF_BYTES, decode_text, find_member, head, is_member_file, read_bytes, strip_gz


def starts_with(path: Path, magic: bytes) -> bool:
    """True for a readable file whose first bytes are ``magic`` (never raises)."""
    try:
        with path.open("rb") as f:
            return f.read(len(magic)) == magic
    except OSError:
        return False


def is_zip(path: Path) -> bool:
    """True for a readable file starting with the zip signature (never raises)."""
    return starts_with(path, b"PK\x03\x04")


class Bundle:
    """Members of a folder or zip archive.

    Parameters
    ----------
    path
        A folder, or a zip file.
    anchor
        A member name that marks the root inside a zip (e.g. ``meta.json``); the shallowest match wins. Without
        it (or when absent) the root is the zip's only top folder if all members share one, else the zip root.
    """

    def __init__(self, path: str | Path, anchor: str | None = None) -> None:
        self.path = Path(path)
        self._zip: dict[str, bytes] | None = None
        self._prefix = ""
        if self.path.is_file():
            try:
                with zipfile.ZipFile(self.path) as zf:
                    self._zip = {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}
            except (zipfile.BadZipFile, OSError, EOFError, ValueError, zlib.error) as exc:
                raise InputError(f"not a readable zip archive ({exc})", source=str(self.path)) from None
            self._prefix = self._root(anchor)
        elif not self.path.is_dir():
            raise InputError("no such file or folder", source=str(self.path))

    def _root(self, anchor: str | None) -> str:
        assert self._zip is not None
        names = [strip_gz(n) for n in self._zip if not n.startswith("__MACOSX/")]
        if anchor is not None:
            hits = sorted((n for n in names if n == anchor or n.endswith("/" + anchor)), key=len)
            if hits:
                return hits[0][: -len(anchor)]
        tops = {n.split("/", 1)[0] for n in names}
        if len(tops) == 1 and all("/" in n for n in names):
            return next(iter(tops)) + "/"
        return ""

    def name(self, member: str) -> str:
        """Display name of a member, for messages (``archive.zip:folder/file.csv`` or ``folder/file.csv``)."""
        return f"{self.path}:{self._prefix}{member}" if self._zip is not None else str(self.path / member)

    def members(self) -> list[str]:
        """Relative names of every file (``.gz`` suffix removed), sorted; in a folder, what is neither a file nor a
        sub-folder is left out with a notice (:func:`pdr.io.text.is_member_file`).
        """
        if self._zip is not None:
            out = {strip_gz(n[len(self._prefix):]) for n in self._zip
                   if n.startswith(self._prefix) and not n.startswith("__MACOSX/")}
        else:
            # A sub-folder is part of the layout; a named pipe, socket or link that loops is said (is_member_file).
            out = {strip_gz(str(f.relative_to(self.path)).replace("\\", "/")) for f in sorted(self.path.rglob("*"))
                   if not f.is_dir() and is_member_file(f)}
        return sorted(out)

    def _stored(self, member: str) -> tuple[str, bytes] | Path | None:
        """Where a member is stored, as ``member`` or ``member.gz``: a zip entry's (name, bytes), a file's path, or
        None if absent.
        """
        if self._zip is not None:
            for cand in (self._prefix + member, self._prefix + member + ".gz"):
                if cand in self._zip:
                    return cand, self._zip[cand]
            return None
        return find_member(self.path, member)

    def get(self, member: str) -> bytes | None:
        """Content of a member (gunzipped if stored as ``member.gz``), None if absent."""
        stored = self._stored(member)
        if stored is None or isinstance(stored, Path):
            return None if stored is None else read_bytes(stored)
        name, raw = stored
        return gunzip(raw, f"{self.path}:{name}") if name.endswith(".gz") else raw

    def head(self, member: str, n: int = SNIFF_BYTES) -> bytes:
        """First ``n`` bytes of a member (gunzipped), empty when absent or unreadable. For sniffing: a member damaged
        further on (a gzip cut short) still shows its header, and the reader then names the damage.
        """
        stored = self._stored(member)
        if stored is None or isinstance(stored, Path):
            return b"" if stored is None else head(stored, n)
        name, raw = stored
        return decompressed_prefix(raw, n) if name.endswith(".gz") else raw[:n]

    def need(self, member: str) -> bytes:
        """Content of a member; :class:`InputError` naming it when absent."""
        raw = self.get(member)
        if raw is None:
            raise InputError(f"missing member '{member}'", source=str(self.path))
        return raw

    def text(self, member: str) -> str:
        """Decoded text of a member (binary content is rejected naming the member)."""
        return decode_text(self.need(member), self.name(member))
