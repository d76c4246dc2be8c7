"""The asyncio client: REST over ``httpx.AsyncClient``, streams over websockets' asyncio client."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncGenerator, AsyncIterable, Iterable, Mapping, Sequence
from types import TracebackType
from typing import Any

import httpx
import numpy as np
import websockets.exceptions
from numpy.typing import ArrayLike
from websockets.asyncio.client import ClientConnection, connect

from service.client import _common as c
from service.client._common import (
    ApiError,
    CircleSpec,
    Encoder,
    ForcesResult,
    Frame,
    FrameResult,
    Method,
    Session,
)


async def _frames(frames: Iterable[Frame] | AsyncIterable[Frame]) -> AsyncGenerator[Frame]:
    if isinstance(frames, AsyncIterable):
        async for frame in frames:
            yield frame
    else:
        for frame in frames:
            yield frame


class AsyncClient:
    """Asyncio client of the efdm-tracker service: :class:`Client`'s API, awaited.

    Runs on asyncio (under anyio too, with its asyncio backend).

    Parameters
    ----------
    base_url : str
        The service's root URL (a path prefix is kept: ``https://host/efdm``).
    api_key : str, optional
        Sent as ``Authorization: Bearer <key>`` (REST and WebSocket).
    timeout : float or None
        Seconds for connecting and for each response (None: wait forever).
    encoder : callable, optional
        Turns frame arrays into image bytes (run in a worker thread); default
        ``ImageEncoder()``, JPEG quality 90.

    Notes
    -----
    Use as ``async with`` (or await :meth:`aclose`).  :meth:`track` and
    :meth:`stream` are async generators: close them early with
    ``contextlib.aclosing`` so the session / socket is released promptly.
    """

    def __init__(
        self,
        base_url: str = "http://127.0.0.1:8000",
        *,
        api_key: str | None = None,
        timeout: float | None = 30.0,
        encoder: Encoder | None = None,
    ) -> None:
        self.base_url = base_url
        self.timeout = timeout
        self.encoder: Encoder = c.ImageEncoder() if encoder is None else encoder
        self._headers = c.headers(api_key)
        self._http = httpx.AsyncClient(base_url=base_url, headers=self._headers, timeout=timeout)

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Close the HTTP connections."""
        await self._http.aclose()

    async def _call(self, method: str, path: str, **kwargs: Any) -> Any:
        response = await self._http.request(method, path, **kwargs)
        if not response.is_success:
            raise c.error_from_body(
                response.status_code,
                response.content,
                response.reason_phrase,
                response.headers.get("retry-after"),
            )
        return response.json() if response.content else None

    async def _encode(self, frame: Frame) -> bytes:
        if isinstance(frame, np.ndarray):
            return await asyncio.to_thread(c.frame_bytes, frame, self.encoder)
        return c.frame_bytes(frame, self.encoder)

    async def create_session(
        self,
        nodes: ArrayLike | None = None,
        *,
        circle: CircleSpec | None = None,
        box: ArrayLike | None = None,
        snap: bool | None = None,
        objects: Sequence[Mapping[str, Any]] | None = None,
        closed: bool = True,
        stiffness: float | None = None,
        method: Method | None = None,
        tracking: Mapping[str, Any] | None = None,
    ) -> Session:
        """Create a session; see :meth:`Client.create_session`."""
        body = c.session_body(
            nodes, circle, closed, stiffness, method, tracking, box=box, snap=snap, objects=objects
        )
        return c.parse_session(await self._call("POST", "/v1/sessions", json=body))

    async def get_session(self, session: str | Session) -> Session:
        """The session's current state; ApiError 404 when unknown or expired."""
        return c.parse_session(await self._call("GET", c.session_path(session)))

    async def delete_session(self, session: str | Session) -> None:
        """Delete the session; ApiError 404 when unknown or expired."""
        await self._call("DELETE", c.session_path(session))

    async def apply_forces(
        self, session: str | Session, forces: ArrayLike, *, if_match: int | str | None = None
    ) -> ForcesResult:
        """Deform the rest shape under one force per node; see :meth:`Client.apply_forces`."""
        return c.parse_forces(
            await self._call(
                "POST",
                c.session_path(session, "/forces"),
                json=c.forces_body(forces),
                headers=c.if_match_header(if_match),
            )
        )

    async def track_frame(
        self, session: str | Session, frame: Frame, *, if_match: int | str | None = None
    ) -> FrameResult:
        """Track one frame (REST); see :meth:`Client.track_frame`."""
        data = await self._encode(frame)
        headers = {"Content-Type": c.media_type(data), **c.if_match_header(if_match)}
        return c.parse_frame(
            await self._call(
                "POST", c.session_path(session, "/frames"), content=data, headers=headers
            )
        )

    async def track(
        self,
        frames: Iterable[Frame] | AsyncIterable[Frame],
        *,
        nodes: ArrayLike | None = None,
        circle: CircleSpec | None = None,
        stiffness: float | None = None,
        method: Method | None = None,
        tracking: Mapping[str, Any] | None = None,
    ) -> AsyncGenerator[FrameResult]:
        """Track frames in a temporary session (REST); see :meth:`Client.track`.

        Yields
        ------
        FrameResult
            One per frame.
        """
        session = await self.create_session(
            nodes, circle=circle, stiffness=stiffness, method=method, tracking=tracking
        )
        try:
            async for frame in _frames(frames):
                yield await self.track_frame(session, frame)
        finally:
            with contextlib.suppress(ApiError, httpx.HTTPError, RuntimeError):
                await self.delete_session(session)

    async def stream(
        self,
        session: str | Session,
        frames: Iterable[Frame] | AsyncIterable[Frame],
        *,
        max_in_flight: int = 1,
        mode: str = "latest",
    ) -> AsyncGenerator[FrameResult]:
        """Track frames over the session's WebSocket; see :meth:`Client.stream`.

        Parameters
        ----------
        session : str or Session
            The session (or its id).
        frames : iterable or async iterable of bytes or ndarray
            The frames, in order (a camera as an async generator, say).
        max_in_flight : int
            1 (default): each frame is answered before the next is sent, so
            none is dropped.  More (realtime): up to this many frames are sent
            ahead; the server skips all but the newest waiting frame and
            results report ``dropped > 0``.
        mode : str
            ``"latest"`` (default) or ``"every"``: see :meth:`Client.stream`.

        Yields
        ------
        FrameResult
            One per tracked frame; ``sum(1 + r.dropped)`` equals the frames sent.

        Raises
        ------
        ApiError
            On a ``{"type": "error"}`` message (the stream ends, the session is
            unchanged) or an error close: 4404 → 404, 4401 → 401, 1009 → 413.
        TimeoutError
            No result within ``timeout`` seconds.
        """
        pending = c.InFlight(max_in_flight)
        url = c.stream_url(self.base_url, session, mode)
        try:
            async with self._connect(url) as ws, contextlib.aclosing(_frames(frames)) as source:
                exhausted = False
                while True:
                    while pending.room and not exhausted:
                        frame = await anext(source, None)
                        if frame is None:
                            exhausted = True
                        else:
                            await ws.send(await self._encode(frame))
                            pending.sent()
                    if not pending.count:
                        return
                    result = await self._receive(ws)
                    pending.answered(result)
                    yield result
        except websockets.exceptions.InvalidStatus as exc:
            response = exc.response
            raise c.error_from_body(response.status_code, response.body or b"") from exc
        except websockets.exceptions.ConnectionClosed as exc:
            error = c.closed_error(exc)
            if error is None:
                raise
            raise error from exc

    def _connect(self, url: str) -> connect:
        return connect(
            url,
            additional_headers=self._headers,
            user_agent_header=None,
            compression=None,
            open_timeout=self.timeout,
            max_size=c.MAX_MESSAGE,
        )

    async def _receive(self, ws: ClientConnection) -> FrameResult:
        while True:
            async with asyncio.timeout(self.timeout):
                data = await ws.recv()
            result = c.parse_message(data)
            if result is not None:
                return result
