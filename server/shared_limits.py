"""Brute-force limiting shared by every web process: failed authentications counted in Redis.

With several web processes (``PDR_WORKER=redis``) the per-process :class:`server.auth.FailureLimiter`
would let an attacker multiply the allowance by the number of processes; this subclass keeps one
sliding-minute window per key (client address or token prefix) in a Redis sorted set, so the limit holds for the whole
deployment. If Redis is unreachable it degrades to the per-process count (still limited, never open).
The key holds the client address or the 10-character token prefix (as `pdr users tokens` lists it); whole
tokens are never stored or logged.
"""

from __future__ import annotations

import logging
import time
import uuid

import redis

from server.auth import FailureLimiter
from server.errors import APIError

log = logging.getLogger(__name__)

WINDOW_S = 60.0


class RedisFailureLimiter(FailureLimiter):
    """Failed authentications per client address in a sliding minute, across processes; over the limit -> 429."""

    def __init__(self, per_minute: int, connection: redis.Redis, namespace: str = "pdr") -> None:
        super().__init__(per_minute)
        self.redis = connection
        self.namespace = namespace

    def _key(self, client: str) -> str:
        return f"{self.namespace}:authfail:{client}"

    def check(self, key: str) -> None:
        try:
            now = time.time()
            pipe = self.redis.pipeline()
            pipe.zremrangebyscore(self._key(key), 0, now - WINDOW_S)
            pipe.zcard(self._key(key))
            count = int(pipe.execute()[1])
        except redis.exceptions.RedisError as exc:
            log.warning("shared failure limiter unavailable (%s); counting in this process", exc)
            super().check(key)
            return
        if count >= self.per_minute:
            raise APIError(429, "too many failed authentication attempts; retry in a minute")

    def fail(self, key: str) -> None:
        super().fail(key)  # the local count backs the shared one while Redis is down
        try:
            now = time.time()
            pipe = self.redis.pipeline()
            pipe.zadd(self._key(key), {f"{now:.6f}-{uuid.uuid4().hex[:8]}": now})
            pipe.expire(self._key(key), int(WINDOW_S) + 1)
            pipe.execute()
        except redis.exceptions.RedisError as exc:
            log.warning("shared failure limiter unavailable (%s)", exc)
