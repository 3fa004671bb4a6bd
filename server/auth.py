"""API tokens: creation (shown once), hashed storage, request authentication and brute-force limiting.

Tokens are 256-bit random strings; only their SHA-256 is stored, so a database leak reveals no usable
token (high-entropy tokens need no slow hash). Lookup is by hash and the match is confirmed with a
constant-time comparison. Tokens are never logged.

Clients that cannot set headers (e.g. the Sensor Logger app) may pass ``?token=`` on ingest endpoints
only. Query strings end up in proxy logs (the service's own access log drops them): prefer the
``Authorization: Bearer`` header, and give phones an ``ingest`` token.

Each token has a *scope*: ``ingest`` may only push data (Sensor Logger, native batches, file uploads, foot
steps, group uploads), ``read`` may only read (GET), ``full`` may do everything. A token may expire, and is
revoked on its own by its prefix (the first 10 characters, shown by ``pdr users tokens``).
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import threading
import time
from collections import defaultdict, deque
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

from flask import Request
from sqlalchemy import Connection, Row, or_, select, update

from server import db
from server.errors import APIError

TOKEN_PREFIX = "pdr_"
#: Characters of a token shown to identify it (``pdr_`` and 6 random characters).
PREFIX_CHARS = 10
#: Token scopes, and what each may do: ``ingest`` pushes data, ``read`` reads, ``full`` does both and manages.
SCOPES = ("ingest", "read", "full")
#: How often the last use of a token is written, s (not on every request).
LAST_USE_RESOLUTION_S = 60.0


@dataclass(frozen=True)
class User:
    """An authenticated user, with the scope of the token that authenticated the request."""

    id: int
    name: str
    scope: str = "full"

    def allows(self, need: str) -> bool:
        """Whether this request's token may do ``need`` (``ingest``, ``read`` or ``full``)."""
        return self.scope == "full" or self.scope == need


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


#: Longest lifetime of an expiring token (days): a century. Beyond it, leave the expiry out.
MAX_EXPIRES_DAYS = 36_525


def issue_token(conn: Connection, user_id: int, scope: str = "full", expires_days: float | None = None) -> str:
    """A new token of ``scope`` for the user, valid ``expires_days`` days (forever if None); shown once."""
    if scope not in SCOPES:
        raise ValueError(f"token scope must be one of {', '.join(SCOPES)}, got {scope!r}")
    if expires_days is not None and not 0 < expires_days <= MAX_EXPIRES_DAYS:
        raise ValueError(f"--expires must be a positive number of days, at most {MAX_EXPIRES_DAYS} (a century; "
                         f"leave it out for a token that does not expire), got {expires_days:g}")
    token = new_token()
    now = db.utcnow()
    conn.execute(db.api_tokens.insert().values(
        user_id=user_id, token_hash=hash_token(token), prefix=token[:PREFIX_CHARS], created_at=now, scope=scope,
        expires_at=None if expires_days is None else now + timedelta(days=expires_days)))
    return token


def user_id(conn: Connection, name: str) -> int:
    """Id of user ``name``; :class:`ValueError` if there is none."""
    row = conn.execute(select(db.users.c.id).where(db.users.c.name == name)).first()
    if row is None:
        raise ValueError(f"no user '{name}'")
    return int(row.id)


def revoke_user_tokens(conn: Connection, name: str, prefix: str | None = None) -> int:
    """Revoke the active tokens of user ``name`` (only those starting with ``prefix`` if given); returns how
    many. :class:`ValueError` if there is no such user, or no active token has that prefix.
    """
    uid = user_id(conn, name)
    q = db.api_tokens.update().where(db.api_tokens.c.user_id == uid, db.api_tokens.c.revoked_at.is_(None))
    if prefix is not None:
        prefix = prefix.strip()
        if len(prefix) < len(TOKEN_PREFIX) + 2:
            raise ValueError(f"token prefix {prefix!r} is too short: give the prefix 'pdr users tokens' shows")
        q = q.where(db.api_tokens.c.prefix == prefix[:PREFIX_CHARS])
    n = int(conn.execute(q.values(revoked_at=db.utcnow())).rowcount or 0)
    if prefix is not None and n == 0:
        raise ValueError(f"user '{name}' has no active token with prefix {prefix!r}")
    return n


def list_tokens(conn: Connection, name: str) -> list[Row[Any]]:
    """Tokens of user ``name`` (prefix, scope, created_at, expires_at, last_used_at, revoked_at), oldest first."""
    t = db.api_tokens
    return list(conn.execute(select(t.c.prefix, t.c.scope, t.c.created_at, t.c.expires_at, t.c.last_used_at,
                                    t.c.revoked_at).where(t.c.user_id == user_id(conn, name)).order_by(t.c.id)))


def delete_user(conn: Connection, name: str) -> None:
    """Delete user ``name`` with every token, session (raw batches, results), report and group."""
    uid = user_id(conn, name)
    conn.execute(db.users.delete().where(db.users.c.id == uid))  # ON DELETE CASCADE removes the rest


def lookup(conn: Connection, token: str) -> User | None:
    """The user owning an active, unexpired ``token`` (with the token's scope), or None; notes the token's use."""
    h = hash_token(token)
    now = db.utcnow()
    t = db.api_tokens
    row = conn.execute(
        select(db.users.c.id, db.users.c.name, t.c.id.label("token_id"), t.c.token_hash, t.c.scope,
               t.c.last_used_at)
        .join(t, t.c.user_id == db.users.c.id)
        .where(t.c.token_hash == h, t.c.revoked_at.is_(None), or_(t.c.expires_at.is_(None), t.c.expires_at > now))
    ).first()
    if row is None or not hmac.compare_digest(row.token_hash, h):
        return None
    last = _aware(row.last_used_at)
    if last is None or (now - last).total_seconds() > LAST_USE_RESOLUTION_S:
        conn.execute(update(t).where(t.c.id == row.token_id).values(last_used_at=now))
        conn.commit()
    return User(int(row.id), str(row.name), str(row.scope))


def _aware(t: datetime | None) -> datetime | None:
    """SQLite returns naive datetimes of what was stored as UTC."""
    if t is None:
        return None
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


class FailureLimiter:
    """Counts failed authentications per key (client address, token prefix) in a sliding minute; over the limit,
    further failures of that key answer 429. A valid token is never refused: it is checked before this limit.
    """

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
            now = time.monotonic()
            if len(self._events) > 10_000:  # random token prefixes must not grow the table without bound
                for k in [k for k, q in self._events.items() if not q or now - q[-1] > 60.0]:
                    del self._events[k]
            q = self._events[key]
            self._prune(q, now)
            q.append(now)


def token_from_request(request: Request, allow_query: bool) -> str | None:
    header = request.headers.get("Authorization", "")
    if header.lower().startswith("bearer "):
        return header[7:].strip() or None
    if allow_query:
        return request.args.get("token") or None
    return None
