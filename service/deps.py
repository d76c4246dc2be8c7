"""Shared per-request objects: settings, the store, the CPU worker limiter."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import anyio.to_thread
from anyio import CapacityLimiter
from starlette.requests import HTTPConnection

from service.images import decode_frame
from service.sessions import Session
from service.settings import Settings
from service.store import SessionStore

T = TypeVar("T")


def settings_of(conn: HTTPConnection) -> Settings:
    """The app's settings."""
    settings: Settings = conn.app.state.settings
    return settings


def store_of(conn: HTTPConnection) -> SessionStore:
    """The app's session store."""
    store: SessionStore = conn.app.state.store
    return store


async def track_encoded(
    conn: HTTPConnection, session: Session, data: bytes, media_type: str | None
) -> dict[str, Any]:
    """Decode an uploaded frame (within the limits) and track it, in a worker thread."""
    settings = settings_of(conn)

    def work() -> dict[str, Any]:
        frame = decode_frame(
            data,
            media_type,
            max_bytes=settings.max_frame_bytes,
            max_pixels=settings.max_frame_pixels,
        )
        return session.track(frame)

    return await compute(conn, work)


async def compute(conn: HTTPConnection, fn: Callable[[], T]) -> T:
    """Run CPU work in a worker thread, at most one per core at a time.

    Keeps the event loop (other sessions, pings, WebSockets) responsive.
    """
    limiter: CapacityLimiter = conn.app.state.cpu
    return await anyio.to_thread.run_sync(fn, limiter=limiter)
