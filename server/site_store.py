"""Storage of uploaded sites and of the copy each session is processed with (tables of migration ``0008_sites``).

A site (a building: landmarks, floor height, floor plans; :mod:`server.sites`) belongs to one user. A session that
names a site gets its own copy (``session_sites``) when its options are set: its results can be rebuilt with the
site it was processed with even after the site is deleted, and the copy goes with the session.
Documents are stored as zlib-compressed canonical JSON with their SHA-256 (:func:`server.store.content_digest`).
"""

from __future__ import annotations

import json
import uuid
import zlib
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Column, DateTime, ForeignKey, Integer, LargeBinary, String, Table, Text, delete, insert, select
from sqlalchemy.engine import Engine, Row

from server import db
from server.errors import APIError
from server.store import content_digest

sites = Table(
    "sites", db.metadata,
    Column("id", String(36), primary_key=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False, index=True),
    Column("name", String(200), nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False),
    Column("digest", String(64), nullable=False),
    Column("size_bytes", Integer, nullable=False),
    Column("summary", Text, nullable=False),
    Column("document", LargeBinary, nullable=False),
)

session_sites = Table(
    "session_sites", db.metadata,
    Column("session_id", String(36), ForeignKey("sessions.id", ondelete="CASCADE"), primary_key=True),
    Column("site_id", String(36), nullable=False),
    Column("digest", String(64), nullable=False),
    Column("document", LargeBinary, nullable=False),
)


@dataclass(frozen=True)
class SiteDocument:
    """A site description as stored: its id, the SHA-256 of its canonical JSON and the JSON itself (bytes)."""

    site_id: str
    digest: str
    json_bytes: bytes

    def parsed(self) -> Any:
        return json.loads(self.json_bytes)


def _pack(document: Any) -> tuple[str, bytes]:
    text = json.dumps(document, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return content_digest(document), zlib.compress(text.encode("utf-8"), 6)


class SiteStore:
    """Repository of sites and session site copies over the service's database engine."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def create(self, user_id: int, name: str, document: Any, summary: dict[str, Any], size_bytes: int) -> str:
        sid = str(uuid.uuid4())
        digest, blob = _pack(document)
        with self.engine.begin() as conn:
            conn.execute(insert(sites).values(id=sid, user_id=user_id, name=name[:200], created_at=db.utcnow(),
                                              digest=digest, size_bytes=size_bytes, summary=json.dumps(summary),
                                              document=blob))
        return sid

    def row(self, site_id: str, user_id: int) -> Row[Any]:
        """The site; 404 when absent or owned by another user (existence is not revealed)."""
        with self.engine.connect() as conn:
            row = conn.execute(select(sites).where(sites.c.id == site_id)).first()
        if row is None or row.user_id != user_id:
            raise APIError(404, f"no site '{site_id[:64]}'")
        return row

    def list_for(self, user_id: int) -> list[Row[Any]]:
        cols = [c for c in sites.c if c.name != "document"]
        with self.engine.connect() as conn:
            return list(conn.execute(select(*cols).where(sites.c.user_id == user_id).order_by(sites.c.created_at)))

    def document(self, site_id: str, user_id: int) -> SiteDocument:
        row = self.row(site_id, user_id)
        return SiteDocument(row.id, row.digest, zlib.decompress(row.document))

    def delete(self, site_id: str, user_id: int) -> None:
        self.row(site_id, user_id)
        with self.engine.begin() as conn:
            conn.execute(delete(sites).where(sites.c.id == site_id))

    def set_session_site(self, session_id: str, site: SiteDocument | None) -> None:
        """Give the session its copy of ``site`` (None: the session names no site)."""
        with self.engine.begin() as conn:
            conn.execute(delete(session_sites).where(session_sites.c.session_id == session_id))
            if site is not None:
                conn.execute(insert(session_sites).values(session_id=session_id, site_id=site.site_id,
                                                          digest=site.digest,
                                                          document=zlib.compress(site.json_bytes, 6)))

    def session_site(self, session_id: str) -> SiteDocument | None:
        """The session's copy of its site, or None."""
        with self.engine.connect() as conn:
            row = conn.execute(select(session_sites).where(session_sites.c.session_id == session_id)).first()
        return None if row is None else SiteDocument(row.site_id, row.digest, zlib.decompress(row.document))
