"""Graceful shutdown: open WebSocket streams end with ``1001 going away``.

On SIGTERM (or Ctrl-C) uvicorn stops listening, asks every open connection
to shut down and waits for the requests in flight, then runs the lifespan
exit.  A WebSocket, though, is closed by uvicorn's connection shutdown at
once, with ``1012``, whatever frame it is tracking.  Here instead:

- :class:`StreamRegistry` (``app.state.streams``) knows every open stream;
  a stream's worker holds :meth:`Stream.in_flight` while it tracks a frame
  (or answers a control message) and sends the result;
- :meth:`StreamRegistry.close_all` waits, per stream, for that turn to end
  (the session is committed before the result goes out), lets no new turn
  start, closes the socket with ``1001`` ("going away": clients reconnect,
  through the load balancer, to another replica) and waits until the stream's
  handler has finished, its final write-through included;
- :class:`GracefulServer` (uvicorn's server, as ``efdm serve`` runs it) stops
  listening and calls ``close_all`` *before* uvicorn's own connection
  shutdown; the lifespan exit calls it again for servers without that hook.

Every wait is bounded by a deadline; a stream still busy at the deadline is
closed anyway.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import socket
from collections.abc import AsyncIterator, Callable

import uvicorn
from starlette.websockets import WebSocket, WebSocketDisconnect

__all__ = ["GOING_AWAY", "REASON", "GracefulServer", "Stream", "StreamRegistry"]

GOING_AWAY = 1001
REASON = "server shutting down"
log = logging.getLogger("efdm.service")


class Stream:
    """One open WebSocket stream, as the registry knows it.

    Parameters
    ----------
    websocket : WebSocket
        The accepted connection.
    """

    def __init__(self, websocket: WebSocket) -> None:
        self.websocket = websocket
        self.closing = False
        self._turn = asyncio.Lock()
        self._gone = asyncio.Event()

    @contextlib.asynccontextmanager
    async def in_flight(self) -> AsyncIterator[None]:
        """Hold this while tracking a frame and sending its result.

        Once the stream is closing, entering waits until the handler is
        cancelled: no new frame starts.
        """
        async with self._turn:
            yield

    def ended(self) -> None:
        """The handler has finished (called by :meth:`StreamRegistry.unregister`)."""
        self._gone.set()

    async def close(self, code: int, reason: str, deadline: float) -> bool:
        """Finish the turn in flight, close with ``code`` and wait for the handler to end.

        Parameters
        ----------
        code : int
            WebSocket close code.
        reason : str
            Close reason (its first 120 characters).
        deadline : float
            ``loop.time()`` after which nothing more is waited for.

        Returns
        -------
        bool
            Whether the turn in flight ended before the deadline.
        """
        self.closing = True
        finished = True
        try:
            async with asyncio.timeout_at(deadline):
                await self._turn.acquire()  # never released: no new turn starts
        except TimeoutError:
            finished = False  # still tracking: close anyway, its answer finds the socket closed
        if not self._gone.is_set():
            with contextlib.suppress(RuntimeError, OSError, WebSocketDisconnect):
                await self.websocket.close(code=code, reason=reason[:120])
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout_at(deadline):
                    await self._gone.wait()  # the client answered, the handler wrote through
        return finished


class StreamRegistry:
    """The open WebSocket streams of one app, closed together on shutdown."""

    def __init__(self) -> None:
        self._streams: set[Stream] = set()
        self._late: set[asyncio.Task[bool]] = set()
        self.closing = False
        self._code = GOING_AWAY
        self._reason = REASON
        self._timeout = 5.0

    def __len__(self) -> int:
        return len(self._streams)

    def register(self, websocket: WebSocket) -> Stream:
        """Add an accepted stream; one that arrives during shutdown is closed at once."""
        stream = Stream(websocket)
        self._streams.add(stream)
        if self.closing:
            deadline = asyncio.get_running_loop().time() + self._timeout
            task = asyncio.create_task(stream.close(self._code, self._reason, deadline))
            self._late.add(task)
            task.add_done_callback(self._late.discard)
        return stream

    def unregister(self, stream: Stream) -> None:
        """Forget a stream whose handler has finished (idempotent)."""
        self._streams.discard(stream)
        stream.ended()

    async def close_all(
        self, code: int = GOING_AWAY, reason: str = REASON, timeout: float = 5.0
    ) -> int:
        """Close every open stream once its frame in flight is answered.

        Streams registered from now on are closed as soon as they register.

        Parameters
        ----------
        code : int
            WebSocket close code (``1001``: going away).
        reason : str
            Close reason.
        timeout : float
            Seconds to wait, in all, for frames in flight and handlers to end.

        Returns
        -------
        int
            How many streams were closed.
        """
        self.closing = True
        self._code, self._reason, self._timeout = code, reason, timeout
        streams = [s for s in self._streams if not s.closing]
        if not streams:
            return 0
        log.info("closing %d WebSocket stream(s) with %d", len(streams), code)
        deadline = asyncio.get_running_loop().time() + timeout
        finished = await asyncio.gather(*(s.close(code, reason, deadline) for s in streams))
        busy = finished.count(False)
        if busy:
            log.warning("%d WebSocket stream(s) still tracking after %g s; closed", busy, timeout)
        return len(streams)


class GracefulServer(uvicorn.Server):
    """uvicorn's server, closing WebSocket streams with ``1001`` before its own shutdown.

    Parameters
    ----------
    config : uvicorn.Config
        As for :class:`uvicorn.Server`.
    streams : StreamRegistry
        The app's registry (``app.state.streams``).
    drain_seconds : float
        At most this long for frames in flight; a second Ctrl-C cuts it short.
        The time it takes comes off ``config.timeout_graceful_shutdown``, which
        so bounds the whole shutdown (the lifespan exit aside).
    on_started : callable, optional
        Called once the server listens (``efdm serve`` prints its address then).
    """

    def __init__(
        self,
        config: uvicorn.Config,
        streams: StreamRegistry,
        *,
        drain_seconds: float = 5.0,
        on_started: Callable[[], None] | None = None,
    ) -> None:
        super().__init__(config)
        self.streams = streams
        self.drain_seconds = drain_seconds
        self.on_started = on_started

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        """uvicorn's start-up; then ``on_started``, once the server listens."""
        await super().startup(sockets=sockets)
        if self.started and self.on_started is not None:
            self.on_started()

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        """Stop listening, close the streams gracefully, then uvicorn's shutdown."""
        loop = asyncio.get_running_loop()
        start = loop.time()
        for server in getattr(self, "servers", []):
            server.close()  # stop accepting: new connections go to other replicas
        drain = asyncio.ensure_future(self.streams.close_all(timeout=self.drain_seconds))
        while not drain.done() and not self.force_exit:
            await asyncio.wait({drain}, timeout=0.1)
        if not drain.done():
            drain.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await drain
        grace = self.config.timeout_graceful_shutdown
        if grace is not None:  # what is left of it for the HTTP requests in flight
            self.config.timeout_graceful_shutdown = max(1, math.ceil(grace - (loop.time() - start)))
        await super().shutdown(sockets=sockets)
