"""Slow and stuck clients: timeouts and limits of the HTTP server itself (uvicorn).

A client that sends its request headers a byte at a time (slowloris) held
its connection for ever, and enough of them exhausted the file descriptors
until ``/healthz`` was unreachable.  Here:

- :func:`timed_protocol`: uvicorn's HTTP protocol with a deadline for each
  request's headers (from the connection's opening, or from the start of the
  next request on a kept-alive connection); past it the connection is
  closed;
- :func:`raise_open_file_limit`: the process's soft limit on open files is
  raised to its hard limit at start;
- the cap on concurrent connections is uvicorn's ``limit_concurrency``
  (beyond it a request gets ``503``), set by :func:`server_options`;
- a WebSocket stream whose client stopped reading is given up by the route
  after ``EFDM_WS_SEND_TIMEOUT_SECONDS`` (:mod:`service.routes.stream`), which then
  drops the connection through :data:`ABORT` (:func:`aborting_protocol`).

Request bodies that trickle in are cut off by :class:`service.limits.BodyLimit`.
"""

from __future__ import annotations

import asyncio
from typing import Any

from service.settings import Settings

__all__ = [
    "ABORT",
    "aborting_protocol",
    "raise_open_file_limit",
    "server_options",
    "timed_protocol",
]

ABORT = "efdm.abort"
"""Scope key, in a WebSocket's ASGI scope, of a callable that drops the connection at once
(set by :func:`aborting_protocol`; absent under another server or a test client)."""


def raise_open_file_limit() -> int:
    """Raise the soft limit on open files to the hard limit; returns the new soft limit."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard == resource.RLIM_INFINITY or hard > soft:
        target = hard if hard != resource.RLIM_INFINITY else max(soft, 1 << 20)
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
            soft = target
        except (ValueError, OSError):
            pass  # not allowed here: keep what there is
    return soft


def timed_protocol(header_seconds: float) -> type[asyncio.Protocol]:
    """uvicorn's httptools protocol, closing connections whose headers take too long."""
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

    class HeaderDeadlineProtocol(HttpToolsProtocol):
        _deadline: asyncio.TimerHandle | None = None

        def _arm(self) -> None:
            self._disarm()
            self._deadline = self.loop.call_later(header_seconds, self._too_slow)

        def _disarm(self) -> None:
            if self._deadline is not None:
                self._deadline.cancel()
                self._deadline = None

        def _too_slow(self) -> None:
            self._deadline = None
            if not self.transport.is_closing():
                self.transport.close()

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._arm()

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            super().connection_lost(exc)

        def on_message_begin(self) -> None:
            super().on_message_begin()
            if self._deadline is None:
                self._arm()

        def on_headers_complete(self) -> None:
            self._disarm()
            super().on_headers_complete()

    return HeaderDeadlineProtocol


def aborting_protocol() -> type[asyncio.Protocol]:
    """uvicorn's WebSocket protocol, giving each stream's scope an :data:`ABORT` callable.

    A client that stopped reading leaves results in the server's send buffer; ASGI's only
    close is a graceful one, which waits for that buffer to drain, and it never does: the
    socket stayed open, megabytes of buffers with it, until the operating system gave up
    on the peer.  The route that gives such a client up calls ``scope[ABORT]()`` instead,
    which aborts the transport: the socket is reset and its buffers freed at once.
    """
    from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

    class AbortingProtocol(WebSocketsSansIOProtocol):
        async def run_asgi(self) -> None:
            scope: dict[str, Any] = self.scope  # type: ignore[assignment]
            scope[ABORT] = self.transport.abort
            await super().run_asgi()

    return AbortingProtocol


def server_options(settings: Settings) -> dict[str, Any]:
    """The uvicorn ``Config`` options that protect the server from slow and many clients."""
    return {
        "http": timed_protocol(settings.header_timeout_seconds),
        "ws": aborting_protocol(),
        "limit_concurrency": settings.max_connections,
        "timeout_keep_alive": 5,
    }
