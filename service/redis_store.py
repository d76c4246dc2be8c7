"""Sessions in Redis, shared by every replica (``EFDM_REDIS_URL``).

Each session is one hash ``<prefix>:session:<id>`` with fields ``v`` (its
version), ``o`` (owner), ``f`` (frame index), ``t`` (last touched) and ``d``
(the whole state as JSON, tracker included), expiring after the idle TTL; a
sorted set ``<prefix>:sessions`` (score = expiry time) counts them for the
session cap, and one per owner, ``<prefix>:owned:<owner>`` (ids in
lexicographic order, expiring a TTL after the owner's last change), lists
them; ids of expired sessions leave it when a listing meets them.  An open
WebSocket stream claims ``<prefix>:stream:<id>`` (a random token, refreshed
while it is open, expiring :data:`STREAM_CLAIM_SECONDS` after its replica
stops); a newer stream overwrites the claim, and the older one's next commit,
which checks the claim in the same script, fails: it is closed as replaced,
on whichever replica it runs, having changed nothing.  Every change is an atomic
compare-and-set on the version (Lua): of two replicas changing one session
at once, one wins and the other gets :class:`VersionConflictError`, so no update
is lost.  When Redis is unreachable, calls raise :class:`StoreUnavailableError`
and recover by themselves; every write runs only within a deadline on Redis's
own clock (:data:`DEADLINE_SHARE`), so a write answered 503 cannot land once a
stalled Redis resumes, and a stream drops what was refused and goes on from
what Redis holds.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
import time
import weakref
from collections import OrderedDict
from collections.abc import AsyncIterator, Awaitable, Callable
from functools import partial
from typing import Any, TypeVar

import anyio.to_thread
import redis.asyncio as redis
from redis.exceptions import RedisError, ResponseError

from service import metrics
from service.domain_errors import (
    ServiceError,
    SessionNotFoundError,
    StoreUnavailableError,
    StreamReplacedError,
    TooManySessionsError,
    VersionConflictError,
)
from service.sessions import Session
from service.store import Listed

T = TypeVar("T")

EXACT_CACHE = 64
"""Sessions each replica keeps exactly in memory after committing them (a few hundred kB
each): Redis holds a compact, lossy tracker state (:meth:`engine.Tracker.to_state`
``compact=True``, tens of kB a frame), so a replica that wrote the version Redis holds
goes on from its exact copy and only a session moving between replicas resumes from
the compact one."""

DEADLINE_SHARE = 0.8
"""A write must run within this share of the socket timeout after it was sent, by
Redis's own clock, or it refuses itself: a write the caller gave up on (and
answered 503) cannot land later, when a stalled Redis or network resumes."""
STREAM_CLAIM_SECONDS = 30.0
"""How long a stream's claim on its session outlives its replica (the key's
expiry, refreshed three times as often while the stream is open)."""
# KEYS: claim.  ARGV: token, ttl_ms.  Refresh (or drop, ttl_ms 0) only one's own claim.
_RENEW = """
if redis.call('GET', KEYS[1]) ~= ARGV[1] then return 0 end
if tonumber(ARGV[2]) == 0 then return redis.call('DEL', KEYS[1]) end
return redis.call('PEXPIRE', KEYS[1], ARGV[2])
"""

# Redis's clock in ms, for the deadline check of the scripts that write.
_NOW_MS = "local t = redis.call('TIME'); local now_ms = t[1] * 1000 + t[2] / 1000\n"
# KEYS: session, index, owned.
# ARGV: version, owner, data, ttl_ms, id, expiry, now, cap, frame index, touched, own ttl,
#       deadline (Redis ms)
_CREATE = (
    _NOW_MS
    + """
if now_ms > tonumber(ARGV[12]) then return -3 end
redis.call('ZREMRANGEBYSCORE', KEYS[2], '-inf', ARGV[7])
if redis.call('ZCARD', KEYS[2]) >= tonumber(ARGV[8]) then return 0 end
redis.call('HSET', KEYS[1], 'v', ARGV[1], 'o', ARGV[2], 'd', ARGV[3], 'f', ARGV[9], 't', ARGV[10],
           'l', ARGV[11])
