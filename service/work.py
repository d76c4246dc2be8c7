"""CPU work off the event loop: worker threads, at most one per core at a time.

Keeps the event loop (other sessions, pings, WebSockets) responsive.  The
routes pass the limiter they get from :data:`service.deps.CpuDep`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import anyio.to_thread
from anyio import CapacityLimiter

from service.images import decode_frame
from service.sessions import Session
from service.settings import Settings

__all__ = ["compute", "track_encoded"]

T = TypeVar("T")


async def compute(cpu: CapacityLimiter, fn: Callable[[], T]) -> T:
    """Run ``fn`` in a worker thread, within the CPU limiter.

    Parameters
    ----------
    cpu : CapacityLimiter
        The app's limiter (``CpuDep``).
    fn : callable
        The work; what it returns or raises comes back here.
    """
    return await anyio.to_thread.run_sync(fn, limiter=cpu)


async def track_encoded(
    cpu: CapacityLimiter,
    settings: Settings,
    session: Session,
    data: bytes,
    media_type: str | None,
) -> dict[str, Any]:
    """Decode an uploaded frame (within the limits) and track it, in a worker thread.

    Parameters
    ----------
    cpu : CapacityLimiter
        The app's limiter (``CpuDep``).
    settings : Settings
        Its frame byte and pixel limits apply.
    session : Session
        The leased session to track.
    data : bytes
        The encoded image.
    media_type : str or None
        Its declared type, if any.

    Returns
    -------
    dict
        The frame result fields (:meth:`Session.track`).
    """

    def work() -> dict[str, Any]:
        frame = decode_frame(
            data,
            media_type,
            max_bytes=settings.max_frame_bytes,
            max_pixels=settings.max_frame_pixels,
        )
        return session.track(frame)

    return await compute(cpu, work)
