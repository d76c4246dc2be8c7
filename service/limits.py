"""Request body limits, enforced before anything reads the body (ASGI middleware)."""

from __future__ import annotations

import asyncio
import json

from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service import metrics
from service.errors import body
from service.units import too_many_bytes

MULTIPART_SLACK = 64 * 1024
"""Bytes a frame's body may exceed ``EFDM_MAX_FRAME_BYTES`` by: a multipart upload's
boundaries and part headers.  The image itself is held to the limit when it is decoded;
the 413 names the limit as set."""


class BodyLimit:
    """Answer 413 once a body exceeds its limit (frames and JSON have their own), 408 when
    it stops arriving.

    Checks ``Content-Length`` up front and counts streamed bytes as they
    arrive, so a client cannot make the server buffer more than the limit;
    a body whose next piece takes longer than ``body_seconds`` is answered
    ``408`` and its connection closed, so a trickling client cannot hold one.
    """

    def __init__(
        self, app: ASGIApp, *, json_bytes: int, frame_bytes: int, body_seconds: float = 30.0
    ) -> None:
        self.app = app
        self.json_bytes = json_bytes
        self.frame_bytes = frame_bytes
        self.body_seconds = body_seconds

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "DELETE", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        is_frame = scope["path"].endswith("/frames")
        limit = self.frame_bytes + MULTIPART_SLACK if is_frame else self.json_bytes
        stated = self.frame_bytes if is_frame else self.json_bytes  # the documented limit
        headers = dict(scope.get("headers") or [])
        declared = headers.get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > limit:
            await _too_large(send, stated, int(declared))
            return
        seen = 0
        responded = False
        complete = False

        async def counting() -> Message:
            nonlocal seen, complete
            if complete:  # the body is in: later reads wait for a disconnect, untimed
                return await receive()
            try:
                message = await asyncio.wait_for(receive(), self.body_seconds)
            except TimeoutError:
                raise _BodyTooSlow(self.body_seconds) from None
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    raise _BodyTooLarge(stated)
                complete = not message.get("more_body", False)
            return message

        async def guarded(message: Message) -> None:
            nonlocal responded
            if message["type"] == "http.response.start":
                responded = True
            await send(message)

        try:
            await self.app(scope, counting, guarded)
        except _BodyTooLarge:
            if not responded:
                await _too_large(send, stated, None)
        except _BodyTooSlow as slow:
            if not responded:
                await _refuse(send, 408, "timeout", slow.detail)


class _BodyTooLarge(HTTPException):
    """Raised inside a body read; FastAPI passes HTTP exceptions through."""

    def __init__(self, limit: int) -> None:
        super().__init__(413, too_many_bytes("body", None, limit))


class _BodyTooSlow(HTTPException):
    """Raised inside a body read that waited too long for the next piece."""

    def __init__(self, seconds: float) -> None:
        super().__init__(408, f"the request body stopped arriving (no data for {seconds:g} s)")


async def _too_large(send: Send, limit: int, size: int | None) -> None:
    await _refuse(send, 413, "too_large", too_many_bytes("body", size, limit))


async def _refuse(send: Send, status: int, code: str, message: str) -> None:
    """Answer ``status`` with the JSON error and close the connection."""
    metrics.ERRORS.labels(kind=code).inc()
    payload = json.dumps(body(status, code, message)).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(payload)).encode()),
                (b"connection", b"close"),
            ],
        }
    )
    await send({"type": "http.response.body", "body": payload})
