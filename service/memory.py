"""Give the memory of ended sessions back to the operating system.

A session's tracker holds a few hundred kB of numpy arrays (the previous
frame, cue maps, colour models). With many sessions alive at once, from
several worker threads, glibc's allocator spreads them over its arenas and
keeps the freed pages: after 1,000 concurrent sessions were created, fed
and deleted, ``efdm serve`` stayed at 3.3 times its idle resident size
although nothing referenced them any more, and ``malloc_trim(0)`` brought
it back to 1.01 times (``python -m bench.serving.churn``). So when sessions
end (deleted, or expired by the sweep), the server trims the heap a few
seconds later, in a worker thread, at most once per :data:`TRIM_AFTER`
seconds however many sessions end. Elsewhere than on glibc (macOS, musl)
there is no ``malloc_trim`` and nothing is done.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import ctypes.util
import sys
from collections.abc import Callable

import anyio

__all__ = ["TRIM_AFTER", "MemoryReleaser", "malloc_trim"]

TRIM_AFTER = 5.0
"""Seconds between the end of a session and the trim: sessions ending in a
burst (a sweep, a client closing many) are trimmed for once, and a trim
(tens of milliseconds on a heap of hundreds of MB) never follows every call."""


def malloc_trim() -> Callable[[], object] | None:
    """glibc's ``malloc_trim(0)`` as a callable, or None where the C library has none."""
    if not sys.platform.startswith("linux"):
        return None
    name = ctypes.util.find_library("c") or "libc.so.6"
    try:
        trim = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return lambda: trim(0)


class MemoryReleaser:
    """Trims the heap a while after sessions end.

    Parameters
    ----------
    trim : callable or None
        What releases the memory (default :func:`malloc_trim`; None: nothing to do).
    after : float
        :data:`TRIM_AFTER`.
    """

    def __init__(
        self, trim: Callable[[], object] | None = None, *, after: float = TRIM_AFTER
    ) -> None:
        self._trim = trim if trim is not None else malloc_trim()
        self._after = after
        self._pending = asyncio.Event()
        self.trims = 0

    def freed(self) -> None:
        """Sessions ended: trim within :data:`TRIM_AFTER` seconds."""
        if self._trim is not None:
            self._pending.set()

    async def run(self) -> None:
        """Trim after sessions end, until cancelled."""
        if self._trim is None:
            return
        trim = self._trim
        while True:
            await self._pending.wait()
            await asyncio.sleep(self._after)
            self._pending.clear()
            with contextlib.suppress(Exception):
                await anyio.to_thread.run_sync(trim)
                self.trims += 1
