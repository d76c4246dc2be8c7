"""Where sessions live: the interface, and the embedded in-memory store.

A store hands out a session under an exclusive *lease* (one mutation at a
time per session; other sessions proceed in parallel) and keeps what the
lease committed.  The in-memory store is the default; a shared store for
several replicas implements the same interface.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import Protocol

from service import metrics
from service.domain_errors import SessionNotFoundError, StreamReplacedError, TooManySessionsError
from service.sessions import Session


@dataclass(frozen=True, slots=True)
class Listed:
    """What a listing shows of a session, without loading its tracker."""

    id: str
    frame_index: int
    version: int
    touched: float
    ttl: float | None = None  # the session's own, when shorter than the store's


class SessionStore(Protocol):
    """The contract every session store fulfils."""

    async def add(self, session: Session) -> None:
        """Keep a new session; TooManySessionsError when the store is full."""

    def lease(
        self, session_id: str, owner: str | None
    ) -> contextlib.AbstractAsyncContextManager[Session]:
        """Exclusive access to a session.

        SessionNotFoundError if it is unknown, expired or not the owner's.
        """

    def stream(
        self, session_id: str, owner: str | None, commit_every: int = 1
    ) -> contextlib.AbstractAsyncContextManager[StreamLease]:
        """A session held for a WebSocket stream: one :meth:`StreamLease.turn` per frame.

        A shared store keeps the session in memory for the stream and writes it
        through every ``commit_every`` turns (and at the end), before the
        stream answers, so what a client was told is committed.

        One stream per session, across replicas: a new stream takes the
        session over, and the one it replaces gets StreamReplacedError at its
        next turn, before it changes anything (a client whose replica died
        reconnects at once).
        """

    async def delete(self, session_id: str, owner: str | None) -> None:
        """Remove a session; SessionNotFoundError as for :meth:`lease`."""

    async def owned(self, owner: str | None, after: str, limit: int) -> list[Listed]:
        """The owner's live sessions with ids after ``after``, in id order, at most ``limit``."""

    async def ping(self) -> bool:
        """Whether the store is reachable."""

    async def count(self) -> int:
        """How many sessions are held."""

    async def sweep(self) -> int:
        """Drop expired sessions; returns how many."""

    async def close(self) -> None:
        """Release resources."""


class StreamLease(Protocol):
    """A stream's hold on its session."""

    def turn(self) -> contextlib.AbstractAsyncContextManager[Session]:
        """Exclusive access for one message; committed (as configured) at exit."""


class _MemoryStreamLease:
    def __init__(self, store: MemoryStore, session_id: str, owner: str | None) -> None:
        self.store, self.session_id, self.owner = store, session_id, owner
        self.token = object()  # this stream's claim on the session

    @contextlib.asynccontextmanager
    async def turn(self) -> AsyncIterator[Session]:
        async with self.store.lease(self.session_id, self.owner) as session:  # the live object
            if self.store._streaming.get(self.session_id) is not self.token:
                raise StreamReplacedError
            yield session


class MemoryStore:
    """Sessions in this process's memory, capped in number, expiring when idle."""

    def __init__(self, *, max_sessions: int, ttl: float) -> None:
        self.max_sessions = max_sessions
        self.ttl = ttl
        self._sessions: dict[str, Session] = {}
        self._locks: dict[str, asyncio.Lock] = {}
        self._streaming: dict[str, object] = {}  # session -> the token of its newest stream

    def _expired(self, session: Session, now: float) -> bool:
        return now - session.touched > session.lifetime(self.ttl)

    def _drop(self, session_id: str) -> None:
        self._sessions.pop(session_id, None)
        self._locks.pop(session_id, None)
        metrics.SESSIONS.set(len(self._sessions))

    async def add(self, session: Session) -> None:
        if len(self._sessions) >= self.max_sessions:
            await self.sweep()
        if len(self._sessions) >= self.max_sessions:
            raise TooManySessionsError(self.max_sessions)
        self._sessions[session.id] = session
        self._locks[session.id] = asyncio.Lock()
        metrics.SESSIONS.set(len(self._sessions))

    def _find(self, session_id: str, owner: str | None) -> Session:
        session = self._sessions.get(session_id)
        if session is None or session.owner != owner:
            raise SessionNotFoundError
        if self._expired(session, time.time()):
            self._drop(session_id)
            raise SessionNotFoundError
        return session

    @contextlib.asynccontextmanager
    async def lease(self, session_id: str, owner: str | None) -> AsyncIterator[Session]:
        self._find(session_id, owner)
        lock = self._locks[session_id]
        async with lock:
            session = self._find(session_id, owner)  # may have gone while we waited
            session.touched = time.time()
            yield session
            session.touched = time.time()

    @contextlib.asynccontextmanager
    async def stream(
        self, session_id: str, owner: str | None, commit_every: int = 1
    ) -> AsyncIterator[StreamLease]:
        self._find(session_id, owner)
        held = _MemoryStreamLease(self, session_id, owner)
        self._streaming[session_id] = held.token  # a newer stream replaces an older one
        try:
            yield held
        finally:
            if self._streaming.get(session_id) is held.token:
                del self._streaming[session_id]

    async def delete(self, session_id: str, owner: str | None) -> None:
        self._find(session_id, owner)
        self._drop(session_id)

    async def owned(self, owner: str | None, after: str, limit: int) -> list[Listed]:
        now = time.time()
        mine = sorted(
            sid
            for sid, s in self._sessions.items()
            if s.owner == owner and sid > after and not self._expired(s, now)
        )
        sessions = (self._sessions[sid] for sid in mine[:limit])
        return [Listed(s.id, s.frame_index, s.version, s.touched, s.ttl) for s in sessions]

    async def ping(self) -> bool:
        return True

    async def count(self) -> int:
        return len(self._sessions)

    async def sweep(self) -> int:
        now = time.time()
        stale = [
            sid
            for sid, s in self._sessions.items()
            if self._expired(s, now) and not self._locks[sid].locked()
        ]
        for sid in stale:
            self._drop(sid)
        return len(stale)

    async def close(self) -> None:
        self._sessions.clear()
        self._locks.clear()
        metrics.SESSIONS.set(0)
