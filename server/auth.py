"""API tokens: creation (shown once), hashed storage, request authentication and brute-force limiting.

Tokens are 256-bit random strings; only their SHA-256 is stored, so a database leak reveals no usable
token (high-entropy tokens need no slow hash). Lookup is by hash and the match is confirmed with a
constant-time comparison. Tokens are never logged.

Clients that cannot set headers (e.g. the Sensor Logger app) may pass ``?token=`` on ingest endpoints
only. Query strings end up in access logs and proxy logs: prefer the ``Authorization: Bearer`` header.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import threading
import time
from collections import defaultdict, deque
from dataclasses import dataclass

from flask import Request
from sqlalchemy import Connection, select

from server import db
from server.errors import APIError

TOKEN_PREFIX = "pdr_"


@dataclass(frozen=True)
class User:
    id: int
    name: str


def new_token() -> str:
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def hash_token(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def add_user(conn: Connection, name: str) -> str:
    """Create user ``name`` with a first token; returns the token (shown once). :class:`ValueError` if taken."""
    name = name.strip()
    if not name or len(name) > 100:
        raise ValueError("user name must have 1 to 100 characters")
    if conn.execute(select(db.users.c.id).where(db.users.c.name == name)).first():
        raise ValueError(f"user '{name}' already exists")
    key = conn.execute(db.users.insert().values(name=name, created_at=db.utcnow())).inserted_primary_key
    assert key is not None
    return issue_token(conn, int(key[0]))


def issue_token(conn: Connection, user_id: int) -> str:
    token = new_token()
    conn.execute(db.api_tokens.insert().values(user_id=user_id, token_hash=hash_token(token), prefix=token[:10],
                                               created_at=db.utcnow()))
    return token


def revoke_user_tokens(conn: Connection, name: str) -> int:
    """Revoke every active token of user ``name``; returns how many. :class:`ValueError` if no such user."""
    row = conn.execute(select(db.users.c.id).where(db.users.c.name == name)).first()
    if row is None:
        raise ValueError(f"no user '{name}'")
    res = conn.execute(db.api_tokens.update()
                       .where(db.api_tokens.c.user_id == row.id, db.api_tokens.c.revoked_at.is_(None))
                       .values(revoked_at=db.utcnow()))
    return int(res.rowcount or 0)


def lookup(conn: Connection, token: str) -> User | None:
    """The user owning an active ``token``, or None."""
    h = hash_token(token)
    row = conn.execute(
        select(db.users.c.id, db.users.c.name, db.api_tokens.c.token_hash)
        .join(db.api_tokens, db.api_tokens.c.user_id == db.users.c.id)
        .where(db.api_tokens.c.token_hash == h, db.api_tokens.c.revoked_at.is_(None))).first()
    if row is None or not hmac.compare_digest(row.token_hash, h):
        return None
    return User(int(row.id), str(row.name))


class FailureLimiter:
    """Counts failed authentications per client address in a sliding minute; over the limit -> 429."""

    def __init__(self, per_minute: int) -> None:
        self.per_minute = per_minute
        self._events: dict[str, deque[float]] = defaultdict(deque)
        self._lock = threading.Lock()

    def _prune(self, q: deque[float], now: float) -> None:
        while q and now - q[0] > 60.0:
            q.popleft()

    def check(self, key: str) -> None:
        with self._lock:
            q = self._events[key]
            self._prune(q, time.monotonic())
            if len(q) >= self.per_minute:
                raise APIError(429, "too many failed authentication attempts; retry in a minute")

    def fail(self, key: str) -> None:
        with self._lock:
            q = self._events[key]
            now = time.monotonic()
            self._prune(q, now)
            q.append(now)


def token_from_request(request: Request, allow_query: bool) -> str | None:
    header = request.headers.get("Authorization", "")
    if header.lower().startswith("bearer "):
        return header[7:].strip() or None
    if allow_query:
        return request.args.get("token") or None
    return None
