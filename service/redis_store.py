"""Sessions in Redis, shared by every replica (``EFDM_REDIS_URL``).

Each session is one hash ``<prefix>:session:<id>`` with fields ``v`` (its
version), ``o`` (owner) and ``d`` (the whole state as JSON, tracker included),
expiring after the idle TTL; a sorted set ``<prefix>:sessions`` (score =
expiry time) counts them for the session cap.  Every change is an atomic
compare-and-set on the version (Lua): of two replicas changing one session
at once, one wins and the other gets :class:`VersionConflictError`, so no update
is lost.  When Redis is unreachable, calls raise :class:`StoreUnavailableError`
and recover by themselves.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
import weakref
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any, TypeVar

import anyio.to_thread
import redis.asyncio as redis
from redis.exceptions import RedisError, ResponseError

from service import metrics
from service.domain_errors import (
    ServiceError,
    SessionNotFoundError,
    StoreUnavailableError,
    TooManySessionsError,
    VersionConflictError,
)
from service.sessions import Session

T = TypeVar("T")

# KEYS: session, index.  ARGV: version, owner, data, ttl_ms, id, expiry, now, cap
_CREATE = """
redis.call('ZREMRANGEBYSCORE', KEYS[2], '-inf', ARGV[7])
if redis.call('ZCARD', KEYS[2]) >= tonumber(ARGV[8]) then return 0 end
redis.call('HSET', KEYS[1], 'v', ARGV[1], 'o', ARGV[2], 'd', ARGV[3])
redis.call('PEXPIRE', KEYS[1], ARGV[4])
redis.call('ZADD', KEYS[2], ARGV[6], ARGV[5])
return 1
"""
# KEYS: session, index.  ARGV: expected version, new version, data, ttl_ms, id, expiry
_COMMIT = """
local v = redis.call('HGET', KEYS[1], 'v')
if not v then return -1 end
if v ~= ARGV[1] then return 0 end
if ARGV[3] ~= '' then redis.call('HSET', KEYS[1], 'v', ARGV[2], 'd', ARGV[3]) end
redis.call('PEXPIRE', KEYS[1], ARGV[4])
redis.call('ZADD', KEYS[2], ARGV[6], ARGV[5])
return 1
"""


def _text(value: bytes | str | None) -> str:
    if value is None:
        return ""
    return value.decode() if isinstance(value, bytes) else value


class _RedisStreamLease:
    """A session kept in memory for a stream, written through every k turns."""

    def __init__(
        self, store: RedisStore, session: Session, owner: str | None, commit_every: int
    ) -> None:
        self.store = store
        self.session = session
        self.owner = owner
        self.commit_every = commit_every
        self.committed = session.version  # the version Redis holds
        self.pending = 0
        self.lock = store.lock_for(session.id)

    @contextlib.asynccontextmanager
    async def turn(self) -> AsyncIterator[Session]:
        async with self.lock:
            yield self.session
            self.session.touched = time.time()
            if self.session.version != self.committed:
                self.pending += 1
                if self.pending >= self.commit_every:
                    await self._commit()

    async def _commit(self) -> None:
        try:
            await self.store.commit(self.session, self.committed)
        except VersionConflictError:  # changed elsewhere: continue from what Redis holds
            self.session = await self.store._load(self.session.id, self.owner)
            self.committed, self.pending = self.session.version, 0
            raise
        self.committed, self.pending = self.session.version, 0

    async def flush(self) -> None:
        """Commit what is still pending (at the end of the stream)."""
        if self.pending:
            async with self.lock:
                await self._commit()


class RedisStore:
    """A :class:`service.store.SessionStore` on Redis (redis-py, asyncio)."""

    def __init__(
        self,
        url: str,
        *,
        max_sessions: int,
        ttl: float,
        prefix: str = "efdm",
        timeout: float = 0.5,
    ) -> None:
        self.max_sessions = max_sessions
        self.ttl = ttl
        self.prefix = prefix
        self.redis = redis.from_url(
            url,
            socket_timeout=timeout,
            socket_connect_timeout=timeout,
            health_check_interval=5,
            decode_responses=False,
        )
        self._index = f"{prefix}:sessions"
        self._create = self.redis.register_script(_CREATE)
        self._commit = self.redis.register_script(_COMMIT)
        # one local lock per session: requests of this replica take turns
        self._locks: weakref.WeakValueDictionary[str, asyncio.Lock] = weakref.WeakValueDictionary()

    def _key(self, session_id: str) -> str:
        return f"{self.prefix}:session:{session_id}"

    async def _call(self, fn: Callable[[], Awaitable[T]]) -> T:
        try:
            return await fn()
        except ResponseError:
            raise
        except (RedisError, OSError) as exc:
            metrics.ERRORS.labels(kind="store_unavailable").inc()
            raise StoreUnavailableError from exc

    def _ttl_ms(self) -> int:
        return max(1, int(self.ttl * 1000))

    async def add(self, session: Session) -> None:
        data = await anyio.to_thread.run_sync(lambda: json.dumps(session.to_record()))
        now = time.time()
        created = await self._call(
            lambda: self._create(
                keys=[self._key(session.id), self._index],
                args=[
                    session.version,
                    session.owner or "",
                    data,
                    self._ttl_ms(),
                    session.id,
                    now + self.ttl,
                    now,
                    self.max_sessions,
                ],
            )
        )
        if not int(created):
            raise TooManySessionsError(self.max_sessions)

    async def _load(self, session_id: str, owner: str | None) -> Session:
        raw = await self._call(lambda: self.redis.hmget(self._key(session_id), ["o", "d"]))
        stored_owner, data = raw
        if data is None or _text(stored_owner) != (owner or ""):
            raise SessionNotFoundError
        record: dict[str, Any] = json.loads(data)
        return await anyio.to_thread.run_sync(lambda: Session.from_record(record))

    def lock_for(self, session_id: str) -> asyncio.Lock:
        """This replica's lock for a session (requests here take turns)."""
        lock = self._locks.get(session_id)
        if lock is None:
            lock = self._locks[session_id] = asyncio.Lock()
        return lock

    @contextlib.asynccontextmanager
    async def lease(self, session_id: str, owner: str | None) -> AsyncIterator[Session]:
        async with self.lock_for(session_id):
            session = await self._load(session_id, owner)
            expected = session.version
            yield session
            session.touched = time.time()
            await self.commit(session, expected)

    @contextlib.asynccontextmanager
    async def stream(
        self, session_id: str, owner: str | None, commit_every: int = 1
    ) -> AsyncIterator[_RedisStreamLease]:
        held = _RedisStreamLease(self, await self._load(session_id, owner), owner, commit_every)
        try:
            yield held
        finally:
            with contextlib.suppress(ServiceError):
                await held.flush()

    async def commit(self, session: Session, expected: int) -> None:
        """Write a session back if nobody changed it since ``expected``.

        Raises
        ------
        VersionConflictError
            The session changed since ``expected`` (on another replica).
        SessionNotFoundError
            The session expired or was deleted meanwhile.
        StoreUnavailableError
            Redis cannot be reached.
        """
        changed = session.version != expected
        data = (
            await anyio.to_thread.run_sync(lambda: json.dumps(session.to_record()))
            if changed
            else ""
        )
        result = int(
            await self._call(
                lambda: self._commit(
                    keys=[self._key(session.id), self._index],
                    args=[
                        expected,
                        session.version,
                        data,
                        self._ttl_ms(),
                        session.id,
                        time.time() + self.ttl,
                    ],
                )
            )
        )
        if result == -1:
            raise SessionNotFoundError
        if result == 0:
            metrics.ERRORS.labels(kind="conflict").inc()
            raise VersionConflictError

    async def delete(self, session_id: str, owner: str | None) -> None:
        stored = await self._call(lambda: self.redis.hget(self._key(session_id), "o"))
        if stored is None or _text(stored) != (owner or ""):
            raise SessionNotFoundError
        async with self.redis.pipeline(transaction=True) as pipe:
            pipe.delete(self._key(session_id))
            pipe.zrem(self._index, session_id)
            await self._call(pipe.execute)

    async def ping(self) -> bool:
        try:
            return bool(await self.redis.ping())
        except (RedisError, OSError):
            return False

    async def count(self) -> int:
        now = time.time()
        async with self.redis.pipeline(transaction=True) as pipe:
            pipe.zremrangebyscore(self._index, "-inf", now)
            pipe.zcard(self._index)
            _, n = await self._call(pipe.execute)
        return int(n)

    async def sweep(self) -> int:
        return int(
            await self._call(lambda: self.redis.zremrangebyscore(self._index, "-inf", time.time()))
        )

    async def close(self) -> None:
        await self.redis.aclose()