redis.call('PEXPIRE', KEYS[1], ARGV[4])
redis.call('ZADD', KEYS[2], ARGV[6], ARGV[5])
redis.call('ZADD', KEYS[3], 0, ARGV[5])
redis.call('PEXPIRE', KEYS[3], ARGV[4])
return 1
"""
)
# KEYS: session, index, owned, stream claim (or any key when claim is '').
# ARGV: expected version, new version, data, ttl_ms, id, expiry, frame index, touched, claim,
#       deadline (Redis ms)
_COMMIT = (
    _NOW_MS
    + """
if now_ms > tonumber(ARGV[10]) then return -3 end
if ARGV[9] ~= '' and redis.call('GET', KEYS[4]) ~= ARGV[9] then return -2 end
local v = redis.call('HGET', KEYS[1], 'v')
if not v then return -1 end
if v ~= ARGV[1] then return 0 end
if ARGV[3] ~= '' then redis.call('HSET', KEYS[1], 'v', ARGV[2], 'd', ARGV[3], 'f', ARGV[7]) end
redis.call('HSET', KEYS[1], 't', ARGV[8])
redis.call('PEXPIRE', KEYS[1], ARGV[4])
redis.call('ZADD', KEYS[2], ARGV[6], ARGV[5])
redis.call('ZADD', KEYS[3], 0, ARGV[5])
redis.call('PEXPIRE', KEYS[3], ARGV[4])
return 1
"""
)


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
        self.claim = ("", "")  # (key, token) of this stream's claim, once made
        self.stale = False  # a write failed: the session in memory is ahead of what was stored

    async def current(self) -> Session:
        """The session as the stream goes on from it (under :attr:`lock`): after a refused
        write, what Redis holds; the refused change is dropped."""
        if self.stale:
            self.session = await self.store._load(self.session.id, self.owner)
            self.committed, self.pending, self.stale = self.session.version, 0, False
        return self.session

    @contextlib.asynccontextmanager
    async def turn(self) -> AsyncIterator[Session]:
        async with self.lock:
            await self.current()
            yield self.session
            self.session.touched = time.time()
            if self.session.version != self.committed:
                self.pending += 1
                if self.pending >= self.commit_every:
                    await self._commit()

    async def _commit(self) -> None:
        try:
            await self.store.commit(self.session, self.committed, claim=self.claim)
        except VersionConflictError:  # changed elsewhere: continue from what Redis holds
            self.session = await self.store._load(self.session.id, self.owner)
            self.committed, self.pending = self.session.version, 0
            raise
        except StoreUnavailableError:  # answered as an error: it must not be applied later
            self.stale = True
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
        exact_cache: int = EXACT_CACHE,
    ) -> None:
        self.max_sessions = max_sessions
        self.exact_cache = exact_cache
        # the sessions this replica wrote last, exact, by id: (version, session)
        self._exact: OrderedDict[str, tuple[int, Session]] = OrderedDict()
        self.ttl = ttl
        self.prefix = prefix
        self.timeout = timeout
        self._offset: float | None = None  # Redis's clock minus ours, s (measured when loading)
        self.redis = redis.from_url(
            url,
            socket_timeout=timeout,
            socket_connect_timeout=timeout,
            health_check_interval=5,
            decode_responses=False,
        )
        self._index = f"{prefix}:sessions"
        self._create = self.redis.register_script(_CREATE)
        self._renew = self.redis.register_script(_RENEW)
        self._commit = self.redis.register_script(_COMMIT)
        # one local lock per session: requests of this replica take turns
        self._locks: weakref.WeakValueDictionary[str, asyncio.Lock] = weakref.WeakValueDictionary()
        # the sessions a stream of this replica holds in memory: requests here use them
        self._streams: dict[str, _RedisStreamLease] = {}

    def _key(self, session_id: str) -> str:
        return f"{self.prefix}:session:{session_id}"

    def _owned(self, owner: str | None) -> str:
        return f"{self.prefix}:owned:{owner or '-'}"

    async def _call(self, fn: Callable[[], Awaitable[T]]) -> T:
        try:
            return await fn()
        except ResponseError:
            raise
        except (RedisError, OSError) as exc:
            metrics.ERRORS.labels(kind="store_unavailable").inc()
            raise StoreUnavailableError from exc

    def _ttl_ms(self, session: Session) -> int:
        return max(1, int(session.lifetime(self.ttl) * 1000))

    async def add(self, session: Session) -> None:
        data = await anyio.to_thread.run_sync(lambda: json.dumps(session.to_record(compact=True)))
        deadline = await self._deadline_ms()
        now = time.time()
        created = await self._call(
            lambda: self._create(
                keys=[self._key(session.id), self._index, self._owned(session.owner)],
                args=[
                    session.version,
                    session.owner or "",
                    data,
                    self._ttl_ms(session),
                    session.id,
                    now + session.lifetime(self.ttl),
                    now,
                    self.max_sessions,
                    session.frame_index,
                    repr(session.touched),
                    "" if session.ttl is None else repr(session.ttl),
                    deadline,
                ],
            )
        )
        if int(created) == -3:  # ran too late: the caller was told 503
            raise StoreUnavailableError
        if not int(created):
            raise TooManySessionsError(self.max_sessions)
        self._keep_exact(session)

    async def _deadline_ms(self) -> float:
        """The latest time, on Redis's clock, a write sent now may run (:data:`DEADLINE_SHARE`)."""
        if self._offset is None:
            before = time.time()
            secs, micros = await self._call(self.redis.time)
            self._offset = secs + micros / 1e6 - (before + time.time()) / 2
        return (time.time() + self._offset + DEADLINE_SHARE * self.timeout) * 1000

    async def _load(self, session_id: str, owner: str | None) -> Session:
        """The session as Redis holds it: this replica's exact copy when it wrote the
        version stored (taken out of the cache: the caller owns it), else the record."""
        before = time.time()
        async with self.redis.pipeline(transaction=False) as pipe:
            pipe.hmget(self._key(session_id), ["o", "v"])
            pipe.time()
            raw, (secs, micros) = await self._call(pipe.execute)
        self._offset = secs + micros / 1e6 - (before + time.time()) / 2
        stored_owner, version = raw
        if version is None or _text(stored_owner) != (owner or ""):
            raise SessionNotFoundError
        cached = self._exact.pop(session_id, None)
        if cached is not None and str(cached[0]) == _text(version):
            return cached[1]
        data = await self._call(partial(self.redis.hget, self._key(session_id), "d"))
        if data is None:
            raise SessionNotFoundError
        record: dict[str, Any] = json.loads(data)
        return await anyio.to_thread.run_sync(lambda: Session.from_record(record))

    def _keep_exact(self, session: Session) -> None:
        """Remember a session this replica just committed, exactly (least recent out)."""
        if self.exact_cache <= 0:
            return
        self._exact[session.id] = (session.version, session)
        self._exact.move_to_end(session.id)
        while len(self._exact) > self.exact_cache:
            self._exact.popitem(last=False)

    def lock_for(self, session_id: str) -> asyncio.Lock:
        """This replica's lock for a session (requests here take turns)."""
        lock = self._locks.get(session_id)
        if lock is None:
            lock = self._locks[session_id] = asyncio.Lock()
        return lock

    @contextlib.asynccontextmanager
    async def lease(self, session_id: str, owner: str | None) -> AsyncIterator[Session]:
        """The session, exclusively on this replica, committed at exit.

        While a stream of this replica holds the session, a request uses the stream's copy
        (as the in-memory store shares its one object): the stream sees the change at its
        next frame instead of finding Redis moved on under it (409).  A request refused
        (the block raises) changed nothing, and the exact copy stays this replica's.
        """
        async with self.lock_for(session_id):
            held = self._streams.get(session_id)
            if held is not None and held.owner != owner:
                held = None  # another owner's id: not found, as _load says
            session = (
                await held.current() if held is not None else await self._load(session_id, owner)
            )
            expected = session.version if held is None else held.committed
            try:
                yield session
            except BaseException:
                if held is None and session.version == expected:
                    self._keep_exact(session)  # refused: nothing changed
                raise
            session.touched = time.time()
            try:
                await self.commit(session, expected)
            except BaseException:
                if held is not None:  # the stream's copy is ahead of Redis: it reloads
                    held.stale = True
                raise
            if held is None:
                self._keep_exact(session)
            else:  # the stream's pending frames went with it
                held.committed, held.pending = session.version, 0

    @contextlib.asynccontextmanager
    async def stream(
        self, session_id: str, owner: str | None, commit_every: int = 1
    ) -> AsyncIterator[_RedisStreamLease]:
        session = await self._load(session_id, owner)
        claim, token = f"{self.prefix}:stream:{session_id}", secrets.token_hex(16)
        ttl_ms = int(STREAM_CLAIM_SECONDS * 1000)
        await self._call(partial(self.redis.set, claim, token, px=ttl_ms))  # replaces any older
        keeper = asyncio.create_task(self._keep_claim(claim, token, ttl_ms))
        held = _RedisStreamLease(self, session, owner, commit_every)
        held.claim = (claim, token)
        self._streams[session_id] = held  # a newer stream here replaces it
        try:
            yield held
        finally:
            keeper.cancel()
            with contextlib.suppress(ServiceError):
                await held.flush()
            if self._streams.get(session_id) is held:
                del self._streams[session_id]
                current = held.session
                if not held.stale and not held.pending and current.version == held.committed:
                    self._keep_exact(current)  # what Redis holds, exactly: go on from it
            with contextlib.suppress(ServiceError, asyncio.CancelledError):
                await self._call(partial(self._renew, keys=[claim], args=[token, 0]))

    async def _keep_claim(self, claim: str, token: str, ttl_ms: int) -> None:
        """Refresh a stream's claim a few times per its lifetime while the stream is open."""
        while True:
            await asyncio.sleep(ttl_ms / 3000)
            with contextlib.suppress(ServiceError):
                await self._call(partial(self._renew, keys=[claim], args=[token, ttl_ms]))

    async def commit(
        self, session: Session, expected: int, *, claim: tuple[str, str] = ("", "")
    ) -> None:
        """Write a session back if nobody changed it since ``expected``.

        With ``claim`` (a stream's claim key and token), only while that
        stream still holds the session.

        Raises
        ------
        VersionConflictError
            The session changed since ``expected`` (on another replica).
        SessionNotFoundError
            The session expired or was deleted meanwhile.
        StreamReplacedError
            A newer stream took the session over.
        StoreUnavailableError
            Redis cannot be reached.
        """
        changed = session.version != expected
        data = (
            await anyio.to_thread.run_sync(lambda: json.dumps(session.to_record(compact=True)))
            if changed
            else ""
        )
        deadline = await self._deadline_ms()  # counted from the send, not the serialising
        result = int(
            await self._call(
                lambda: self._commit(
                    keys=[
                        self._key(session.id),
                        self._index,
                        self._owned(session.owner),
                        claim[0] or self._index,
                    ],
                    args=[
                        expected,
                        session.version,
                        data,
                        self._ttl_ms(session),
                        session.id,
                        time.time() + session.lifetime(self.ttl),
                        session.frame_index,
                        repr(session.touched),
                        claim[1],
                        deadline,
                    ],
                )
            )
        )
        if result == -3:  # ran too late: the caller was told 503
            raise StoreUnavailableError
        if result == -2:
            raise StreamReplacedError
        if result == -1:
            raise SessionNotFoundError
        if result == 0:
            metrics.ERRORS.labels(kind="conflict").inc()
            raise VersionConflictError

    async def delete(self, session_id: str, owner: str | None) -> None:
        stored = await self._call(lambda: self.redis.hget(self._key(session_id), "o"))
        if stored is None or _text(stored) != (owner or ""):
            raise SessionNotFoundError
        self._exact.pop(session_id, None)
        async with self.redis.pipeline(transaction=True) as pipe:
            pipe.delete(self._key(session_id))
            pipe.zrem(self._index, session_id)
            pipe.zrem(self._owned(owner), session_id)
            await self._call(pipe.execute)

    async def owned(self, owner: str | None, after: str, limit: int) -> list[Listed]:
        key = self._owned(owner)
        found: list[Listed] = []
        start = f"({after}" if after else "-"
        while len(found) < limit:
            ids = await self._call(partial(self._ids_from, key, start, limit - len(found)))
            if not ids:
                break
            async with self.redis.pipeline(transaction=False) as pipe:
                for sid in ids:
                    pipe.hmget(self._key(sid), ["v", "f", "t", "l"])
                rows = await self._call(pipe.execute)
            gone = [sid for sid, (v, *_) in zip(ids, rows, strict=True) if v is None]
            found += [
                Listed(sid, int(f or -1), int(v), float(t or 0.0), float(ttl) if ttl else None)
                for sid, (v, f, t, ttl) in zip(ids, rows, strict=True)
                if v is not None
            ]
            if gone:  # expired since: tidy the owner's list as we go
                await self._call(partial(self.redis.zrem, key, *gone))
            start = f"({ids[-1]}"
        return found

    async def _ids_from(self, key: str, start: str, count: int) -> list[str]:
        """Up to ``count`` ids of the sorted set ``key`` from ``start`` (a lex bound) on."""
        return [_text(i) for i in await self.redis.zrangebylex(key, start, "+", start=0, num=count)]

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
