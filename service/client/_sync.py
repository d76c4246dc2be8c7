"""The blocking client: REST over ``httpx.Client``, streams over websockets' sync client."""

from __future__ import annotations

import contextlib
from collections.abc import Generator, Iterable, Mapping, Sequence
from types import TracebackType
from typing import Any

import httpx
import websockets.exceptions
from numpy.typing import ArrayLike
from websockets.sync.client import ClientConnection, connect

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


class Client:
    """Blocking client of the efdm-tracker service.

    Parameters
    ----------
    base_url : str
        The service's root URL (a path prefix is kept: ``https://host/efdm``).
    api_key : str, optional
        Sent as ``Authorization: Bearer <key>`` (REST and WebSocket).
    timeout : float or None
        Seconds for connecting and for each response (None: wait forever).
    encoder : callable, optional
        Turns frame arrays into image bytes; default ``ImageEncoder()``, JPEG
        quality 90.  E.g. ``ImageEncoder("png")`` for lossless frames.

    Notes
    -----
    Use as a context manager (or call :meth:`close`).  Errors the service
    answers raise :class:`ApiError`; network failures raise ``httpx``'s
    exceptions (REST) or ``websockets`` / ``OSError`` ones (streams).
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
        self._http = httpx.Client(base_url=base_url, headers=self._headers, timeout=timeout)

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the HTTP connections."""
        self._http.close()

    def _call(self, method: str, path: str, **kwargs: Any) -> Any:
        response = self._http.request(method, path, **kwargs)
        if not response.is_success:
            raise c.error_from_body(
                response.status_code,
                response.content,
                response.reason_phrase,
                response.headers.get("retry-after"),
            )
        return response.json() if response.content else None

    def create_session(
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
        """Create a session from an initial contour.

        Parameters
        ----------
        nodes : array_like, shape (N, 2), optional
            Initial contour, ``[[x, y], ...]`` pixels.
        circle : tuple, optional
            ``(center, radius)`` or ``(center, radius, count)`` instead of
            ``nodes``: a circle of ``count`` (default 64) nodes.
        box : array_like, optional
            ``[x0, y0, x1, y1]`` around the object, pixel edges, instead of
            ``nodes``: 64 nodes, snapped onto the object on the first frame.
        snap : bool, optional
            Snap the outline onto the object on the first frame (server
            default: true for ``box``, false otherwise).
        objects : sequence of dict, optional
            Several objects instead (the API's ``"objects"``: each a dict
            of ``nodes``, ``circle``, ``box`` or ``mask``, with optional
            ``id`` and ``snap``); frame results then carry ``objects``.
        closed : bool
            Closed ring (needed for tracking) or open chain.
        stiffness, method, tracking : optional
            Model stiffness, solver and tracker options (server defaults
            when omitted: 10.0, ``"exact"``, ``{}``).

        Returns
        -------
        Session

        Raises
        ------
        ValueError
            Not exactly one of ``nodes``, ``circle``, ``box`` and ``objects``; nodes not (N, 2).
        ApiError
            422 invalid contour or options, 429 too many sessions.
        """
        body = c.session_body(
            nodes, circle, closed, stiffness, method, tracking, box=box, snap=snap, objects=objects
        )
        return c.parse_session(self._call("POST", "/v1/sessions", json=body))

    def get_session(self, session: str | Session) -> Session:
        """The session's current state; ApiError 404 when unknown or expired."""
        return c.parse_session(self._call("GET", c.session_path(session)))

    def delete_session(self, session: str | Session) -> None:
        """Delete the session; ApiError 404 when unknown or expired."""
        self._call("DELETE", c.session_path(session))

    def apply_forces(
        self, session: str | Session, forces: ArrayLike, *, if_match: int | str | None = None
    ) -> ForcesResult:
        """Deform the session's rest shape under one force per node.

        Parameters
        ----------
        session : str or Session
            The session (or its id).
        forces : array_like, shape (N, 2)
            ``[[fx, fy], ...]`` pixels, one per node.
        if_match : int or str, optional
            The session version this change expects; ApiError 412 if stale.

        Returns
        -------
        ForcesResult

        Raises
        ------
        ApiError
            404 unknown session, 412 stale version, 422 wrong number of forces.
        """
        return c.parse_forces(
            self._call(
                "POST",
                c.session_path(session, "/forces"),
                json=c.forces_body(forces),
                headers=c.if_match_header(if_match),
            )
        )

    def track_frame(
        self, session: str | Session, frame: Frame, *, if_match: int | str | None = None
    ) -> FrameResult:
        """Track the session's contour into one frame (REST).

        Parameters
        ----------
        session : str or Session
            The session (or its id); it must be closed.
        frame : bytes or ndarray
            An encoded JPEG / PNG / WebP image, or a BGR / grey uint8 array
            (encoded with :attr:`encoder`).
        if_match : int or str, optional
            The session version this frame expects; ApiError 412 if stale.

        Returns
        -------
        FrameResult

        Raises
        ------
        ApiError
            400 undecodable image, 404 unknown session, 412 stale version,
            413 image too large, 422 open contour.
        """
        data = c.frame_bytes(frame, self.encoder)
        headers = {"Content-Type": c.media_type(data), **c.if_match_header(if_match)}
        return c.parse_frame(
            self._call("POST", c.session_path(session, "/frames"), content=data, headers=headers)
        )

    def track(
        self,
        frames: Iterable[Frame],
        *,
        nodes: ArrayLike | None = None,
        circle: CircleSpec | None = None,
        stiffness: float | None = None,
        method: Method | None = None,
        tracking: Mapping[str, Any] | None = None,
    ) -> Generator[FrameResult]:
        """Track frames from an initial contour in a temporary session (REST).

        The session is created on the first ``next()`` and deleted (best
        effort) when the frames run out or the iterator is closed.

        Parameters
        ----------
        frames : iterable of bytes or ndarray
            The frames, in order.
        nodes, circle, stiffness, method, tracking
            The initial contour and model, as for :meth:`create_session`.

        Yields
        ------
        FrameResult
            One per frame.
        """
        session = self.create_session(
            nodes, circle=circle, stiffness=stiffness, method=method, tracking=tracking
        )
        try:
            for frame in frames:
                yield self.track_frame(session, frame)
        finally:
            with contextlib.suppress(ApiError, httpx.HTTPError, RuntimeError):
                self.delete_session(session)

    def stream(
        self,
        session: str | Session,
        frames: Iterable[Frame],
        *,
        max_in_flight: int = 1,
        mode: str = "latest",
    ) -> Generator[FrameResult]:
        """Track frames over the session's WebSocket.

        Parameters
        ----------
        session : str or Session
            The session (or its id).
        frames : iterable of bytes or ndarray
            The frames, in order.
        max_in_flight : int
            Frames sent before waiting for a result.  1 (default): every frame
            is answered, exactly as over REST.  More pipelines the sends
            (realtime): when frames arrive faster than the server tracks them
            it skips all but the newest, and results report ``dropped > 0``.
        mode : str
            ``"latest"`` (default; a live camera: the newest frame wins, as
            above) or ``"every"`` (a file: every frame tracked in order, none
            dropped, whatever ``max_in_flight``; the server reads no further
            while its queue is full).

        Yields
        ------
        FrameResult
            One per tracked frame; ``sum(1 + r.dropped)`` equals the frames sent.

        Raises
        ------
        ApiError
            On a ``{"type": "error"}`` message (e.g. 400 for a frame that does
            not decode; the stream ends, the session is unchanged), or when the
            server closes the socket: 4404 → 404, 4401 → 401, 1009 → 413.
        TimeoutError
            No result within ``timeout`` seconds.
        """
        pending = c.InFlight(max_in_flight)
        url = c.stream_url(self.base_url, session, mode)
        try:
            with self._connect(url) as ws:
                source = iter(frames)
                exhausted = False
                while True:
                    while pending.room and not exhausted:
                        frame = next(source, None)
                        if frame is None:
                            exhausted = True
                        else:
                            ws.send(c.frame_bytes(frame, self.encoder))
                            pending.sent()
                    if not pending.count:
                        return
                    result = self._receive(ws)
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

    def _connect(self, url: str) -> ClientConnection:
        return connect(
            url,
            additional_headers=self._headers,
            user_agent_header=None,
            compression=None,
            open_timeout=self.timeout,
            max_size=c.MAX_MESSAGE,
        )

    def _receive(self, ws: ClientConnection) -> FrameResult:
        while True:
            result = c.parse_message(ws.recv(timeout=self.timeout))
            if result is not None:
                return result
